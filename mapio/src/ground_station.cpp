#include "hwr/mapio/ground_station.hpp"

#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include "hwr/core/log.hpp"
#include "hwr/mapio/cloud_writers.hpp"
#include "hwr/mapio/world_cloud.hpp"

namespace hwr::mapio {
namespace {

core::Status make_dir(const std::string& path) {
  if (::mkdir(path.c_str(), 0755) != 0 && errno != EEXIST)
    return core::IoError("cannot create " + path + ": " + std::strerror(errno));
  return core::Status::Ok();
}

}  // namespace

GroundStation::GroundStation(const GroundStationConfig& config, GroundStore store)
    : config_(config), store_(std::move(store)) {}

core::Expected<std::unique_ptr<GroundStation>> GroundStation::open(const GroundStationConfig& config) {
  if (config.out_dir.empty()) return core::InvalidArgument("ground station: no output folder");
  auto store = GroundStore::open(config.out_dir);
  if (!store.ok()) return store.status();
  for (const std::string& note : store->open_report().notes)
    HWR_LOG_WARN("ground", "store: %s", note.c_str());
  std::unique_ptr<GroundStation> g(new GroundStation(config, std::move(store.value())));
  for (const auto& [robot, run_id] : g->store_.runs()) {
    Run& run = g->run_of(robot, run_id);
    const core::Status st = run.tracker->restore(g->store_.stored_link_seqs(robot, run_id));
    if (!st.ok())
      HWR_LOG_WARN("ground", "restoring %s/%lld: %s", robot.c_str(), static_cast<long long>(run_id),
                   st.message().c_str());
    run.resume_due = true;
  }
  return g;
}

GroundStation::Run& GroundStation::run_of(const std::string& robot_id, int64_t run_id) {
  Run& run = runs_[{robot_id, run_id}];
  if (!run.tracker) run.tracker = std::make_unique<AckTracker>(robot_id, run_id);
  return run;
}

void GroundStation::reject(const core::Status& why) {
  ++stats_.rejected;
  stats_.last_error = why.message();
  HWR_LOG_WARN("ground", "chunk rejected: %s", why.message().c_str());
}

void GroundStation::on_chunk_message(const uint8_t* data, size_t size, int64_t now_ns) {
  ++stats_.messages;
  core::Status st = decode_chunk_message(data, size, &chunk_, config_.wire);
  if (st.ok()) st = verify_chunk(chunk_, config_.wire);
  if (st.ok()) st = GroundStore::validate_robot_id(chunk_.robot_id);
  if (!st.ok()) return reject(st);
  Run& run = run_of(chunk_.robot_id, chunk_.run_id);
  switch (run.tracker->classify(chunk_.link_seq)) {
    case AckTracker::SeqClass::kStored:
      ++stats_.duplicates;
      run.ack_due = true;  // the robot resent it: our ack was lost
      return;
    case AckTracker::SeqClass::kBeyondWindow:
      ++stats_.refused_window;
      return;
    case AckTracker::SeqClass::kInvalid:
      return reject(core::InvalidArgument("negative link_seq"));
    case AckTracker::SeqClass::kNew:
      break;
  }
  // The payload must decode to what the header says before the chunk is stored and acknowledged.
  if (chunk_.num_points > 0) {
    st = decode_chunk(chunk_.payload.data(), chunk_.payload.size(), chunk_.num_points, config_.decode,
                      &decoded_);
    if (!st.ok()) return reject(st);
  }
  bool was_new = false;
  st = store_.put(chunk_, &was_new);
  if (!st.ok()) {
    ++stats_.store_errors;
    stats_.last_error = st.message();
    HWR_LOG_ERROR("ground", "cannot store a chunk (not acknowledged; the robot will resend): %s",
                  st.message().c_str());
    return;
  }
  run.tracker->record(chunk_.link_seq);
  run.ack_due = true;
  if (was_new) {
    ++stats_.chunks_stored;
    stats_.bytes_stored += static_cast<int64_t>(chunk_.payload.size());
    stats_.points_stored += chunk_.num_points;
    if (first_chunk_ns_ == 0) first_chunk_ns_ = now_ns;
    stats_.last_chunk_ns = now_ns;
  }
}

core::Status GroundStation::write_maps(bool merged) {
  // A segment that cannot be assembled (its files damaged on disk) is skipped and reported; the
  // others are still written. The first error is returned.
  core::Status first_error = core::Status::Ok();
  auto note = [&](const core::Status& st) {
    if (st.ok()) return true;
    HWR_LOG_ERROR("ground", "map: %s", st.message().c_str());
    if (first_error.ok()) first_error = st;
    return false;
  };
  std::vector<hwr_lcm::map_chunk_t> chunks;
  for (const auto& [robot, run_id] : store_.runs()) {
    const std::string dir = config_.out_dir + "/" + robot + "/" + std::to_string(run_id) + "/maps";
    if (!note(make_dir(dir))) continue;
    WorldCloud all;
    std::map<int32_t, GroundStore::SegmentInfo> latest;  // per segment id: its newest complete version
    for (const GroundStore::SegmentInfo& s : store_.segments(robot, run_id)) {
      if (!s.complete) continue;
      latest[s.segment_id] = s;
      auto key = std::make_tuple(robot, run_id, s.segment_id, s.version);
      auto w = written_.find(key);
      if (w != written_.end() && w->second == s.chunk_count) continue;
      WorldCloud cloud;
      if (!note(store_.load_segment(robot, run_id, s.segment_id, s.version, &chunks))) continue;
      if (!note(assemble_world_cloud(chunks, config_.decode, &decoded_, &cloud))) continue;
      char name[64];
      std::snprintf(name, sizeof(name), "/segment_%06d_v%d", s.segment_id, s.version);
      const size_t n = cloud.xyz.size() / 3;
      if (!note(write_ply(dir + name + ".ply", cloud.xyz.data(), cloud.rgb.data(), nullptr, n))) continue;
      if (config_.write_pcd &&
          !note(write_pcd(dir + name + ".pcd", cloud.xyz.data(), cloud.rgb.data(), nullptr, n)))
        continue;
      written_[key] = s.chunk_count;
      ++stats_.segments_written;
    }
    if (!merged) continue;
    for (const auto& [id, s] : latest) {
      if (!note(store_.load_segment(robot, run_id, s.segment_id, s.version, &chunks))) continue;
      note(assemble_world_cloud(chunks, config_.decode, &decoded_, &all));
    }
    const size_t n = all.xyz.size() / 3;
    note(write_ply(dir + "/merged.ply", all.xyz.data(), all.rgb.data(), nullptr, n));
    if (config_.write_pcd) note(write_pcd(dir + "/merged.pcd", all.xyz.data(), all.rgb.data(), nullptr, n));
  }
  return first_error;
}

std::string GroundStation::status_line(int64_t now_ns) const {
  int complete = 0, seen = 0;
  for (const auto& [robot, run_id] : store_.runs()) {
    for (const GroundStore::SegmentInfo& s : store_.segments(robot, run_id)) {
      ++seen;
      complete += s.complete ? 1 : 0;
    }
  }
  const double span_s = first_chunk_ns_ > 0 ? (now_ns - first_chunk_ns_) * 1e-9 : 0.0;
  char line[256];
  std::snprintf(line, sizeof(line),
                "runs %zu | segments %d/%d complete | chunks %lld (+%lld dup, %lld rejected) | points %lld | "
                "%.2f MB | %.2f MB/s | acks %lld",
                store_.runs().size(), complete, seen, static_cast<long long>(store_.chunks_stored()),
                static_cast<long long>(stats_.duplicates), static_cast<long long>(stats_.rejected),
                static_cast<long long>(stats_.points_stored), stats_.bytes_stored * 1e-6,
                span_s > 0 ? stats_.bytes_stored * 1e-6 / span_s : 0.0,
                static_cast<long long>(stats_.acks_sent));
  return line;
}

}  // namespace hwr::mapio
