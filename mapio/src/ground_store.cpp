#include "hwr/mapio/ground_store.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>

#include "durable_file.hpp"
#include "hwr/core/file_io.hpp"
#include "hwr/mapio/chunk_wire.hpp"

namespace hwr::mapio {
namespace fs = std::filesystem;
using detail::is_dir;
using detail::is_file;
using detail::list_dir;
using detail::make_dir;

namespace {

constexpr char kLockName[] = ".ground_store.lock";
// What the operator console (operator_console.hpp) keeps beside the runs: not the store's, not noted.
constexpr char kOperatorLockName[] = ".operator_console.lock";
constexpr char kOperatorDirName[] = "operator";
// What the viewer's telemetry (ground_telemetry.hpp) keeps beside the runs.
constexpr char kTelemetryDirName[] = "telemetry";
constexpr char kTmpSuffix[] = ".tmp";  // core::write_file_atomic's temp name is PATH + ".tmp"
constexpr char kCorruptSuffix[] = ".corrupt";
constexpr size_t kMaxRobotIdChars = 64;

std::string pad6(int32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "%06d", v);
  return buf;
}

std::string segment_dir_name(int32_t segment_id, int32_t version) {
  return "seg_" + pad6(segment_id) + "_v" + std::to_string(version);
}

std::string chunk_stem(int32_t chunk_index) { return "chunk_" + pad6(chunk_index); }

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Non-negative decimal digits without sign; false on overflow past `max`.
bool parse_digits(const std::string& s, int64_t max, int64_t* out) {
  if (s.empty() || s.size() > 19) return false;
  int64_t v = 0;
  for (const char c : s) {
    if (c < '0' || c > '9') return false;
    const int64_t d = c - '0';
    if (v > (max - d) / 10) return false;
    v = v * 10 + d;
  }
  *out = v;
  return true;
}

// A run folder's name is the canonical decimal run_id (no leading zeros).
bool parse_run_dir(const std::string& name, int64_t* run_id) {
  return parse_digits(name, INT64_MAX, run_id) && name == std::to_string(*run_id);
}

bool parse_segment_dir(const std::string& name, int32_t* segment_id, int32_t* version) {
  const size_t v = name.find("_v");
  if (name.rfind("seg_", 0) != 0 || v == std::string::npos) return false;
  int64_t id = 0, ver = 0;
  if (!parse_digits(name.substr(4, v - 4), INT32_MAX, &id) ||
      !parse_digits(name.substr(v + 2), INT32_MAX, &ver)) {
    return false;
  }
  *segment_id = static_cast<int32_t>(id);
  *version = static_cast<int32_t>(ver);
  return name == segment_dir_name(*segment_id, *version);
}

// "chunk_000012" + suffix -> 12.
bool parse_chunk_file(const std::string& name, const std::string& suffix, int32_t* chunk_index) {
  if (name.rfind("chunk_", 0) != 0 || !ends_with(name, suffix)) return false;
  int64_t idx = 0;
  if (!parse_digits(name.substr(6, name.size() - 6 - suffix.size()), INT32_MAX, &idx)) return false;
  *chunk_index = static_cast<int32_t>(idx);
  return name == chunk_stem(*chunk_index) + suffix;
}

// --- the LCM message on disk -----------------------------------------------------------------------

// What a stored message may hold: the store's own size cap, nothing tighter (the link applied its
// limits before put()).
ChunkWireLimits stored_limits() {
  ChunkWireLimits limits;
  limits.max_message_bytes = static_cast<size_t>(GroundStore::kMaxStoredMessageBytes);
  limits.max_payload_bytes = static_cast<size_t>(GroundStore::kMaxStoredMessageBytes);
  limits.max_points = INT32_MAX;
  return limits;
}

// Checks a message's fields before they become paths or index entries (put() and open() alike).
core::Status validate_chunk(const hwr_lcm::map_chunk_t& c) {
  HWR_RETURN_IF_ERROR(GroundStore::validate_robot_id(c.robot_id));
  const std::string what = "chunk " + c.robot_id + "/" + std::to_string(c.run_id) + " link_seq " +
                           std::to_string(c.link_seq) + ": ";
  if (c.run_id < 0 || c.link_seq < 0 || c.segment_id < 0 || c.segment_version < 0 || c.chunk_index < 0 ||
      c.chunk_count < 0 || c.num_points < 0) {
    return core::InvalidArgument(what +
                                 "run_id, link_seq, segment_id, segment_version, chunk_index, chunk_count "
                                 "and num_points must be >= 0");
  }
  if (c.payload_size < 0 || static_cast<size_t>(c.payload_size) != c.payload.size()) {
    return core::InvalidArgument(what + "payload_size " + std::to_string(c.payload_size) + " but " +
                                 std::to_string(c.payload.size()) + " payload bytes");
  }
  if (c.segment_complete != 0 && c.chunk_index >= c.chunk_count) {
    return core::InvalidArgument(what + "segment_complete with chunk_index " + std::to_string(c.chunk_index) +
                                 " >= chunk_count " + std::to_string(c.chunk_count));
  }
  return core::Status::Ok();
}

// Reads and decodes one stored .lcm. kCorruptData (what open() quarantines) for an oversized,
// undecodable or invalid message; kNotFound / kIoError from the file system as they are.
core::Status read_stored_chunk(const std::string& path, hwr_lcm::map_chunk_t* out) {
  std::error_code ec;
  const uintmax_t size = fs::file_size(path, ec);
  if (ec) {
    if (ec == std::errc::no_such_file_or_directory) return core::NotFound(path + ": file not found");
    return core::IoError(path + ": cannot stat: " + ec.message());
  }
  if (size > static_cast<uintmax_t>(GroundStore::kMaxStoredMessageBytes)) {
    return core::CorruptData(path + ": " + std::to_string(size) + " bytes, over the " +
                             std::to_string(GroundStore::kMaxStoredMessageBytes >> 20) +
                             " MiB limit of a stored chunk message");
  }
  std::string bytes;
  HWR_RETURN_IF_ERROR(core::read_file(path, &bytes));
  // chunk_wire's decoder bounds every length field before LCM allocates for it.
  const core::Status decoded = decode_chunk_message(reinterpret_cast<const uint8_t*>(bytes.data()),
                                                    bytes.size(), out, stored_limits());
  if (!decoded.ok()) return core::CorruptData(path + ": " + decoded.message());
  if (chunk_crc32(*out) != static_cast<uint64_t>(out->crc32)) {
    return core::CorruptData(path + ": CRC32 mismatch (the stored bytes changed)");
  }
  const core::Status valid = validate_chunk(*out);
  if (!valid.ok()) return core::CorruptData(path + ": " + valid.message());
  return core::Status::Ok();
}

}  // namespace

