// The pose-estimation pipeline on real RGB-D data: TUM fr3/teddy, 193 frames, visual-only (the
// sequence has no gyro). Oracles: the motion-capture ground truth (ATE, issue #3 acceptance:
// <= 1.0 cm), and the allocation counter (issue #3: no heap allocation per frame in steady state
// on the tracking path; OpenCV's ORB is the one stage that still allocates, measured separately).

#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "hal/hal_test_util.hpp"
#include "hwr/core/alloc_counter.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/estimation/offline_run.hpp"
#include "hwr/estimation/pose_estimator.hpp"
#include "hwr/estimation/trajectory_metrics.hpp"
#include "hwr/hal/replay_source.hpp"

namespace hwr::estimation {
namespace {

using hal::testing::kTeddyDir;

TEST(VisualOdometryTum, GivenTeddyWhenRunThenTheAteIsUnderOneCentimetre) {
  HWR_REQUIRE_DATASET(kTeddyDir);
  auto log = hal::open_dataset_log("tum:" + kTeddyDir);
  ASSERT_TRUE(log.ok()) << log.status().message();
  auto gt = core::read_tum_trajectory(kTeddyDir + "/groundtruth.txt");
  ASSERT_TRUE(gt.ok());
  auto run = run_offline(log.value(), OfflineRunOptions{});
  ASSERT_TRUE(run.ok()) << run.status().message();
  EXPECT_EQ(run->frames, 193u);
  EXPECT_EQ(run->counters.tracker.lost, 0u);
  EXPECT_TRUE(run->counters.visual_only);
  EXPECT_EQ(run->trajectory.size(), 193u);
  auto ate = compute_ate(gt.value(), run->trajectory);
  ASSERT_TRUE(ate.ok());
  EXPECT_GT(ate->pairs, 180u);
  EXPECT_LT(ate->translation_m.rmse, 0.010);
  // The full bundle adjustment ran over every keyframe and did not make things worse.
  EXPECT_GT(run->full_ba.cameras, 10);
  auto before = compute_ate(gt.value(), run->trajectory_before_full_ba);
  ASSERT_TRUE(before.ok());
  EXPECT_LT(ate->translation_m.rmse, before->translation_m.rmse * 1.2);
}

// A map point pool far smaller than the run needs (teddy makes ~20k points): the tracker retires
// the oldest keyframes' points instead of running out, keeps tracking, and the full BA still runs
// over the keyframes that keep points, with the oldest of them fixing the gauge.
TEST(VisualOdometryTum, GivenASmallPointPoolWhenRunThenOldPointsAreRetiredAndTrackingContinues) {
  HWR_REQUIRE_DATASET(kTeddyDir);
  auto log = hal::open_dataset_log("tum:" + kTeddyDir);
  ASSERT_TRUE(log.ok()) << log.status().message();
  auto gt = core::read_tum_trajectory(kTeddyDir + "/groundtruth.txt");
  ASSERT_TRUE(gt.ok());
  OfflineRunOptions options;
  options.estimator.tracker.map_point_capacity = 8000;
  auto run = run_offline(log.value(), options);
  ASSERT_TRUE(run.ok()) << run.status().message();
  EXPECT_EQ(run->counters.tracker.lost, 0u);
  EXPECT_GT(run->counters.tracker.points_retired, 0u);
  EXPECT_GT(run->counters.tracker.keyframes_retired, 0u);
  EXPECT_EQ(run->counters.tracker.point_pool_exhausted, 0u);
  EXPECT_GT(run->full_ba.cameras, 5);
  EXPECT_LT(run->full_ba.cameras, static_cast<int>(run->counters.tracker.keyframes));
  auto ate = compute_ate(gt.value(), run->trajectory);
  ASSERT_TRUE(ate.ok());
  EXPECT_LT(ate->translation_m.rmse, 0.015);
}

// Frames after warm-up that make no keyframe: every stage but the ORB extraction (OpenCV's own
// allocations, counted and reported) allocates nothing.
TEST(VisualOdometryTum, GivenSteadyStateWhenTrackingThenOnlyOpenCvOrbAllocates) {
  HWR_REQUIRE_DATASET(kTeddyDir);
  auto log = hal::open_dataset_log("tum:" + kTeddyDir);
  ASSERT_TRUE(log.ok()) << log.status().message();
  PoseEstimator estimator(PoseEstimatorConfig{}, log->info);
  core::StageAllocations orb;
  estimator.tracker().set_extract_hook(&core::StageAllocations::hook, &orb);
  hal::RgbdFrame frame;
  size_t steady = 0, frames_with_allocations = 0;
  uint64_t orb_total = 0;
  for (size_t i = 0; i < log->frame_t_ns.size(); ++i) {
    ASSERT_TRUE(log->load_frame(i, &frame).ok());
    orb.allocations = 0;
    core::AllocationScope scope;
    const TrackResult& r = estimator.process_frame(frame);
    const uint64_t outside_orb = scope.allocations() - orb.allocations;
    const uint64_t orb_allocs = orb.allocations;
    if (estimator.local_ba_due()) {
      ASSERT_TRUE(estimator.run_local_ba().ok());
    }
    if (i < 30 || r.keyframe) continue;
    ++steady;
    orb_total += orb_allocs;
    if (outside_orb > 0) {
      ++frames_with_allocations;
      ADD_FAILURE() << "frame " << i << ": " << outside_orb << " allocations outside the ORB extraction";
    }
  }
  EXPECT_GT(steady, 100u);
  EXPECT_EQ(frames_with_allocations, 0u);
  std::printf("[ info ] %zu steady-state frames; OpenCV ORB allocates %.1f times per frame, the rest 0\n",
              steady, static_cast<double>(orb_total) / static_cast<double>(steady));
}

}  // namespace
}  // namespace hwr::estimation
