#pragma once
// The pose-estimation pipeline of the robot (paper sections II-A and II-B): IMU samples drive the
// multiplicative EKF at IMU rate (after a static initialisation), camera frames are tracked by the
// visual front end from the IMU's predicted pose, each tracked pose updates the filter, keyframes
// feed a sliding-window bundle adjustment, and a full bundle adjustment refines every keyframe at
// the end of a run. Without a gyro (TUM RGB-D) it runs visual-only with a constant-velocity model.
//
// The scheduler calls it from three tasks on one thread: add_imu/advance_imu from the inertial
// task, process_frame from the camera task, run_local_ba from the mapping task. Frames are
// processed at their exact timestamp: the filter is propagated up to the frame time, splitting
// the IMU interval that straddles it (zero-order hold), so the visual update and the prediction
// refer to the same instant. Everything is allocated in the constructor.

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/estimation/imu_mekf.hpp"
#include "hwr/estimation/local_bundle_adjustment.hpp"
#include "hwr/estimation/pose_history.hpp"
#include "hwr/estimation/static_init.hpp"
#include "hwr/estimation/visual_tracker.hpp"
#include "hwr/hal/imu_sample.hpp"
#include "hwr/hal/mag_sample.hpp"
#include "hwr/hal/rgbd_frame.hpp"
#include "hwr/hal/sensor_source.hpp"

namespace hwr::estimation {

struct PoseEstimatorConfig {
  // Depth noise of the camera, sigma = c * z^2 (m), used by the motion-only refinement and the
  // bundle adjustment (it overrides theirs). 0.0015 is the simulator's quadratic term; on TUM
  // fr3/teddy (Kinect) it also gives the best ATE: 0.004 made teddy's ATE 5x worse (hwr-bench frame).
  double depth_sigma_per_m2 = 0.0015;
  TrackerConfig tracker;
  LocalBaConfig local_ba;
  bool local_ba_enabled = true;
  bool full_ba_at_end = true;
  bool use_imu = true;  // when the source has one
  ImuNoise imu_noise;
  StaticInitConfig static_init;
  int pose_history_capacity = 1600;  // IMU-rate states kept for interpolation (8 s at 200 Hz)
  int imu_queue_capacity = 2048;     // samples waiting for their frame
  int max_frames = 216'000;          // trajectory records (2 h at 30 Hz)
  // Visual pose updates: the refiner's covariance, inflated by this factor (the map's own error
  // is not in it) and floored.
  double visual_cov_inflation = 4.0;
  // The floors stand for the map's own slowly varying error (time-correlated, so a filter that
  // took each pose as independent would grow overconfident and start rejecting them).
  double visual_min_sigma_m = 0.01;
  double visual_min_sigma_rad = 0.003;
  // This many consecutive visual updates refused by the gate restart the filter at the camera pose.
  int gated_updates_before_reset = 10;
  // With an IMU, frames wait for the static initialisation this long at most, then the run goes
  // on visual-only with the world frame at the first camera pose.
  double static_init_timeout_s = 10.0;
};

// One row of --timing-out: the camera task's stages for one frame, plus the mapping task's local
// bundle adjustment that ran after it (0 when none).
struct FrameTiming {
  int64_t t_ns = 0;
  int64_t imu_ns = 0;  // propagation to the frame time and the filter update
  TrackTimings track;
  int64_t total_ns = 0;  // the whole process_frame
  int64_t local_ba_ns = 0;
  int32_t features = 0, matches = 0, inliers = 0;
  TrackState state = TrackState::kWaiting;
  bool keyframe = false;
};

struct PoseEstimatorCounters {
  TrackerCounters tracker;
  ImuMekf::Counters mekf{};
  uint64_t imu_samples = 0;
  uint64_t imu_queue_overflows = 0;
  uint64_t frames_waiting_for_init = 0;
  uint64_t frames_out_of_order = 0;
  uint64_t frames_late_for_filter = 0;  // the filter was already past the frame: no update
  uint64_t frames_ahead_of_imu = 0;     // no IMU sample after the frame yet: no update
  uint64_t visual_updates_gated = 0;
  uint64_t filter_resets = 0;
  uint64_t local_ba_runs = 0;
  uint64_t local_ba_failures = 0;
  bool imu_initialized = false;
  bool visual_only = false;
};

class PoseEstimator {
 public:
  PoseEstimator(const PoseEstimatorConfig& config, const hal::SourceInfo& source);

  void add_imu(const hal::ImuSample& sample);  // queued; see advance_imu
  void add_mag(const hal::MagSample& sample);
  // Propagates the queued IMU samples stamped at or before until_ns (the inertial task calls it with
  // a hold-back, so a late frame still finds the samples around its time queued).
  void advance_imu(int64_t until_ns);
  const TrackResult& process_frame(const hal::RgbdFrame& frame);
  bool local_ba_due() const { return local_ba_due_; }
  core::Expected<LocalBaReport> run_local_ba();
  // End of run: the full bundle adjustment over every keyframe in the ring (when enabled).
  core::Expected<LocalBaReport> finish();

  // Camera poses at every tracked frame's time, expressed through their reference keyframe, so
  // bundle adjustment refines them too.
  std::vector<core::StampedPose> trajectory() const;
  const std::vector<FrameTiming>& timings() const { return timings_; }
  PoseEstimatorCounters counters() const;
  const VisualTracker& tracker() const { return tracker_; }
  VisualTracker& tracker() { return tracker_; }
  bool imu_initialized() const { return mekf_.initialized(); }
  const ImuMekf& mekf() const { return mekf_; }

 private:
  struct FrameRecord {
    int64_t t_ns;
    int32_t reference_keyframe;
    Eigen::Quaterniond q_kf_cam;
    Eigen::Vector3d p_kf_cam_m;
  };
  void consume_imu(const hal::ImuSample& s);
  bool imu_front(hal::ImuSample* s) const;
  void imu_pop();
  void update_filter(const TrackResult& r);

  PoseEstimatorConfig config_;
  hal::SourceInfo source_;
  bool use_imu_ = false;
  VisualTracker tracker_;
  LocalBundleAdjustment local_ba_;
  ImuMekf mekf_;
  StaticInitializer static_init_;
  PoseHistory history_;
  std::vector<hal::ImuSample> imu_queue_;  // circular
  size_t imu_head_ = 0, imu_count_ = 0;
  int64_t last_imu_t_ns_ = INT64_MIN;
  int64_t first_frame_t_ns_ = INT64_MIN;
  int64_t last_frame_t_ns_ = INT64_MIN;
  bool visual_only_ = false;
  bool local_ba_due_ = false;
  int gated_streak_ = 0;
  bool have_last_visual_ = false;
  int64_t last_visual_t_ns_ = 0;
  Eigen::Vector3d last_visual_p_world_imu_m_ = Eigen::Vector3d::Zero();
  TrackResult last_;
  std::vector<FrameRecord> records_;
  std::vector<FrameTiming> timings_;
  PoseEstimatorCounters counters_;
};

}  // namespace hwr::estimation