// --- the index -------------------------------------------------------------------------------------

struct ChunkRecord {
  int32_t segment_id = 0, version = 0, chunk_index = 0, chunk_count = 0;
  bool complete = false;
  int32_t num_points = 0, payload_size = 0;
  int64_t crc32 = 0;
  double T_world_segment[12] = {};
};

struct RunIndex {
  std::map<int64_t, ChunkRecord> by_link_seq;
  // (segment_id, version) -> chunk_index -> link_seq
  std::map<std::pair<int32_t, int32_t>, std::map<int32_t, int64_t>> segments;
};

struct GroundStore::State {
  std::string out_dir;
  int lock_fd = -1;
  OpenReport report;
  std::map<std::pair<std::string, int64_t>, RunIndex> runs;
  int64_t chunks = 0;

  ~State() {
    if (lock_fd >= 0) ::close(lock_fd);
  }

  std::string run_dir(const std::string& robot_id, int64_t run_id) const {
    return out_dir + "/" + robot_id + "/" + std::to_string(run_id);
  }
  std::string segment_dir(const std::string& robot_id, int64_t run_id, int32_t segment_id,
                          int32_t version) const {
    return run_dir(robot_id, run_id) + "/" + segment_dir_name(segment_id, version);
  }

  const RunIndex* find_run(const std::string& robot_id, int64_t run_id) const {
    const auto it = runs.find({robot_id, run_id});
    return it == runs.end() ? nullptr : &it->second;
  }

