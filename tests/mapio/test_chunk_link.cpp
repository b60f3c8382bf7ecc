// The reliable chunk link (issue #5 item 3): AckTracker and ChunkSender with closed-form
// expectations, then the whole protocol in simulated time through a faulty transport
// (fault_transport.hpp): loss, reordering, duplication, a 5 s cut and a ground-station restart.
// Oracle for the link runs: the ground side's stored set holds every chunk exactly once, each
// byte-identical to what the robot produced (payload regenerated independently, CRC as sealed).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "fault_transport.hpp"
#include "hwr/mapio/ack_tracker.hpp"
#include "hwr/mapio/chunk_sender.hpp"
#include "hwr/mapio/chunk_wire.hpp"

namespace hwr::mapio {
namespace {

using test::FaultConfig;
using test::FaultStats;

constexpr int64_t kMs = 1'000'000;
constexpr int64_t kS = 1'000'000'000;

// ---------------------------------------------------------------------------------------------
// AckTracker

std::vector<int64_t> selective_of(const AckTracker& t) {
  hwr_lcm::chunk_ack_t a;
  t.make_ack(&a, false);
  EXPECT_EQ(a.num_selective, static_cast<int32_t>(a.selective.size()));
  return a.selective;
}

TEST(AckTracker, DuplicatesRefusedAndCumulativeAdvancesOverFilledGaps) {
  AckTracker t("hwr-0", 5, 64, 16);
  EXPECT_EQ(t.cumulative_seq(), -1);
  EXPECT_TRUE(t.record(0));
  EXPECT_FALSE(t.record(0));  // duplicate
  EXPECT_EQ(t.classify(0), AckTracker::SeqClass::kStored);
  EXPECT_TRUE(t.record(2));
  EXPECT_TRUE(t.record(4));
  EXPECT_EQ(t.cumulative_seq(), 0);
  EXPECT_EQ(selective_of(t), (std::vector<int64_t>{2, 4}));
  EXPECT_FALSE(t.record(2));
  EXPECT_TRUE(t.record(1));  // fills the gap: cumulative jumps over 2
  EXPECT_EQ(t.cumulative_seq(), 2);
  EXPECT_EQ(selective_of(t), (std::vector<int64_t>{4}));
  EXPECT_TRUE(t.record(3));
  EXPECT_EQ(t.cumulative_seq(), 4);
  EXPECT_TRUE(selective_of(t).empty());
  EXPECT_FALSE(t.record(-1));
  EXPECT_EQ(t.classify(-1), AckTracker::SeqClass::kInvalid);
  EXPECT_EQ(t.num_recorded(), 5);

  hwr_lcm::chunk_ack_t a;
  t.make_ack(&a, true);
  EXPECT_EQ(a.robot_id, "hwr-0");
  EXPECT_EQ(a.run_id, 5);
  EXPECT_EQ(a.cumulative_seq, 4);
  EXPECT_EQ(a.resume_report, 1);
  EXPECT_TRUE(verify_ack(a, ChunkWireLimits{}).ok());
}

TEST(AckTracker, BeyondWindowRefusedUntilTheWindowMoves) {
  AckTracker t("hwr-0", 5, 64, 16);  // window [cumulative + 1, cumulative + 64]
  EXPECT_EQ(t.classify(64), AckTracker::SeqClass::kBeyondWindow);
  EXPECT_FALSE(t.record(64));
  EXPECT_EQ(t.num_recorded(), 0);  // refused, not recorded
  EXPECT_TRUE(t.record(63));       // the window's last seq (same ring position as 64 + 63 later)
  for (int64_t s = 0; s < 63; ++s) ASSERT_TRUE(t.record(s));
  EXPECT_EQ(t.cumulative_seq(), 63);
  EXPECT_EQ(t.classify(127), AckTracker::SeqClass::kNew);  // ring positions reused, clean
  EXPECT_EQ(t.classify(128), AckTracker::SeqClass::kBeyondWindow);
  EXPECT_TRUE(t.record(127));
  EXPECT_FALSE(t.record(128));
  EXPECT_EQ(selective_of(t), (std::vector<int64_t>{127}));
  // A hostile seq far away (found by fuzz_ack_message: the window test overflowed).
  EXPECT_EQ(t.classify(std::numeric_limits<int64_t>::max()), AckTracker::SeqClass::kBeyondWindow);
  AckTracker fresh("hwr-0", 5, 64, 16);
  EXPECT_FALSE(fresh.record(std::numeric_limits<int64_t>::max()));
  EXPECT_EQ(fresh.num_recorded(), 0);
}

TEST(AckTracker, SelectiveListIsTheLowestStoredAboveCumulativeCapped) {
  AckTracker t("r", 1, 256, 3);
  for (int64_t s : {9, 3, 250, 7, 5, 100}) ASSERT_TRUE(t.record(s));
  EXPECT_EQ(selective_of(t), (std::vector<int64_t>{3, 5, 7}));
  AckTracker all("r", 1, 256, 100);
  for (int64_t s : {9, 3, 250, 7, 5, 100, 64, 63, 127, 128}) ASSERT_TRUE(all.record(s));
  EXPECT_EQ(selective_of(all), (std::vector<int64_t>{3, 5, 7, 9, 63, 64, 100, 127, 128, 250}));
}

TEST(AckTracker, MatchesASetOracleOnAShuffledStream) {
  // A sender window of 64 delivering out of order with duplicates, 20000 seqs through a ring of 128.
  std::mt19937_64 rng(3);
  AckTracker t("r", 1, 128, 1000);
  std::set<int64_t> stored;
  int64_t next = 0;
  std::vector<int64_t> outstanding;
  int64_t oracle_cum = -1;  // every seq <= it is in `stored`
  while (next < 20000 || !outstanding.empty()) {
    while (next < 20000 && outstanding.size() < 64) outstanding.push_back(next++);
    const size_t k = rng() % outstanding.size();
    const int64_t s = outstanding[k];
    const bool expect_new = stored.count(s) == 0;
    const auto cls = t.classify(s);
    while (stored.count(oracle_cum + 1)) ++oracle_cum;
    const bool beyond = s > oracle_cum + 128;
    ASSERT_EQ(cls, beyond ? AckTracker::SeqClass::kBeyondWindow
                          : (expect_new ? AckTracker::SeqClass::kNew : AckTracker::SeqClass::kStored));
    ASSERT_EQ(t.record(s), expect_new && !beyond);
    if (expect_new && !beyond) stored.insert(s);
    if (!beyond && rng() % 4 != 0) outstanding.erase(outstanding.begin() + static_cast<long>(k));  // else dup
    if (rng() % 50 == 0) {
      while (stored.count(oracle_cum + 1)) ++oracle_cum;
      ASSERT_EQ(t.cumulative_seq(), oracle_cum);
      std::vector<int64_t> expect(stored.upper_bound(oracle_cum), stored.end());
      ASSERT_EQ(selective_of(t), expect);
    }
  }
  EXPECT_EQ(t.cumulative_seq(), 19999);
  EXPECT_EQ(t.num_recorded(), 20000);
}

TEST(AckTracker, RestoreRebuildsFromStoredSeqs) {
  AckTracker t("r", 1, 64, 100);
  ASSERT_TRUE(t.record(40));
  EXPECT_TRUE(t.restore({7, 0, 1, 2, 5, 2, 1}).ok());
  EXPECT_EQ(t.cumulative_seq(), 2);
  EXPECT_EQ(selective_of(t), (std::vector<int64_t>{5, 7}));  // 40 was forgotten
  EXPECT_FALSE(t.record(5));
  EXPECT_TRUE(t.record(40));

  // Window after restoring 0 and 1: [2, 65].
  const core::Status beyond = t.restore({0, 1, 65, 66, 200});
  EXPECT_EQ(beyond.code(), core::ErrorCode::kOutOfRange);
  EXPECT_NE(beyond.message().find("2 stored link_seq values from 66"), std::string::npos)
      << beyond.to_string();
  EXPECT_EQ(t.cumulative_seq(), 1);
  EXPECT_EQ(selective_of(t), (std::vector<int64_t>{65}));
  EXPECT_EQ(t.classify(66), AckTracker::SeqClass::kBeyondWindow);

  const core::Status negative = t.restore({-3, 0});
  EXPECT_EQ(negative.code(), core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(t.cumulative_seq(), 0);
}

// ---------------------------------------------------------------------------------------------
// ChunkSender, closed-form

hwr_lcm::map_chunk_t plain_chunk(size_t payload_bytes, int index = 0) {
  hwr_lcm::map_chunk_t c;  // LCM types leave their scalars uninitialized: set every field
  c.t_ns = 0;
  c.segment_id = 0;
  c.segment_version = 0;
  c.chunk_index = index;
  c.segment_complete = 0;
  c.chunk_count = index + 1;
  for (int i = 0; i < 12; ++i) c.T_world_segment[i] = (i % 5 == 0) ? 1.0 : 0.0;  // identity
  c.num_points = 1;
  c.has_normals = 0;
  c.max_position_error_m = 0.001f;
  c.payload.assign(payload_bytes, static_cast<uint8_t>(index));
  return c;
}

hwr_lcm::chunk_ack_t ack_of(const ChunkSender& s, int64_t cumulative, std::vector<int64_t> selective,
                            bool resume = false) {
  hwr_lcm::chunk_ack_t a;
  a.t_ns = 0;
  a.robot_id = s.robot_id();
  a.run_id = s.run_id();
  a.cumulative_seq = cumulative;
  a.selective = std::move(selective);
  a.resume_report = resume ? 1 : 0;
  seal_ack(&a);
  return a;
}

struct Published {
  std::vector<int64_t> seqs;
  std::vector<hwr_lcm::map_chunk_t> chunks;
  void clear() {
    seqs.clear();
    chunks.clear();
  }
};

int service(ChunkSender& s, int64_t now_ns, Published* out) {
  out->clear();
  return s.service(now_ns, [out](const hwr_lcm::map_chunk_t& c) {
    out->seqs.push_back(c.link_seq);
    out->chunks.push_back(c);
  });
}

TEST(ChunkSender, OfferNumbersStampsAndSeals) {
  ChunkSender s("hwr-7", 99, LinkConfig{});
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(s.offer(plain_chunk(100, i), 0));
  Published p;
  EXPECT_EQ(service(s, 5, &p), 3);
  ASSERT_EQ(p.seqs, (std::vector<int64_t>{0, 1, 2}));
  for (const auto& c : p.chunks) {
    EXPECT_EQ(c.robot_id, "hwr-7");
    EXPECT_EQ(c.run_id, 99);
    EXPECT_EQ(c.t_ns, 5);
    EXPECT_EQ(c.payload_size, 100);
    EXPECT_TRUE(verify_chunk(c, ChunkWireLimits{}).ok()) << verify_chunk(c, ChunkWireLimits{}).to_string();
  }
  EXPECT_EQ(s.stats().sends, 3);
  EXPECT_EQ(s.next_link_seq(), 3);
}

TEST(ChunkSender, WindowBoundsChunksAndBytes) {
  LinkConfig cfg;
  cfg.window_chunks = 4;
  cfg.window_bytes = 1000;
  ChunkSender s("r", 1, cfg);
  EXPECT_TRUE(s.offer(plain_chunk(600), 0));
  EXPECT_FALSE(s.can_accept(401));
  auto big = plain_chunk(401);
  EXPECT_FALSE(s.offer(std::move(big), 0));
  EXPECT_EQ(big.payload.size(), 401u);        // refused: left untouched for a later offer
  EXPECT_TRUE(s.offer(plain_chunk(400), 0));  // exactly full in bytes
  EXPECT_EQ(s.stats().in_flight_bytes, 1000u);
  EXPECT_FALSE(s.offer(plain_chunk(1), 0));
  EXPECT_FALSE(s.can_accept(1001));
  ChunkSender n("r", 1, cfg);
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(n.offer(plain_chunk(10, i), 0));
  EXPECT_FALSE(n.offer(plain_chunk(10), 0));  // 5th chunk
  EXPECT_EQ(n.stats().window_full_refusals, 1);
  EXPECT_EQ(s.stats().window_full_refusals, 2);
  Published p;
  service(n, 0, &p);
  n.on_ack(ack_of(n, 0, {}), 1);
  EXPECT_TRUE(n.offer(plain_chunk(10), 1));
  EXPECT_EQ(n.stats().max_in_flight, 4);
}

TEST(ChunkSender, ServiceSendsInSeqOrderCappedPerCall) {
  LinkConfig cfg;
  cfg.max_sends_per_service = 3;
  ChunkSender s("r", 1, cfg);
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(s.offer(plain_chunk(10, i), 0));
  Published p;
  EXPECT_EQ(service(s, 0, &p), 3);
  EXPECT_EQ(p.seqs, (std::vector<int64_t>{0, 1, 2}));
  EXPECT_EQ(service(s, 0, &p), 2);
  EXPECT_EQ(p.seqs, (std::vector<int64_t>{3, 4}));
  EXPECT_EQ(service(s, 1, &p), 0);
}

TEST(ChunkSender, ExponentialBackoffCappedAndResetOnProgress) {
  LinkConfig cfg;  // 200 ms, x2
  cfg.max_rto_ns = 1000 * kMs;
  ChunkSender s("r", 1, cfg);
  ASSERT_TRUE(s.offer(plain_chunk(10, 0), 0));
  ASSERT_TRUE(s.offer(plain_chunk(10, 1), 0));
  Published p;
  EXPECT_EQ(service(s, 0, &p), 2);
  EXPECT_EQ(s.next_due_ns(), 200 * kMs);
  EXPECT_EQ(service(s, 200 * kMs - 1, &p), 0);
  EXPECT_EQ(service(s, 200 * kMs, &p), 2);  // resend 1, next timeout 400 ms
  EXPECT_EQ(s.next_due_ns(), 600 * kMs);
  EXPECT_EQ(service(s, 600 * kMs, &p), 2);  // resend 2, next 800 ms
  EXPECT_EQ(s.next_due_ns(), 1400 * kMs);
  EXPECT_EQ(service(s, 1400 * kMs, &p), 2);  // resend 3, 1600 ms capped to 1000 ms
  EXPECT_EQ(s.next_due_ns(), 2400 * kMs);
  EXPECT_EQ(s.stats().max_rto_seen_ns, 1000 * kMs);
  EXPECT_EQ(s.stats().resends, 6);
  // Progress at 1500 ms: seq 0 acknowledged; seq 1's timer becomes last send + 200 ms.
  s.on_ack(ack_of(s, 0, {}), 1500 * kMs);
  EXPECT_EQ(s.stats().acked, 1);
  EXPECT_EQ(s.next_due_ns(), 1600 * kMs);
  EXPECT_EQ(service(s, 1600 * kMs, &p), 1);
  EXPECT_EQ(p.seqs, (std::vector<int64_t>{1}));
  EXPECT_EQ(s.next_due_ns(), 2000 * kMs);  // backoff restarted: 200 ms x 2
  // An ack without progress (a duplicate) changes nothing.
  s.on_ack(ack_of(s, 0, {}), 1700 * kMs);
  EXPECT_EQ(s.next_due_ns(), 2000 * kMs);
}

TEST(ChunkSender, CumulativeSelectiveForeignAndInvalidAcks) {
  ChunkSender s("r", 1, LinkConfig{});
  for (int i = 0; i < 6; ++i) ASSERT_TRUE(s.offer(plain_chunk(100, i), 0));
  Published p;
  service(s, 0, &p);
  auto foreign = ack_of(s, 5, {});
  foreign.robot_id = "other";
  s.on_ack(foreign, 1);
  foreign = ack_of(s, 5, {});
  foreign.run_id = 2;
  s.on_ack(foreign, 1);
  EXPECT_EQ(s.stats().foreign_acks, 2);
  s.on_ack(ack_of(s, 6, {}), 1);  // seq 6 was never assigned
  s.on_ack(ack_of(s, 1, {9}), 1);
  s.on_ack(ack_of(s, std::numeric_limits<int64_t>::max(), {}), 1);
  s.on_ack(ack_of(s, -2, {}), 1);
  EXPECT_EQ(s.stats().invalid_acks, 4);
  EXPECT_EQ(s.stats().in_flight, 6);
  s.on_ack(ack_of(s, 1, {4, 3}), 2);  // unsorted selective is fine
  EXPECT_EQ(s.stats().in_flight, 2);
  EXPECT_EQ(s.stats().in_flight_bytes, 200u);
  EXPECT_EQ(s.stats().acked, 4);
  EXPECT_EQ(service(s, 202 * kMs, &p), 2);
  EXPECT_EQ(p.seqs, (std::vector<int64_t>{2, 5}));  // only the unacknowledged are resent
  s.on_ack(ack_of(s, 5, {}), 3);
  EXPECT_TRUE(s.idle());
  EXPECT_EQ(s.next_due_ns(), std::numeric_limits<int64_t>::max());
}

TEST(ChunkSender, ResumeReportRewindsEverythingNotListed) {
  ChunkSender s("r", 1, LinkConfig{});
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(s.offer(plain_chunk(10, i), 0));
  Published p;
  service(s, 0, &p);
  EXPECT_EQ(service(s, 10 * kMs, &p), 0);
  s.on_ack(ack_of(s, 0, {2}, /*resume=*/true), 10 * kMs);
  EXPECT_EQ(s.stats().resume_reports, 1);
  EXPECT_EQ(service(s, 10 * kMs, &p), 3);
  EXPECT_EQ(p.seqs, (std::vector<int64_t>{1, 3, 4}));
  EXPECT_EQ(s.stats().resends, 3);
}

// ---------------------------------------------------------------------------------------------
// The link in simulated time

constexpr int kChunksPerSegment = 50;

// The robot's chunks: deterministic from (seed, index), so the ground side can regenerate the
// expected bytes independently instead of keeping copies.
struct ChunkSource {
  uint64_t seed;
  std::vector<size_t> sizes;
  ChunkSource(uint64_t s, int n) : seed(s) {
    std::mt19937_64 rng(s);
    std::uniform_int_distribution<size_t> size(1024, 300 * 1024);
    for (int i = 0; i < n; ++i) sizes.push_back(size(rng));
  }
  void fill_payload(int i, std::vector<uint8_t>* out) const {
    out->resize(sizes[static_cast<size_t>(i)]);
    uint64_t x = seed * 0x9E3779B97F4A7C15ull + static_cast<uint64_t>(i) + 1;  // splitmix64
    for (size_t k = 0; k < out->size(); k += 8) {
      uint64_t z = (x += 0x9E3779B97F4A7C15ull);
      z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
      z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
      z ^= z >> 31;
      std::memcpy(out->data() + k, &z, std::min<size_t>(8, out->size() - k));
    }
  }
  hwr_lcm::map_chunk_t make(int i) const {
    hwr_lcm::map_chunk_t c;
    c.t_ns = 0;
    c.segment_id = i / kChunksPerSegment;
    c.segment_version = 0;
    c.chunk_index = i % kChunksPerSegment;
    c.segment_complete = (i % kChunksPerSegment == kChunksPerSegment - 1) ? 1 : 0;
    c.chunk_count = c.chunk_index + 1;
    const double yaw = 0.01 * i;
    const double T[12] = {
        std::cos(yaw), -std::sin(yaw), 0, 0.5 * i, std::sin(yaw), std::cos(yaw), 0, -0.1 * i, 0, 0, 1, 0.02};
    std::memcpy(c.T_world_segment, T, sizeof T);
    c.num_points = static_cast<int32_t>(sizes[static_cast<size_t>(i)] / 16 + 1);
    c.has_normals = 0;
    c.max_position_error_m = 0.001f;
    fill_payload(i, &c.payload);
    return c;
  }
};

struct Scenario {
  FaultConfig up, down;
  uint64_t seed = 1;
  int num_chunks = 2000;
  LinkConfig link;
  bool restart = false;
  int64_t kill_ns = 0, restart_ns = 0;
  bool restore_on_restart = true;  // false: a deliberately broken ground station (negative control)
  int64_t tick_ns = 1 * kMs;
  int64_t max_sim_ns = 120 * kS;
};

struct Outcome {
  int64_t end_ns = 0;
  bool sender_idle = false;
  int offered = 0;
  int stored = 0;             // distinct chunks on the ground's "disk"
  int stored_twice = 0;       // a chunk the ground stored again: must be 0
  int payload_mismatch = 0;   // stored bytes differ from what the robot produced: must be 0
  int crc_mismatch = 0;       // stored CRC differs from the one the robot sealed: must be 0
  int link_seq_mismatch = 0;  // the chunk for index i did not carry link_seq i
  int missing = 0;            // chunks 0..n-1 absent at the end
  int rejected = 0;           // undecodable or failing verify_chunk (corruption)
  int acks_rejected = 0;      // robot side: undecodable or failing verify_ack (corruption)
  int duplicates_ignored = 0;
  int beyond_window = 0;
  int window_violations = 0;  // in-flight chunks or bytes above the configured window
  int stored_at_cut = -1, stored_at_kill = -1;
  ChunkSender::Stats sender;
  FaultStats up, down;
};

class Ground {
 public:
  Ground(const ChunkSource& source, const std::string& robot_id, int64_t run_id)
      : source_(source), robot_id_(robot_id), run_id_(run_id) {
    start(/*restore=*/false);
  }
  void kill() { tracker_.reset(); }
  // Returns the resume report to send.
  const std::vector<uint8_t>& start(bool restore) {
    tracker_ = std::make_unique<AckTracker>(robot_id_, run_id_);
    if (restore) {
      std::vector<int64_t> seqs;
      for (const auto& [seq, info] : disk_) seqs.push_back(seq);
      EXPECT_TRUE(tracker_->restore(seqs).ok());
    }
    tracker_->make_ack(&ack_, /*resume_report=*/true);
    EXPECT_TRUE(encode_ack_message(ack_, &ack_bytes_).ok());
    return ack_bytes_;
  }
  bool up() const { return tracker_ != nullptr; }

  // Handles one received message; returns true with *ack_out set when an ack is to be sent.
  bool receive(const std::vector<uint8_t>& bytes, const std::vector<int64_t>& sealed_crc, Outcome* o,
               std::vector<uint8_t>** ack_out) {
    if (!up()) return false;
    if (!decode_chunk_message(bytes.data(), bytes.size(), &msg_).ok() || !verify_chunk(msg_, limits_).ok()) {
      ++o->rejected;
      return false;
    }
    if (msg_.robot_id != robot_id_ || msg_.run_id != run_id_) return false;
    switch (tracker_->classify(msg_.link_seq)) {
      case AckTracker::SeqClass::kNew:
        store(sealed_crc, o);  // durable first, then record, then acknowledge
        tracker_->record(msg_.link_seq);
        break;
      case AckTracker::SeqClass::kStored:
        ++o->duplicates_ignored;
        break;
      case AckTracker::SeqClass::kBeyondWindow:
        ++o->beyond_window;
        return false;
      case AckTracker::SeqClass::kInvalid:
        ++o->rejected;
        return false;
    }
    tracker_->make_ack(&ack_, false);
    EXPECT_TRUE(encode_ack_message(ack_, &ack_bytes_).ok());
    *ack_out = &ack_bytes_;
    return true;
  }

  const std::map<int64_t, int>& disk() const { return disk_; }

 private:
  void store(const std::vector<int64_t>& sealed_crc, Outcome* o) {
    const int index = msg_.segment_id * kChunksPerSegment + msg_.chunk_index;
    if (!keys_.insert(index).second) ++o->stored_twice;
    disk_[msg_.link_seq] = index;
    if (msg_.link_seq != index) ++o->link_seq_mismatch;
    if (index < 0 || index >= static_cast<int>(source_.sizes.size())) {
      ++o->payload_mismatch;
      return;
    }
    source_.fill_payload(index, &expected_);
    if (msg_.payload != expected_) ++o->payload_mismatch;
    if (static_cast<size_t>(msg_.link_seq) >= sealed_crc.size() ||
        sealed_crc[static_cast<size_t>(msg_.link_seq)] != msg_.crc32) {
      ++o->crc_mismatch;
    }
  }

  const ChunkSource& source_;
  std::string robot_id_;
  int64_t run_id_;
  ChunkWireLimits limits_;
  std::unique_ptr<AckTracker> tracker_;
  std::map<int64_t, int> disk_;  // link_seq -> chunk index; survives restarts
  std::set<int> keys_;
  hwr_lcm::map_chunk_t msg_;
  hwr_lcm::chunk_ack_t ack_;
  std::vector<uint8_t> ack_bytes_, expected_;
};

Outcome run_link(const Scenario& sc) {
  const std::string robot_id = "hwr-0";
  const int64_t run_id = 1732477000000000000;
  const ChunkSource source(sc.seed, sc.num_chunks);
  test::FaultLink link(sc.up, sc.down, sc.seed);
  ChunkSender sender(robot_id, run_id, sc.link);
  Ground ground(source, robot_id, run_id);
  Outcome o;
  std::vector<int64_t> sealed_crc(static_cast<size_t>(sc.num_chunks), -1);  // robot-side record
  std::vector<std::vector<uint8_t>> msgs;
  std::vector<uint8_t> wire;
  hwr_lcm::chunk_ack_t ack;
  hwr_lcm::map_chunk_t pending;
  bool have_pending = false;
  int next = 0;
  bool killed = false, restarted = false;

  int64_t t = 0;
  for (; t <= sc.max_sim_ns; t += sc.tick_ns) {
    if (o.stored_at_cut < 0 && sc.up.cut_end_ns > sc.up.cut_begin_ns && t >= sc.up.cut_begin_ns) {
      o.stored_at_cut = static_cast<int>(ground.disk().size());
    }
    if (sc.restart && !killed && t >= sc.kill_ns) {
      killed = true;
      o.stored_at_kill = static_cast<int>(ground.disk().size());
      ground.kill();
    }
    if (sc.restart && killed && !restarted && t >= sc.restart_ns) {
      restarted = true;
      link.down.send(ground.start(sc.restore_on_restart), t);
    }
    // Ground side.
    link.up.poll(t, &msgs);
    for (const auto& m : msgs) {
      std::vector<uint8_t>* ack_bytes = nullptr;
      if (ground.receive(m, sealed_crc, &o, &ack_bytes)) link.down.send(*ack_bytes, t);
    }
    // Robot side: acks, then new chunks while the window has room, then publication.
    link.down.poll(t, &msgs);
    for (const auto& m : msgs) {
      if (decode_ack_message(m.data(), m.size(), &ack).ok() && verify_ack(ack, ChunkWireLimits{}).ok()) {
        sender.on_ack(ack, t);
      } else {
        ++o.acks_rejected;
      }
    }
    while (next < sc.num_chunks) {
      if (!have_pending) {
        pending = source.make(next);
        have_pending = true;
      }
      if (!sender.offer(std::move(pending), t)) break;  // back-pressure: keep it for later
      have_pending = false;
      ++next;
    }
    sender.service(t, [&](const hwr_lcm::map_chunk_t& c) {
      if (c.link_seq < sc.num_chunks && sealed_crc[static_cast<size_t>(c.link_seq)] < 0) {
        sealed_crc[static_cast<size_t>(c.link_seq)] = c.crc32;
      }
      EXPECT_TRUE(encode_chunk_message(c, &wire).ok());
      link.up.send(wire, t);
    });
    const auto& st = sender.stats();
    if (st.in_flight > sc.link.window_chunks || st.in_flight_bytes > sc.link.window_bytes)
      ++o.window_violations;
    if (next == sc.num_chunks && sender.idle() && (!sc.restart || restarted)) break;
  }
  o.end_ns = t;
  o.offered = next;
  o.sender_idle = sender.idle();
  o.sender = sender.stats();
  o.up = link.up.stats();
  o.down = link.down.stats();
  o.stored = static_cast<int>(ground.disk().size());
  std::set<int> indices;
  for (const auto& [seq, index] : ground.disk()) indices.insert(index);
  for (int i = 0; i < sc.num_chunks; ++i) o.missing += indices.count(i) == 0 ? 1 : 0;
  return o;
}

void report(const char* name, const Outcome& o) {
  std::printf(
      "[link %s] sim %.2f s: stored %d, sends %lld, resends %lld, acks %lld, resume %lld, refusals %lld, "
      "max in flight %d chunks / %.1f MiB, max rto %.0f ms | up: sent %lld lost %lld cut %lld dup %lld "
      "reord %lld corrupt %lld | down: sent %lld lost %lld cut %lld dup %lld | ground: dup ignored %d, "
      "rejected %d, beyond window %d | robot: acks rejected %d\n",
      name, static_cast<double>(o.end_ns) / kS, o.stored, static_cast<long long>(o.sender.sends),
      static_cast<long long>(o.sender.resends), static_cast<long long>(o.sender.acks),
      static_cast<long long>(o.sender.resume_reports), static_cast<long long>(o.sender.window_full_refusals),
      o.sender.max_in_flight, static_cast<double>(o.sender.max_in_flight_bytes) / (1 << 20),
      static_cast<double>(o.sender.max_rto_seen_ns) / kMs, static_cast<long long>(o.up.sent),
      static_cast<long long>(o.up.lost), static_cast<long long>(o.up.cut),
      static_cast<long long>(o.up.duplicated), static_cast<long long>(o.up.reordered),
      static_cast<long long>(o.up.corrupted), static_cast<long long>(o.down.sent),
      static_cast<long long>(o.down.lost), static_cast<long long>(o.down.cut),
      static_cast<long long>(o.down.duplicated), o.duplicates_ignored, o.rejected, o.beyond_window,
      o.acks_rejected);
  std::fflush(stdout);
}

// Every chunk exactly once, byte-identical, nothing left in flight, the window respected.
void expect_delivered_exactly_once(const Scenario& sc, const Outcome& o) {
  EXPECT_TRUE(o.sender_idle) << "sender still has " << o.sender.in_flight << " chunks in flight";
  EXPECT_EQ(o.offered, sc.num_chunks);
  EXPECT_EQ(o.stored, sc.num_chunks);
  EXPECT_EQ(o.missing, 0);
  EXPECT_EQ(o.stored_twice, 0);
  EXPECT_EQ(o.payload_mismatch, 0);
  EXPECT_EQ(o.crc_mismatch, 0);
  EXPECT_EQ(o.link_seq_mismatch, 0);
  EXPECT_EQ(o.window_violations, 0);
  EXPECT_LE(o.sender.max_in_flight, sc.link.window_chunks);
  EXPECT_LE(o.sender.max_in_flight_bytes, sc.link.window_bytes);
  EXPECT_EQ(o.sender.sends, sc.num_chunks);
  EXPECT_EQ(o.sender.acked, sc.num_chunks);
}

FaultConfig wired(double rate_bytes_per_s = 125e6) {  // 1 Gbit/s, 1 ms latency
  FaultConfig f;
  f.latency_ns = 1 * kMs;
  f.rate_bytes_per_s = rate_bytes_per_s;
  return f;
}

TEST(ChunkLink, CleanLinkNeedsNoResends) {
  Scenario sc;
  sc.up = wired();
  sc.down = wired();
  const Outcome o = run_link(sc);
  report("clean", o);
  expect_delivered_exactly_once(sc, o);
  EXPECT_EQ(o.sender.resends, 0);
  EXPECT_EQ(o.duplicates_ignored, 0);
  EXPECT_GT(o.sender.window_full_refusals, 0);  // the link, not the producer, set the pace
}

TEST(ChunkLink, TenPercentLossEachWay) {
  Scenario sc;
  sc.seed = 2;
  sc.up = wired();
  sc.down = wired();
  sc.up.loss = sc.down.loss = 0.10;
  const Outcome o = run_link(sc);
  report("loss 10%", o);
  expect_delivered_exactly_once(sc, o);
  EXPECT_GT(o.up.lost, 100);
  EXPECT_GT(o.down.lost, 100);
  EXPECT_GE(o.sender.resends, o.up.lost);  // every lost chunk was resent at least once
}

TEST(ChunkLink, Reordering) {
  Scenario sc;
  sc.seed = 3;
  sc.up = wired();
  sc.down = wired();
  sc.up.reorder = sc.down.reorder = 0.5;
  sc.up.reorder_max_delay_ns = sc.down.reorder_max_delay_ns = 40 * kMs;
  const Outcome o = run_link(sc);
  report("reorder", o);
  expect_delivered_exactly_once(sc, o);
  EXPECT_GT(o.up.reordered, 500);
}

TEST(ChunkLink, TwentyPercentDuplication) {
  Scenario sc;
  sc.seed = 4;
  sc.up = wired();
  sc.down = wired();
  sc.up.duplicate = sc.down.duplicate = 0.20;
  const Outcome o = run_link(sc);
  report("dup 20%", o);
  expect_delivered_exactly_once(sc, o);
  EXPECT_GT(o.up.duplicated, 200);
  EXPECT_GE(o.duplicates_ignored, o.up.duplicated);  // each duplicate reached the ground and was ignored
}

TEST(ChunkLink, FiveSecondCutMidStream) {
  Scenario sc;
  sc.seed = 5;
  sc.up = wired();
  sc.down = wired();
  sc.up.cut_begin_ns = sc.down.cut_begin_ns = 1 * kS;
  sc.up.cut_end_ns = sc.down.cut_end_ns = 6 * kS;
  const Outcome o = run_link(sc);
  report("cut 5 s", o);
  expect_delivered_exactly_once(sc, o);
  EXPECT_GT(o.stored_at_cut, 0);
  EXPECT_LT(o.stored_at_cut, sc.num_chunks);  // the cut really was mid-stream
  EXPECT_GT(o.end_ns, 6 * kS);
  EXPECT_GT(o.sender.max_rto_seen_ns, sc.link.initial_rto_ns);  // backed off during the cut
  // After the cut the backoff reset lets the stream resume at once, not after a long timer.
  EXPECT_LT(o.end_ns, 6 * kS + 4 * kS);
}

TEST(ChunkLink, GroundStationRestartResumes) {
  Scenario sc;
  sc.seed = 6;
  sc.up = wired();
  sc.down = wired();
  sc.up.loss = sc.down.loss = 0.02;  // so some chunks are stored but unacknowledged at the kill
  sc.restart = true;
  sc.kill_ns = 1 * kS;
  sc.restart_ns = 1500 * kMs;
  const Outcome o = run_link(sc);
  report("restart", o);
  expect_delivered_exactly_once(sc, o);
  EXPECT_GT(o.stored_at_kill, 0);
  EXPECT_LT(o.stored_at_kill, sc.num_chunks);
  EXPECT_EQ(o.sender.resume_reports, 1);
}

TEST(ChunkLink, AllFaultsCombined) {
  Scenario sc;
  sc.seed = 7;
  sc.up = wired();
  sc.down = wired();
  for (FaultConfig* f : {&sc.up, &sc.down}) {
    f->loss = 0.10;
    f->reorder = 0.3;
    f->reorder_max_delay_ns = 30 * kMs;
    f->duplicate = 0.20;
    f->cut_begin_ns = 1 * kS;
    f->cut_end_ns = 6 * kS;
  }
  sc.up.corrupt = 0.01;    // chunks
  sc.down.corrupt = 0.01;  // acks: a flipped bit that still decodes must fail the ack's CRC
  sc.restart = true;
  sc.kill_ns = 6500 * kMs;
  sc.restart_ns = 7000 * kMs;
  sc.link.window_bytes = 8u << 20;  // the byte bound binds as well
  const Outcome o = run_link(sc);
  report("combined", o);
  expect_delivered_exactly_once(sc, o);
  EXPECT_GT(o.stored_at_cut, 0);
  EXPECT_LT(o.stored_at_kill, sc.num_chunks);
  EXPECT_GT(o.rejected, 0);  // corrupted copies were caught by the CRC
  EXPECT_GT(o.down.corrupted, 0);
  EXPECT_GT(o.acks_rejected, 0);  // corrupted acks were refused, and nothing went missing for it
  EXPECT_EQ(o.sender.resume_reports, 1);
}

TEST(ChunkLink, OracleCatchesAGroundStationThatForgetsOnRestart) {
  // Negative control: a ground station that restarts without restore() stores chunks it already had
  // (or never acknowledges again below its lost cumulative point). The oracle must notice.
  Scenario sc;
  sc.seed = 6;
  sc.num_chunks = 600;
  sc.up = wired();
  sc.down = wired();
  sc.up.loss = sc.down.loss = 0.05;
  sc.restart = true;
  sc.kill_ns = 300 * kMs;
  sc.restart_ns = 400 * kMs;
  sc.restore_on_restart = false;
  sc.max_sim_ns = 20 * kS;
  const Outcome o = run_link(sc);
  report("forgetful ground (negative control)", o);
  EXPECT_GT(o.stored_at_kill, 0);
  EXPECT_TRUE(o.stored_twice > 0 || !o.sender_idle)
      << "a forgetful ground station went unnoticed: stored_twice " << o.stored_twice;
}

}  // namespace
}  // namespace hwr::mapio
