#pragma once
// What the ground station keeps of the robots' telemetry for the viewer (issue #9;
// docs/ground_viewer.md): per robot, its latest run's trajectory and current camera pose (HWR_POSE),
// its latest scheduler and link health (HWR_STATUS) and the keyframe images it sent
// (HWR_KEYFRAME_IMAGE). Everything is kept under OUT_DIR/<robot>/telemetry/ as it arrives, so a
// restarted ground station shows what it showed before:
//   trajectory_<run>.txt    one line per pose: t_ns tracking localized T_world_cam (12 values)
//   status.lcm              the latest status_t (replaced atomically)
//   kf_<run>_<t_ns>_<W>x<H>.jpg   keyframe images (W x H: the keyframe's size, box_px coordinates)
// Messages are decoded and validated by telemetry_wire.hpp; a message that fails is counted and
// dropped. A pose older than the newest kept one of its run is ignored (out of order). In memory a
// trajectory keeps at most max_trajectory_poses poses: when full, every other one is dropped (the
// first and the newest kept). A line of trajectory_<run>.txt cut by a crash (no '\n' at its end) is
// skipped when loading, and closed with a word no pose line has before the next pose is appended.
// Not thread-safe (the caller serializes).

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "hwr/core/status.hpp"
#include "hwr/mapio/telemetry_wire.hpp"

namespace hwr::mapio {

struct GroundTelemetryConfig {
  std::string out_dir;
  size_t max_trajectory_poses = 20'000;
  TelemetryWireLimits wire;
};

struct TrajectoryPose {
  int64_t t_ns = 0;
  bool tracking = true, localized = false;
  double T_world_cam[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};  // 3x4 [R | t] row by row, metres
};

struct KeyframeImageInfo {
  int64_t run_id = 0, keyframe_t_ns = 0;
  int32_t width = 0, height = 0;  // the keyframe's size (box_px coordinates)
  std::string path;               // the JPEG file
};

struct RobotTelemetry {
  int64_t run_id = -1;                     // the latest run seen in a pose or status (-1: none yet)
  std::vector<TrajectoryPose> trajectory;  // of run_id, oldest first, thinned (see above)
  std::optional<hwr_lcm::status_t> status;
  int64_t status_received_ns = 0;            // the caller's clock
  std::vector<KeyframeImageInfo> keyframes;  // of run_id, oldest first (all of them: ~100 bytes each)
};

struct GroundTelemetryStats {
  int64_t poses = 0, statuses = 0, keyframe_images = 0;  // taken
  int64_t rejected = 0;                                  // undecodable or invalid (last_error says why)
  int64_t out_of_order = 0;                              // poses older than the newest of their run
  int64_t store_errors = 0;  // a file could not be written (the message is still shown)
  std::string last_error;
};

class GroundTelemetry {
 public:
  // Creates OUT_DIR if needed and loads what an earlier session kept. Damaged lines and files are
  // skipped and noted (open_notes()); kIoError only when OUT_DIR cannot be created or read.
  static core::Expected<std::unique_ptr<GroundTelemetry>> open(const GroundTelemetryConfig& config);
  ~GroundTelemetry();

  void on_pose_message(const uint8_t* data, size_t size);
  void on_status_message(const uint8_t* data, size_t size, int64_t now_ns);
  void on_keyframe_image_message(const uint8_t* data, size_t size);

  std::vector<std::string> robots() const;
  const RobotTelemetry* robot(const std::string& robot_id) const;  // null when nothing came from it
  const GroundTelemetryStats& stats() const { return stats_; }
  const std::vector<std::string>& open_notes() const { return notes_; }

  GroundTelemetry(const GroundTelemetry&) = delete;
  GroundTelemetry& operator=(const GroundTelemetry&) = delete;

 private:
  struct Robot;
  explicit GroundTelemetry(GroundTelemetryConfig config);
  core::Status load();
  Robot& robot_of(const std::string& robot_id);
  void switch_run(Robot& r, int64_t run_id);
  void add_pose(Robot& r, const TrajectoryPose& pose);
  void reject(const core::Status& why);
  std::string dir_of(const std::string& robot_id) const;

  GroundTelemetryConfig config_;
  std::map<std::string, std::unique_ptr<Robot>> robots_;
  GroundTelemetryStats stats_;
  std::vector<std::string> notes_;
  hwr_lcm::pose_t pose_;  // decode buffers, reused
  hwr_lcm::status_t status_;
  hwr_lcm::keyframe_image_t image_;
  std::vector<uint8_t> encoded_;
};

}  // namespace hwr::mapio