  // Why `c` cannot join the index, or OK (also OK for the very chunk already there: *duplicate).
  core::Status check_conflict(const hwr_lcm::map_chunk_t& c, bool* duplicate) const {
    *duplicate = false;
    const RunIndex* run = find_run(c.robot_id, c.run_id);
    if (run == nullptr) return core::Status::Ok();
    const std::string what = "chunk " + c.robot_id + "/" + std::to_string(c.run_id) + " link_seq " +
                             std::to_string(c.link_seq) + " (segment " + std::to_string(c.segment_id) + " v" +
                             std::to_string(c.segment_version) + " chunk " + std::to_string(c.chunk_index) +
                             ")";
    const auto it = run->by_link_seq.find(c.link_seq);
    if (it != run->by_link_seq.end()) {
      const ChunkRecord& r = it->second;
      if (r.segment_id == c.segment_id && r.version == c.segment_version && r.chunk_index == c.chunk_index &&
          r.crc32 == c.crc32 && r.payload_size == c.payload_size) {
        *duplicate = true;
        return core::Status::Ok();
      }
      return core::InvalidArgument(what + " conflicts with the stored link_seq " +
                                   std::to_string(c.link_seq) + " (segment " + std::to_string(r.segment_id) +
                                   " v" + std::to_string(r.version) + " chunk " +
                                   std::to_string(r.chunk_index) + ", crc32 " + std::to_string(r.crc32) +
                                   " vs " + std::to_string(c.crc32) + ")");
    }
    const auto seg = run->segments.find({c.segment_id, c.segment_version});
    if (seg != run->segments.end()) {
      const auto at = seg->second.find(c.chunk_index);
      if (at != seg->second.end()) {
        return core::InvalidArgument(what + ": that place already holds link_seq " +
                                     std::to_string(at->second));
      }
    }
    return core::Status::Ok();
  }

  void index(const hwr_lcm::map_chunk_t& c) {
    ChunkRecord r;
    r.segment_id = c.segment_id;
    r.version = c.segment_version;
    r.chunk_index = c.chunk_index;
    r.chunk_count = c.chunk_count;
    r.complete = c.segment_complete != 0;
    r.num_points = c.num_points;
    r.payload_size = c.payload_size;
    r.crc32 = c.crc32;
    std::copy(c.T_world_segment, c.T_world_segment + 12, r.T_world_segment);
    RunIndex& run = runs[{c.robot_id, c.run_id}];
    run.by_link_seq[c.link_seq] = r;
    run.segments[{c.segment_id, c.segment_version}][c.chunk_index] = c.link_seq;
    ++chunks;
  }

  core::Status scan();
  core::Status scan_segment(const std::string& robot_id, int64_t run_id, int32_t segment_id, int32_t version,
                            const std::string& dir);
  void note(std::string line) { report.notes.push_back(std::move(line)); }
};

core::Status GroundStore::State::scan() {
  std::vector<fs::directory_entry> robots;
  HWR_RETURN_IF_ERROR(list_dir(out_dir, &robots));
  for (const auto& robot : robots) {
    const std::string robot_id = robot.path().filename().string();
    if (robot_id == kLockName || robot_id == kOperatorLockName) continue;
    if (!is_dir(robot) || !validate_robot_id(robot_id).ok()) {
      note(robot.path().string() + ": not a robot folder, ignored");
      continue;
    }
    std::vector<fs::directory_entry> run_dirs;
    HWR_RETURN_IF_ERROR(list_dir(robot.path().string(), &run_dirs));
    for (const auto& run : run_dirs) {
      if ((run.path().filename() == kOperatorDirName || run.path().filename() == kTelemetryDirName) &&
          is_dir(run))
        continue;
      int64_t run_id = 0;
      if (!is_dir(run) || !parse_run_dir(run.path().filename().string(), &run_id)) {
        note(run.path().string() + ": not a run folder, ignored");
        continue;
      }
      std::vector<fs::directory_entry> segment_dirs;
      HWR_RETURN_IF_ERROR(list_dir(run.path().string(), &segment_dirs));
      for (const auto& seg : segment_dirs) {
        int32_t segment_id = 0, version = 0;
        if (!is_dir(seg) || !parse_segment_dir(seg.path().filename().string(), &segment_id, &version)) {
          note(seg.path().string() + ": not a segment folder, ignored");
          continue;
        }
        HWR_RETURN_IF_ERROR(scan_segment(robot_id, run_id, segment_id, version, seg.path().string()));
      }
    }
  }
  report.chunks_loaded = chunks;
  return core::Status::Ok();
}

