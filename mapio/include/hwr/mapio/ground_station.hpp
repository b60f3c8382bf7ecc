#pragma once
// The ground station's receiver (issue #5 item 4), the library behind `hwr-ground`: every received
// HWR_MAP_CHUNK message is decoded with bounded lengths, verified (CRC32, ranges), classified by the
// run's AckTracker (new / duplicate / beyond the window), its Draco payload decoded and checked,
// stored durably (GroundStore), and only then acknowledged. At open it restores every run's tracker
// from the store and owes each run a resume report, so a restarted ground station neither loses nor
// duplicates anything and the robot resumes from there.
//
// Maps: a segment version whose chunks are all stored is assembled in the world frame
// (T_world_segment of its latest chunk; a point id seen twice keeps the later chunk's point) and
// written as OUT/<robot>/<run>/maps/segment_<id>_v<version>.ply and .pcd; write_maps(true) also
// writes merged.ply / merged.pcd of every complete segment's latest version.
//
// Not thread-safe: one thread calls on_chunk_message(), service() and write_maps().

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/mapio/ack_tracker.hpp"
#include "hwr/mapio/chunk_codec.hpp"
#include "hwr/mapio/chunk_wire.hpp"
#include "hwr/mapio/ground_store.hpp"

namespace hwr::mapio {

struct GroundStationConfig {
  std::string out_dir;
  ChunkWireLimits wire;
  ChunkDecodeLimits decode;
  int64_t ack_interval_ns = 20'000'000;  // a run with news is acknowledged at most this often
  bool write_pcd = true;
};

struct GroundStationStats {
  int64_t messages = 0;
  int64_t chunks_stored = 0;   // new chunks stored this session
  int64_t duplicates = 0;      // already stored: acknowledged again, not stored
  int64_t rejected = 0;        // undecodable, failed verification or Draco checks
  int64_t refused_window = 0;  // beyond the ack tracker's window: the robot resends later
  int64_t store_errors = 0;
  int64_t bytes_stored = 0;  // payload bytes
  int64_t points_stored = 0;
  int64_t acks_sent = 0;
  int64_t segments_written = 0;  // per-segment map files written
  int64_t last_chunk_ns = 0;     // now_ns of the last new chunk
  std::string last_error;        // of the last rejection
};

class GroundStation {
 public:
  // Opens (and repairs) the store under config.out_dir; the runs found owe a resume report.
  static core::Expected<std::unique_ptr<GroundStation>> open(const GroundStationConfig& config);

  void on_chunk_message(const uint8_t* data, size_t size, int64_t now_ns);
  // Publishes the acks that are due (resume reports first) through publish(const chunk_ack_t&).
  template <class Publish>
  int service(int64_t now_ns, Publish&& publish) {
    int n = 0;
    for (auto& [key, run] : runs_) {
      if (!run.resume_due && !(run.ack_due && now_ns - run.last_ack_ns >= config_.ack_interval_ns)) continue;
      run.tracker->make_ack(&ack_, run.resume_due);
      ack_.t_ns = now_ns;
      publish(static_cast<const hwr_lcm::chunk_ack_t&>(ack_));
      run.resume_due = run.ack_due = false;
      run.last_ack_ns = now_ns;
      ++n;
    }
    stats_.acks_sent += n;
    return n;
  }
  // Writes the maps of segments completed since the last call (and the merged maps when `merged`).
  // A segment that fails (damaged files) is skipped and logged; the first error is returned.
  core::Status write_maps(bool merged);

  const GroundStationStats& stats() const { return stats_; }
  const GroundStore& store() const { return store_; }
  // One line: runs, segments complete/seen, chunks, points, MB, rate, duplicates, rejected.
  std::string status_line(int64_t now_ns) const;

 private:
  struct Run {
    std::unique_ptr<AckTracker> tracker;
    bool resume_due = false, ack_due = false;
    int64_t last_ack_ns = 0;
  };
  GroundStation(const GroundStationConfig& config, GroundStore store);
  Run& run_of(const std::string& robot_id, int64_t run_id);
  void reject(const core::Status& why);

  GroundStationConfig config_;
  GroundStore store_;
  std::map<std::pair<std::string, int64_t>, Run> runs_;
  std::map<std::tuple<std::string, int64_t, int32_t, int32_t>, int32_t> written_;  // -> chunk count written
  hwr_lcm::map_chunk_t chunk_;
  hwr_lcm::chunk_ack_t ack_;
  DecodedChunk decoded_;
  GroundStationStats stats_;
  int64_t first_chunk_ns_ = 0;
};

}  // namespace hwr::mapio
