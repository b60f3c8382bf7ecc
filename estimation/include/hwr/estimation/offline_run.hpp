#pragma once
// Runs the pose estimator over a whole replay log on the calling thread, without the scheduler:
// samples are fed in time order exactly as hwr-robot's tasks would (IMU queued, frames tracked
// at their time, the sliding-window bundle adjustment after each keyframe, the full one at the
// end). Tests and benches use it; timings come from the estimator's own per-stage clocks.

#include <cstddef>
#include <functional>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/estimation/pose_estimator.hpp"
#include "hwr/hal/replay_source.hpp"

namespace hwr::estimation {

struct OfflineRunOptions {
  PoseEstimatorConfig estimator;
  size_t max_frames = 0;  // 0: every frame
  // Called after every frame with the estimator (e.g. to count allocations per frame).
  std::function<void(size_t frame_index, const PoseEstimator&)> after_frame;
  // Called once with the new estimator before the first frame (e.g. to set instrumentation hooks).
  std::function<void(PoseEstimator&)> on_start;
  // Called around process_frame only (allocation counting of the tracking path).
  std::function<void(size_t frame_index, bool before)> around_track;
  // Called once after the end-of-run full bundle adjustment, with the final keyframes (e.g. to
  // flush the local mapper).
  std::function<void(const PoseEstimator&)> at_end;
};

struct OfflineRun {
  std::vector<core::StampedPose> trajectory;  // T_world_cam at image times (after full BA)
  std::vector<core::StampedPose> trajectory_before_full_ba;
  std::vector<FrameTiming> timings;
  PoseEstimatorCounters counters;
  LocalBaReport full_ba;
  double full_ba_s = 0;
  size_t frames = 0;
  size_t frame_errors = 0;
};

core::Expected<OfflineRun> run_offline(const hal::ReplayLog& log, const OfflineRunOptions& options);

}  // namespace hwr::estimation