core::Status GroundStore::State::scan_segment(const std::string& robot_id, int64_t run_id, int32_t segment_id,
                                              int32_t version, const std::string& dir) {
  std::vector<fs::directory_entry> entries;
  HWR_RETURN_IF_ERROR(list_dir(dir, &entries));
  std::map<int32_t, std::string> lcm_files, drc_files;
  bool changed = false;
  for (const auto& e : entries) {
    const std::string name = e.path().filename().string();
    const std::string path = e.path().string();
    int32_t idx = 0;
    if (is_file(e) && ends_with(name, kTmpSuffix)) {
      if (std::remove(path.c_str()) != 0)
        return core::IoError(path + ": cannot remove: " + std::strerror(errno));
      ++report.temp_files_removed;
      note(path + ": temp file of an interrupted write, removed");
      changed = true;
    } else if (is_file(e) && parse_chunk_file(name, ".lcm", &idx)) {
      lcm_files[idx] = path;
    } else if (is_file(e) && parse_chunk_file(name, ".drc", &idx)) {
      drc_files[idx] = path;
    } else if (!(is_file(e) && ends_with(name, std::string(".lcm") + kCorruptSuffix))) {
      note(path + ": not a chunk file, ignored");
    }
  }

  for (const auto& [idx, path] : lcm_files) {
    hwr_lcm::map_chunk_t c;
    core::Status st = read_stored_chunk(path, &c);
    if (st.code() != core::ErrorCode::kOk && st.code() != core::ErrorCode::kCorruptData) return st;
    bool duplicate = false;
    if (st.ok() && (c.robot_id != robot_id || c.run_id != run_id || c.segment_id != segment_id ||
                    c.segment_version != version || c.chunk_index != idx)) {
      st = core::CorruptData(path + ": the message names " + c.robot_id + "/" + std::to_string(c.run_id) +
                             " segment " + std::to_string(c.segment_id) + " v" +
                             std::to_string(c.segment_version) + " chunk " + std::to_string(c.chunk_index) +
                             ", not its path");
    }
    if (st.ok()) {
      st = check_conflict(c, &duplicate);
      if (!st.ok() || duplicate)
        st = core::CorruptData(path + ": link_seq " + std::to_string(c.link_seq) +
                               " is already stored elsewhere in this run");
    }
    if (!st.ok()) {
      const std::string quarantine = path + kCorruptSuffix;
      if (std::rename(path.c_str(), quarantine.c_str()) != 0) {
        return core::IoError(path + ": cannot rename to " + quarantine + ": " + std::strerror(errno));
      }
      ++report.corrupt_quarantined;
      note(st.message() + "; renamed to " + quarantine + ", not counted as stored");
      changed = true;
      continue;  // its .drc, if any, is removed below as a lone payload
    }
    // The .drc was written before the .lcm, so it is there unless someone removed or altered it.
    const std::string drc = dir + "/" + chunk_stem(idx) + ".drc";
    std::string payload;
    const bool drc_ok = drc_files.count(idx) != 0 && core::read_file(drc, &payload).ok() &&
                        payload.size() == c.payload.size() &&
                        std::equal(payload.begin(), payload.end(), c.payload.begin(),
                                   [](char a, uint8_t b) { return static_cast<uint8_t>(a) == b; });
    if (!drc_ok) {
      HWR_RETURN_IF_ERROR(core::write_file_atomic(drc, c.payload));
      ++report.payloads_rewritten;
      note(drc + ": missing or different from the payload in " + path + ", rewritten");
      changed = true;
    }
    drc_files.erase(idx);
    index(c);
  }

  for (const auto& [idx, path] : drc_files) {
    if (std::remove(path.c_str()) != 0)
      return core::IoError(path + ": cannot remove: " + std::strerror(errno));
    ++report.lone_payloads_removed;
    note(path + ": payload without its .lcm (interrupted or corrupt chunk), removed");
    changed = true;
  }
  if (changed) return core::fsync_directory(dir);
  return core::Status::Ok();
}

// --- GroundStore -----------------------------------------------------------------------------------

GroundStore::GroundStore(std::unique_ptr<State> state) : state_(std::move(state)) {}
GroundStore::GroundStore(GroundStore&&) noexcept = default;
GroundStore& GroundStore::operator=(GroundStore&&) noexcept = default;
GroundStore::~GroundStore() = default;

core::Status GroundStore::validate_robot_id(const std::string& robot_id) {
  const bool ok = !robot_id.empty() && robot_id.size() <= kMaxRobotIdChars &&
                  std::all_of(robot_id.begin(), robot_id.end(), [](char c) {
                    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                           c == '_' || c == '-';
                  });
  if (ok) return core::Status::Ok();
  std::string shown = robot_id.substr(0, kMaxRobotIdChars + 8);
  for (char& c : shown) {
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7e) c = '?';
  }
  return core::InvalidArgument("robot_id '" + shown + "' (" + std::to_string(robot_id.size()) +
                               " chars) must match [A-Za-z0-9_-]{1,64}: it names a folder of the store");
}

