// GroundStore (mapio/ground_store.hpp): what is put is listed and read back byte-identical after a
// reopen; duplicates write nothing; crash leftovers and damaged files are repaired or quarantined at
// open and never counted; hostile names never become paths; a writer killed with SIGKILL at random
// moments leaves a store whose every listed chunk decodes to exactly what was put.

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "sigkill_writer.hpp"
#include "temp_dir.hpp"
#include "hwr/core/file_io.hpp"
#include "hwr/mapio/chunk_wire.hpp"
#include "hwr/mapio/ground_store.hpp"

namespace {

namespace fs = std::filesystem;
using hwr::core::ErrorCode;
using hwr::mapio::GroundStore;
using hwr_lcm::map_chunk_t;

struct TempDir : hwr::testing::TempDir {
  TempDir() : hwr::testing::TempDir("hwr_ground_store") {}
};

struct ChunkSpec {
  std::string robot_id = "hwr-0";
  int64_t run_id = 1700000000000000000;
  int64_t link_seq = 0;
  int32_t segment_id = 0, version = 0, chunk_index = 0, chunk_count = 1;
  bool complete = false;
  size_t payload_bytes = 100;
};

// A sealed chunk whose payload and pose derive from the spec alone (so a test can rebuild it).
map_chunk_t make_chunk(const ChunkSpec& s) {
  map_chunk_t c;
  c.t_ns = 1000 + s.link_seq;
  c.robot_id = s.robot_id;
  c.run_id = s.run_id;
  c.link_seq = s.link_seq;
  c.segment_id = s.segment_id;
  c.segment_version = s.version;
  c.chunk_index = s.chunk_index;
  c.segment_complete = s.complete ? 1 : 0;
  c.chunk_count = s.chunk_count;
  const double T[12] = {1, 0, 0,  0.5 * s.segment_id + 0.01 * s.chunk_index, 0, 1, 0, -1.0 * s.version, 0,
                        0, 1, 2.0};
  std::copy(T, T + 12, c.T_world_segment);
  c.num_points = static_cast<int32_t>(s.payload_bytes / 8);
  c.has_normals = 0;
  c.max_position_error_m = 0.001f;
  std::mt19937 rng(static_cast<uint32_t>(s.link_seq * 7919 + s.segment_id * 31 + s.chunk_index));
  c.payload.resize(s.payload_bytes);
  for (auto& b : c.payload) b = static_cast<uint8_t>(rng());
  hwr::mapio::seal_chunk(&c);
  return c;
}

std::vector<uint8_t> encoded(const map_chunk_t& c) {
  std::vector<uint8_t> out;
  EXPECT_TRUE(hwr::mapio::encode_chunk_message(c, &out).ok());
  return out;
}

std::string read_text(const std::string& path) {
  std::string s;
  EXPECT_TRUE(hwr::core::read_file(path, &s).ok()) << path;
  return s;
}

std::set<std::string> names_in(const std::string& dir) {
  std::set<std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) out.insert(e.path().filename().string());
  return out;
}

// Files under `dir` whose name ends with `suffix`, recursively.
std::vector<std::string> files_ending(const std::string& dir, const std::string& suffix) {
  std::vector<std::string> out;
  if (!fs::exists(dir)) return out;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string n = e.path().filename().string();
    if (n.size() >= suffix.size() && n.compare(n.size() - suffix.size(), suffix.size(), suffix) == 0) {
      out.push_back(e.path().string());
    }
  }
  return out;
}

// .drc files without their .lcm beside them.
int lone_payloads(const std::string& dir) {
  int n = 0;
  for (const std::string& drc : files_ending(dir, ".drc")) {
    if (!fs::exists(drc.substr(0, drc.size() - 4) + ".lcm")) ++n;
  }
  return n;
}

GroundStore open_ok(const std::string& dir) {
  auto store = GroundStore::open(dir);
  EXPECT_TRUE(store.ok()) << store.status().to_string();
  return std::move(store).value();
}

// --- round trip --------------------------------------------------------------------------------------

std::vector<ChunkSpec> round_trip_specs() {
  std::vector<ChunkSpec> specs;
  auto add = [&](const std::string& robot, int64_t run, int64_t link, int32_t seg, int32_t ver, int32_t idx,
                 int32_t count, bool complete, size_t bytes) {
    ChunkSpec s;
    s.robot_id = robot;
    s.run_id = run;
    s.link_seq = link;
    s.segment_id = seg;
    s.version = ver;
    s.chunk_index = idx;
    s.chunk_count = count;
    s.complete = complete;
    s.payload_bytes = bytes;
    specs.push_back(s);
  };
  // Segment 0 v0: three chunks, the last closes it. Segment 1 v0: two chunks, still open, put out of
  // order. Segment 1 v1: a re-sent version of one chunk. A second robot's run. An empty payload.
  add("hwr-0", 100, 0, 0, 0, 0, 1, false, 3000);
  add("hwr-0", 100, 1, 0, 0, 1, 2, false, 5000);
  add("hwr-0", 100, 2, 0, 0, 2, 3, true, 700);
  add("hwr-0", 100, 4, 1, 0, 1, 2, false, 0);
  add("hwr-0", 100, 3, 1, 0, 0, 1, false, 1200);
  add("hwr-0", 100, 5, 1, 1, 0, 1, true, 2500);
  add("hwr_1", 7, 0, 12, 0, 0, 1, false, 64);
  return specs;
}

void expect_round_trip_listing(const GroundStore& store, const std::vector<map_chunk_t>& chunks) {
  using Run = std::pair<std::string, int64_t>;
  EXPECT_EQ(store.runs(), (std::vector<Run>{{"hwr-0", 100}, {"hwr_1", 7}}));
  EXPECT_EQ(store.stored_link_seqs("hwr-0", 100), (std::vector<int64_t>{0, 1, 2, 3, 4, 5}));
  EXPECT_EQ(store.stored_link_seqs("hwr_1", 7), (std::vector<int64_t>{0}));
  EXPECT_TRUE(store.stored_link_seqs("hwr-0", 7).empty());
  EXPECT_TRUE(store.has("hwr-0", 100, 5));
  EXPECT_FALSE(store.has("hwr-0", 100, 6));
  EXPECT_FALSE(store.has("hwr_1", 100, 0));
  EXPECT_FALSE(store.has("../x", 100, 0));
  EXPECT_EQ(store.chunks_stored(), 7);

  const auto segs = store.segments("hwr-0", 100);
  ASSERT_EQ(segs.size(), 3u);
  // (id, version, stored, count, complete, the chunk whose pose is reported, points, bytes)
  EXPECT_EQ(segs[0].segment_id, 0);
  EXPECT_EQ(segs[0].version, 0);
  EXPECT_EQ(segs[0].chunks_stored, 3);
  EXPECT_EQ(segs[0].chunk_count, 3);
  EXPECT_TRUE(segs[0].complete);
  EXPECT_EQ(segs[0].points_stored, chunks[0].num_points + chunks[1].num_points + chunks[2].num_points);
  EXPECT_EQ(segs[0].payload_bytes_stored, 3000 + 5000 + 700);
  EXPECT_TRUE(std::equal(segs[0].T_world_segment, segs[0].T_world_segment + 12, chunks[2].T_world_segment));
  EXPECT_EQ(segs[1].segment_id, 1);
  EXPECT_EQ(segs[1].version, 0);
  EXPECT_EQ(segs[1].chunks_stored, 2);
  EXPECT_EQ(segs[1].chunk_count, 2);
  EXPECT_FALSE(segs[1].complete) << "no segment_complete chunk was stored";
  EXPECT_TRUE(std::equal(segs[1].T_world_segment, segs[1].T_world_segment + 12, chunks[3].T_world_segment))
      << "the pose comes from the highest chunk_index, whatever the arrival order";
  EXPECT_EQ(segs[2].segment_id, 1);
  EXPECT_EQ(segs[2].version, 1);
  EXPECT_TRUE(segs[2].complete);

  std::vector<map_chunk_t> loaded;
  ASSERT_TRUE(store.load_segment("hwr-0", 100, 1, 0, &loaded).ok());
  ASSERT_EQ(loaded.size(), 2u);
  EXPECT_EQ(encoded(loaded[0]), encoded(chunks[4])) << "ordered by chunk_index, not by arrival";
  EXPECT_EQ(encoded(loaded[1]), encoded(chunks[3]));
  ASSERT_TRUE(store.load_segment("hwr-0", 100, 0, 0, &loaded).ok());
  ASSERT_EQ(loaded.size(), 3u);
  for (size_t i = 0; i < 3; ++i) EXPECT_EQ(encoded(loaded[i]), encoded(chunks[i])) << "chunk " << i;
  EXPECT_EQ(store.load_segment("hwr-0", 100, 2, 0, &loaded).code(), ErrorCode::kNotFound);
  EXPECT_EQ(store.load_segment("hwr-0", 101, 0, 0, &loaded).code(), ErrorCode::kNotFound);

  // The .drc holds the payload alone (what draco_decoder reads).
  for (const map_chunk_t& c : chunks) {
    const std::string drc =
        store.drc_path(c.robot_id, c.run_id, c.segment_id, c.segment_version, c.chunk_index);
    const std::string bytes = read_text(drc);
    EXPECT_EQ(std::vector<uint8_t>(bytes.begin(), bytes.end()), c.payload) << drc;
  }
}