core::Expected<GroundStore> GroundStore::open(const std::string& out_dir) {
  if (out_dir.empty()) return core::InvalidArgument("ground store: empty output folder");
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec) return core::IoError(out_dir + ": cannot create folder: " + ec.message());
  if (!fs::is_directory(out_dir, ec)) return core::IoError(out_dir + ": not a folder");

  auto state = std::make_unique<State>();
  state->out_dir = out_dir;
  while (state->out_dir.size() > 1 && state->out_dir.back() == '/') state->out_dir.pop_back();
  const std::string lock_path = state->out_dir + "/" + kLockName;
  state->lock_fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (state->lock_fd < 0)
    return core::IoError(lock_path + ": cannot open lock file: " + std::strerror(errno));
  if (::flock(state->lock_fd, LOCK_EX | LOCK_NB) != 0) {
    if (errno == EWOULDBLOCK) {
      return core::Unavailable(out_dir +
                               ": another ground store (hwr-ground) has this folder open; stop it or "
                               "use another output folder");
    }
    return core::IoError(lock_path + ": flock failed: " + std::strerror(errno));
  }
  HWR_RETURN_IF_ERROR(state->scan());
  return GroundStore(std::move(state));
}

core::Status GroundStore::put(const hwr_lcm::map_chunk_t& chunk, bool* was_new) {
  if (was_new != nullptr) *was_new = false;
  HWR_RETURN_IF_ERROR(validate_chunk(chunk));
  const int64_t encoded_size = chunk.getEncodedSize();
  if (encoded_size > kMaxStoredMessageBytes) {
    return core::InvalidArgument(
        "chunk " + chunk.robot_id + "/" + std::to_string(chunk.run_id) + " link_seq " +
        std::to_string(chunk.link_seq) + ": " + std::to_string(encoded_size) + " bytes encoded, over the " +
        std::to_string(kMaxStoredMessageBytes >> 20) + " MiB limit of a stored chunk message");
  }
  if (chunk_crc32(chunk) != static_cast<uint64_t>(chunk.crc32)) {
    return core::CorruptData("chunk " + chunk.robot_id + "/" + std::to_string(chunk.run_id) + " link_seq " +
                             std::to_string(chunk.link_seq) +
                             ": CRC32 mismatch; verify_chunk() before put()");
  }
  bool duplicate = false;
  HWR_RETURN_IF_ERROR(state_->check_conflict(chunk, &duplicate));
  if (duplicate) return core::Status::Ok();

  std::vector<uint8_t> encoded;
  HWR_RETURN_IF_ERROR(encode_chunk_message(chunk, &encoded));

  const std::string robot_dir = state_->out_dir + "/" + chunk.robot_id;
  const std::string run_dir = state_->run_dir(chunk.robot_id, chunk.run_id);
  const std::string seg_dir =
      state_->segment_dir(chunk.robot_id, chunk.run_id, chunk.segment_id, chunk.segment_version);
  HWR_RETURN_IF_ERROR(make_dir(state_->out_dir, robot_dir));
  HWR_RETURN_IF_ERROR(make_dir(robot_dir, run_dir));
  HWR_RETURN_IF_ERROR(make_dir(run_dir, seg_dir));

  // The payload first, then the .lcm that makes the chunk count: a process killed in between leaves
  // a lone .drc, which open() removes. One folder fsync covers both renames; should a power loss
  // keep the .lcm's rename and lose the .drc's, open() rewrites the .drc from the .lcm (which holds
  // the payload), so the .lcm alone is the durable record.
  const std::string stem = seg_dir + "/" + chunk_stem(chunk.chunk_index);
  HWR_RETURN_IF_ERROR(core::write_file_atomic(stem + ".drc", chunk.payload));
  HWR_RETURN_IF_ERROR(core::write_file_atomic(stem + ".lcm", encoded));
  HWR_RETURN_IF_ERROR(core::fsync_directory(seg_dir));
  state_->index(chunk);
  if (was_new != nullptr) *was_new = true;
  return core::Status::Ok();
}

bool GroundStore::has(const std::string& robot_id, int64_t run_id, int64_t link_seq) const {
  const RunIndex* run = state_->find_run(robot_id, run_id);
  return run != nullptr && run->by_link_seq.count(link_seq) != 0;
}