TEST(GroundStore, GivenChunksOfTwoRunsWhenReopenedThenListingsSegmentsAndBytesRoundTrip) {
  TempDir tmp;
  std::vector<map_chunk_t> chunks;
  for (const ChunkSpec& s : round_trip_specs()) chunks.push_back(make_chunk(s));
  {
    GroundStore store = open_ok(tmp.file("out"));
    for (const map_chunk_t& c : chunks) {
      bool was_new = false;
      ASSERT_TRUE(store.put(c, &was_new).ok()) << c.link_seq;
      EXPECT_TRUE(was_new);
    }
    SCOPED_TRACE("before reopening");
    expect_round_trip_listing(store, chunks);
  }
  GroundStore store = open_ok(tmp.file("out"));
  SCOPED_TRACE("after reopening");
  expect_round_trip_listing(store, chunks);
  const GroundStore::OpenReport& r = store.open_report();
  EXPECT_EQ(r.chunks_loaded, 7);
  EXPECT_EQ(r.temp_files_removed + r.lone_payloads_removed + r.corrupt_quarantined + r.payloads_rewritten, 0);
  EXPECT_TRUE(r.notes.empty()) << r.notes.front();
  // The documented layout.
  EXPECT_TRUE(fs::is_regular_file(tmp.file("out") + "/hwr-0/100/seg_000001_v0/chunk_000001.lcm"));
  EXPECT_TRUE(fs::is_regular_file(tmp.file("out") + "/hwr-0/100/seg_000001_v0/chunk_000001.drc"));
  EXPECT_TRUE(fs::is_regular_file(tmp.file("out") + "/hwr_1/7/seg_000012_v0/chunk_000000.lcm"));
}

TEST(GroundStore, GivenTheSameChunkAgainThenItIsAcceptedWithoutRewritingAnything) {
  TempDir tmp;
  ChunkSpec s;
  s.payload_bytes = 4096;
  const map_chunk_t c = make_chunk(s);
  const std::string seg_dir = tmp.file("out") + "/hwr-0/" + std::to_string(s.run_id) + "/seg_000000_v0";
  struct stat before_lcm {
  }, before_drc{}, after{};
  {
    GroundStore store = open_ok(tmp.file("out"));
    ASSERT_TRUE(store.put(c).ok());
    ASSERT_EQ(::stat((seg_dir + "/chunk_000000.lcm").c_str(), &before_lcm), 0);
    ASSERT_EQ(::stat((seg_dir + "/chunk_000000.drc").c_str(), &before_drc), 0);
    map_chunk_t resent = c;
    resent.t_ns += 5'000'000'000;  // a resend restamps the time; the CRC leaves t_ns out
    bool was_new = true;
    ASSERT_TRUE(store.put(resent, &was_new).ok());
    EXPECT_FALSE(was_new);
    EXPECT_EQ(store.chunks_stored(), 1);
  }
  GroundStore store = open_ok(tmp.file("out"));
  bool was_new = true;
  ASSERT_TRUE(store.put(c, &was_new).ok());
  EXPECT_FALSE(was_new) << "a restarted store must recognise what it already has";
  EXPECT_EQ(names_in(seg_dir), (std::set<std::string>{"chunk_000000.drc", "chunk_000000.lcm"}));
  // A rewrite goes through temp + rename, which gives the file a new inode.
  ASSERT_EQ(::stat((seg_dir + "/chunk_000000.lcm").c_str(), &after), 0);
  EXPECT_EQ(after.st_ino, before_lcm.st_ino);
  ASSERT_EQ(::stat((seg_dir + "/chunk_000000.drc").c_str(), &after), 0);
  EXPECT_EQ(after.st_ino, before_drc.st_ino);
}