std::vector<int64_t> GroundStore::stored_link_seqs(const std::string& robot_id, int64_t run_id) const {
  std::vector<int64_t> out;
  const RunIndex* run = state_->find_run(robot_id, run_id);
  if (run == nullptr) return out;
  out.reserve(run->by_link_seq.size());
  for (const auto& entry : run->by_link_seq) out.push_back(entry.first);
  return out;
}

std::vector<std::pair<std::string, int64_t>> GroundStore::runs() const {
  std::vector<std::pair<std::string, int64_t>> out;
  for (const auto& entry : state_->runs) out.push_back(entry.first);
  return out;
}

std::vector<GroundStore::SegmentInfo> GroundStore::segments(const std::string& robot_id,
                                                            int64_t run_id) const {
  std::vector<SegmentInfo> out;
  const RunIndex* run = state_->find_run(robot_id, run_id);
  if (run == nullptr) return out;
  for (const auto& [key, chunks] : run->segments) {
    SegmentInfo info;
    info.segment_id = key.first;
    info.version = key.second;
    info.chunks_stored = static_cast<int32_t>(chunks.size());
    int32_t final_count = -1;
    for (const auto& [idx, link_seq] : chunks) {
      const ChunkRecord& r = run->by_link_seq.at(link_seq);
      info.chunk_count = std::max(info.chunk_count, r.chunk_count);
      if (r.complete) final_count = r.chunk_count;
      info.points_stored += r.num_points;
      info.payload_bytes_stored += r.payload_size;
      // Chunks iterate by ascending index: the last one holds the latest pose.
      std::copy(r.T_world_segment, r.T_world_segment + 12, info.T_world_segment);
    }
    if (final_count >= 0) info.chunk_count = final_count;
    // Indexes are distinct and >= 0, so count == final_count with the largest index final_count - 1
    // means exactly 0 .. final_count - 1.
    info.complete =
        final_count >= 0 && info.chunks_stored == final_count && chunks.rbegin()->first == final_count - 1;
    out.push_back(info);
  }
  return out;
}

int64_t GroundStore::chunks_stored() const { return state_->chunks; }

core::Status GroundStore::load_segment(const std::string& robot_id, int64_t run_id, int32_t segment_id,
                                       int32_t version, std::vector<hwr_lcm::map_chunk_t>* out) const {
  out->clear();
  const RunIndex* run = state_->find_run(robot_id, run_id);
  const std::map<int32_t, int64_t>* chunks = nullptr;
  if (run != nullptr) {
    const auto seg = run->segments.find({segment_id, version});
    if (seg != run->segments.end()) chunks = &seg->second;
  }
  if (chunks == nullptr) {
    return core::NotFound(robot_id + "/" + std::to_string(run_id) + " segment " + std::to_string(segment_id) +
                          " v" + std::to_string(version) + ": nothing stored");
  }
  out->reserve(chunks->size());
  for (const auto& [idx, link_seq] : *chunks) {
    const std::string path = lcm_path(robot_id, run_id, segment_id, version, idx);
    hwr_lcm::map_chunk_t c;
    const core::Status st = read_stored_chunk(path, &c);
    if (!st.ok()) return core::CorruptData("stored chunk changed on disk: " + st.message());
    if (c.link_seq != link_seq || c.robot_id != robot_id || c.run_id != run_id ||
        c.segment_id != segment_id || c.segment_version != version || c.chunk_index != idx) {
      return core::CorruptData(path + ": changed on disk (its fields no longer match what was stored)");
    }
    out->push_back(std::move(c));
  }
  return core::Status::Ok();
}

std::string GroundStore::lcm_path(const std::string& robot_id, int64_t run_id, int32_t segment_id,
                                  int32_t version, int32_t chunk_index) const {
  return state_->segment_dir(robot_id, run_id, segment_id, version) + "/" + chunk_stem(chunk_index) + ".lcm";
}

std::string GroundStore::drc_path(const std::string& robot_id, int64_t run_id, int32_t segment_id,
                                  int32_t version, int32_t chunk_index) const {
  return state_->segment_dir(robot_id, run_id, segment_id, version) + "/" + chunk_stem(chunk_index) + ".drc";
}

const std::string& GroundStore::out_dir() const { return state_->out_dir; }
const GroundStore::OpenReport& GroundStore::open_report() const { return state_->report; }

}  // namespace hwr::mapio