TEST(GroundStore, GivenAChunkThatConflictsWithAStoredOneThenItIsRejectedAndNothingChanges) {
  TempDir tmp;
  GroundStore store = open_ok(tmp.file("out"));
  ChunkSpec s;
  s.link_seq = 3;
  s.chunk_index = 0;
  ASSERT_TRUE(store.put(make_chunk(s)).ok());

  ChunkSpec other_place = s;  // same link_seq, another chunk_index
  other_place.chunk_index = 1;
  other_place.chunk_count = 2;
  EXPECT_EQ(store.put(make_chunk(other_place)).code(), ErrorCode::kInvalidArgument);

  ChunkSpec other_seq = s;  // same place, another link_seq
  other_seq.link_seq = 4;
  const auto st = store.put(make_chunk(other_seq));
  EXPECT_EQ(st.code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(st.message().find("already holds link_seq 3"), std::string::npos) << st.message();

  map_chunk_t other_bytes = make_chunk(s);  // same link_seq and place, other content
  other_bytes.payload[0] ^= 0xff;
  hwr::mapio::seal_chunk(&other_bytes);
  EXPECT_EQ(store.put(other_bytes).code(), ErrorCode::kInvalidArgument);

  map_chunk_t bad_crc = make_chunk(other_place);
  bad_crc.crc32 ^= 1;
  EXPECT_EQ(store.put(bad_crc).code(), ErrorCode::kCorruptData);

  EXPECT_EQ(store.stored_link_seqs(s.robot_id, s.run_id), (std::vector<int64_t>{3}));
  EXPECT_EQ(names_in(tmp.file("out") + "/hwr-0/" + std::to_string(s.run_id) + "/seg_000000_v0"),
            (std::set<std::string>{"chunk_000000.drc", "chunk_000000.lcm"}));
}

TEST(GroundStore, GivenHostileOrMalformedFieldsThenPutRejectsThemBeforeTouchingTheDisk) {
  TempDir tmp;
  GroundStore store = open_ok(tmp.file("out"));
  const std::vector<std::string> hostile = {"../x", "",     std::string(65, 'a'), "a/b", ".", "..", "a b",
                                            "x\n",  "/abs", "r\xc3\xa9"};
  for (const std::string& id : hostile) {
    ChunkSpec s;
    s.robot_id = id;
    const auto st = store.put(make_chunk(s));
    EXPECT_EQ(st.code(), ErrorCode::kInvalidArgument) << "robot_id '" << id << "'";
    EXPECT_NE(st.message().find("[A-Za-z0-9_-]{1,64}"), std::string::npos) << st.message();
  }
  EXPECT_EQ(names_in(tmp.file("out")), (std::set<std::string>{".ground_store.lock"}));
  EXPECT_EQ(names_in(tmp.path()), (std::set<std::string>{"out"})) << "nothing may appear beside the store";

  ChunkSpec longest;
  longest.robot_id = std::string(63, 'Z') + "9";
  EXPECT_TRUE(store.put(make_chunk(longest)).ok()) << "64 characters is allowed";

  auto malformed = [&](auto mutate) {
    ChunkSpec s;
    s.link_seq = 50;
    map_chunk_t c = make_chunk(s);
    mutate(&c);
    hwr::mapio::seal_chunk(&c);  // sets payload_size from payload; the mutation may change it after
    return c;
  };
  EXPECT_EQ(store.put(malformed([](map_chunk_t* c) { c->run_id = -1; })).code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(store.put(malformed([](map_chunk_t* c) { c->link_seq = -2; })).code(),
            ErrorCode::kInvalidArgument);
  EXPECT_EQ(store.put(malformed([](map_chunk_t* c) { c->segment_id = -1; })).code(),
            ErrorCode::kInvalidArgument);
  EXPECT_EQ(store.put(malformed([](map_chunk_t* c) { c->chunk_index = -1; })).code(),
            ErrorCode::kInvalidArgument);
  EXPECT_EQ(store
                .put(malformed([](map_chunk_t* c) {
                  c->segment_complete = 1;
                  c->chunk_count = 0;
                }))
                .code(),
            ErrorCode::kInvalidArgument);
  map_chunk_t size_lie = malformed([](map_chunk_t*) {});
  size_lie.payload_size += 1;
  EXPECT_EQ(store.put(size_lie).code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(store.chunks_stored(), 1);
}

TEST(GroundStore, GivenAMessageOverTheSizeCapThenPutRejectsIt) {
  TempDir tmp;
  GroundStore store = open_ok(tmp.file("out"));
  map_chunk_t big = make_chunk(ChunkSpec{});
  big.payload.assign(static_cast<size_t>(GroundStore::kMaxStoredMessageBytes), 0x5a);
  big.payload_size = static_cast<int32_t>(big.payload.size());
  const auto st = store.put(big);
  EXPECT_EQ(st.code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(st.message().find("64 MiB"), std::string::npos) << st.message();
  EXPECT_EQ(store.chunks_stored(), 0);
}

TEST(GroundStore, GivenASecondStoreOnTheSameFolderThenItIsRefusedUntilTheFirstCloses) {
  TempDir tmp;
  {
    GroundStore first = open_ok(tmp.file("out"));
    auto second = GroundStore::open(tmp.file("out"));
    ASSERT_FALSE(second.ok());
    EXPECT_EQ(second.status().code(), ErrorCode::kUnavailable) << second.status().to_string();
  }
  EXPECT_TRUE(GroundStore::open(tmp.file("out")).ok());
}

// --- crash leftovers ------------------------------------------------------------------------------------

// Offset of payload_size in the LCM encoding of a chunk with this robot_id (map_chunk_t.lcm order).
size_t payload_size_offset(const std::string& robot_id) {
  return 8 /*fingerprint*/ + 8 /*t_ns*/ + 4 + robot_id.size() + 1 + 8 + 8 + 4 + 4 + 4 + 1 + 4 + 96 + 4 + 1 +
         4;
}

TEST(GroundStore, GivenCrashLeftoversAndDamagedFilesThenOpenCleansThemAndCountsOnlyGoodChunks) {
  TempDir tmp;
  std::vector<map_chunk_t> chunks;
  for (int i = 0; i < 6; ++i) {
    ChunkSpec s;
    s.link_seq = i;
    s.chunk_index = i;
    s.chunk_count = i + 1;
    s.payload_bytes = 2000 + 100 * i;
    chunks.push_back(make_chunk(s));
  }
  {
    GroundStore store = open_ok(tmp.file("out"));
    for (const auto& c : chunks) ASSERT_TRUE(store.put(c).ok());
  }
  const std::string dir = tmp.file("out") + "/hwr-0/" + std::to_string(chunks[0].run_id) + "/seg_000000_v0";
  auto lcm = [&](int i) { return dir + "/chunk_00000" + std::to_string(i) + ".lcm"; };
  auto drc = [&](int i) { return dir + "/chunk_00000" + std::to_string(i) + ".drc"; };
  // Interrupted writes: temps, and a payload whose .lcm never came.
  ASSERT_TRUE(hwr::core::write_file_atomic(dir + "/chunk_000009.drc.tmp", std::string("partial")).ok());
  ASSERT_TRUE(hwr::core::write_file_atomic(dir + "/chunk_000009.lcm.tmp", std::string("partial")).ok());
  ASSERT_TRUE(hwr::core::write_file_atomic(dir + "/chunk_000008.drc", std::string("lone payload")).ok());
  // Damage: 0's payload file lost; 1 truncated; 2 one flipped payload bit (decodes, CRC fails);
  // 3 claims a 2 GiB payload; 4 a sparse file over the size cap; 5 stays intact.
  fs::remove(drc(0));
  fs::resize_file(lcm(1), fs::file_size(lcm(1)) / 2);
  {
    std::string bytes = read_text(lcm(2));
    bytes[payload_size_offset("hwr-0") + 4 + 10] ^= 0x01;
    ASSERT_TRUE(hwr::core::write_file_atomic(lcm(2), bytes).ok());
  }
  {
    std::string bytes = read_text(lcm(3));
    const size_t at = payload_size_offset("hwr-0");
    bytes[at] = 0x7f, bytes[at + 1] = bytes[at + 2] = bytes[at + 3] = static_cast<char>(0xff);
    ASSERT_TRUE(hwr::core::write_file_atomic(lcm(3), bytes).ok());
  }
  fs::resize_file(lcm(4), static_cast<uintmax_t>(GroundStore::kMaxStoredMessageBytes) + 1);
  ASSERT_TRUE(hwr::core::write_file_atomic(dir + "/notes.txt", std::string("an operator's file")).ok());

  {
    GroundStore store = open_ok(tmp.file("out"));
    const GroundStore::OpenReport& r = store.open_report();
    EXPECT_EQ(r.chunks_loaded, 2);
    EXPECT_EQ(r.temp_files_removed, 2);
    EXPECT_EQ(r.corrupt_quarantined, 4);
    EXPECT_EQ(r.lone_payloads_removed, 5) << "chunk 8's and those of the four quarantined chunks";
    EXPECT_EQ(r.payloads_rewritten, 1);
    std::string all_notes;
    for (const auto& n : r.notes) all_notes += n + "\n";
    EXPECT_NE(all_notes.find("64 MiB"), std::string::npos) << all_notes;
    EXPECT_NE(all_notes.find("CRC32 mismatch"), std::string::npos) << all_notes;
    EXPECT_NE(all_notes.find("notes.txt: not a chunk file, ignored"), std::string::npos) << all_notes;

    EXPECT_EQ(store.stored_link_seqs("hwr-0", chunks[0].run_id), (std::vector<int64_t>{0, 5}));
    EXPECT_EQ(names_in(dir), (std::set<std::string>{"chunk_000000.drc", "chunk_000000.lcm",
                                                    "chunk_000001.lcm.corrupt", "chunk_000002.lcm.corrupt",
                                                    "chunk_000003.lcm.corrupt", "chunk_000004.lcm.corrupt",
                                                    "chunk_000005.drc", "chunk_000005.lcm", "notes.txt"}));
    const std::string drc0 = read_text(drc(0));
    EXPECT_EQ(std::vector<uint8_t>(drc0.begin(), drc0.end()), chunks[0].payload) << "rewritten from the .lcm";
    const auto segs = store.segments("hwr-0", chunks[0].run_id);
    ASSERT_EQ(segs.size(), 1u);
    EXPECT_EQ(segs[0].chunks_stored, 2);

    // The robot resends what the store lacks; it is then stored normally.
    for (int i = 1; i <= 4; ++i) {
      bool was_new = false;
      ASSERT_TRUE(store.put(chunks[i], &was_new).ok());
      EXPECT_TRUE(was_new);
    }
  }
  GroundStore store = open_ok(tmp.file("out"));
  EXPECT_EQ(store.open_report().chunks_loaded, 6);
  EXPECT_EQ(store.open_report().corrupt_quarantined, 0);
  std::vector<map_chunk_t> loaded;
  ASSERT_TRUE(store.load_segment("hwr-0", chunks[0].run_id, 0, 0, &loaded).ok());
  ASSERT_EQ(loaded.size(), 6u);
  for (int i = 0; i < 6; ++i) EXPECT_EQ(encoded(loaded[i]), encoded(chunks[i])) << "chunk " << i;
}

TEST(GroundStore, GivenAFileDamagedAfterOpenThenLoadSegmentReportsCorruptData) {
  TempDir tmp;
  GroundStore store = open_ok(tmp.file("out"));
  const map_chunk_t c = make_chunk(ChunkSpec{});
  ASSERT_TRUE(store.put(c).ok());
  const std::string path = store.lcm_path(c.robot_id, c.run_id, 0, 0, 0);
  fs::resize_file(path, fs::file_size(path) - 1);
  std::vector<map_chunk_t> loaded;
  const auto st = store.load_segment(c.robot_id, c.run_id, 0, 0, &loaded);
  EXPECT_EQ(st.code(), ErrorCode::kCorruptData);
  EXPECT_NE(st.message().find(path), std::string::npos) << st.message();
}

// --- SIGKILL at random moments ----------------------------------------------------------------------

// The crash test's chunk for link_seq k: four chunks per segment, payloads of 1 kB .. 100 kB.
map_chunk_t crash_chunk(int64_t k) {
  ChunkSpec s;
  s.robot_id = "crash-bot";
  s.run_id = 42;
  s.link_seq = k;
  s.segment_id = static_cast<int32_t>(k / 4);
  s.chunk_index = static_cast<int32_t>(k % 4);
  s.chunk_count = s.chunk_index + 1;
  s.complete = s.chunk_index == 3;
  s.payload_bytes = 1000 + static_cast<size_t>((static_cast<uint64_t>(k) * 2654435761u) % 100000);
  return make_chunk(s);
}

[[noreturn]] void crash_child(const std::string& dir) {
  auto store = GroundStore::open(dir);
  if (!store.ok()) _exit(2);
  for (int64_t k = store->chunks_stored(); k < 1000000; ++k) {
    if (!store->put(crash_chunk(k)).ok()) _exit(3);
  }
  _exit(0);
}

TEST(GroundStore, GivenAWriterKilledAtRandomMomentsThenEveryListedChunkDecodesToWhatWasPut) {
  TempDir tmp;
  const std::string dir = tmp.file("out");
  std::mt19937 rng(20261125);
  std::uniform_int_distribution<int> delay_ms(5, 120);
  constexpr int kRounds = 20;
  size_t previous = 0;
  int interrupted = 0;
  for (int round = 0; round < kRounds; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    const int delay = delay_ms(rng);
    hwr::test::kill_writer_after(delay, [&] { crash_child(dir); });
    if (::testing::Test::HasFatalFailure()) return;

    if (!files_ending(dir, ".tmp").empty() || lone_payloads(dir) > 0) ++interrupted;
    GroundStore store = open_ok(dir);
    EXPECT_EQ(store.open_report().corrupt_quarantined, 0) << "a killed writer must never leave a bad .lcm";
    EXPECT_TRUE(files_ending(dir, ".tmp").empty()) << "temp files left after open()";
    EXPECT_EQ(lone_payloads(dir), 0) << "lone .drc left after open()";

    const std::vector<int64_t> seqs = store.stored_link_seqs("crash-bot", 42);
    ASSERT_GE(seqs.size(), previous) << "chunks disappeared";
    for (size_t i = 0; i < seqs.size(); ++i)
      ASSERT_EQ(seqs[i], static_cast<int64_t>(i)) << "not a prefix 0..k-1";
    for (const auto& seg : store.segments("crash-bot", 42)) {
      const int64_t last_k = 4 * int64_t{seg.segment_id} + seg.chunks_stored - 1;
      if (last_k < static_cast<int64_t>(previous) && round != kRounds - 1) continue;  // checked before
      std::vector<map_chunk_t> loaded;
      ASSERT_TRUE(store.load_segment("crash-bot", 42, seg.segment_id, 0, &loaded).ok());
      EXPECT_EQ(seg.complete, seg.chunks_stored == 4);
      for (const map_chunk_t& c : loaded) {
        ASSERT_EQ(encoded(c), encoded(crash_chunk(c.link_seq))) << "link_seq " << c.link_seq;
        const std::string drc = read_text(store.drc_path("crash-bot", 42, c.segment_id, 0, c.chunk_index));
        ASSERT_EQ(std::vector<uint8_t>(drc.begin(), drc.end()), c.payload) << "link_seq " << c.link_seq;
      }
    }
    previous = seqs.size();
  }
  std::printf("[ crash    ] %d kills: %zu chunks stored, %d kills landed inside a put\n", kRounds, previous,
              interrupted);
  EXPECT_GT(previous, 0u) << "the writer never stored a chunk: the test checked nothing";
  EXPECT_GT(interrupted, 0) << "no kill landed inside a put: the test checked nothing";
}

}  // namespace
