// The visual-inertial pipeline on the simulator's lab (rendered live, with IMU, depth noise and
// texture): accuracy against the simulator's exact ground truth, and the robustness cases of issue
// #3 — a 2 s camera dropout (IMU-only propagation, then recovery), an exposure jump, NaN depth
// holes, a fast turn — each must keep running, count its fault, and stay within 2x the clean
// run's ATE.

#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "hwr/estimation/offline_run.hpp"
#include "hwr/estimation/trajectory_metrics.hpp"
#include "hwr/hal/fault_injection.hpp"
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/sim_live_log.hpp"

namespace hwr::estimation {
namespace {

constexpr double kDurationS = 26.0;  // two walks and a turn in place at a weld joint

struct SimRun {
  double ate_m = 0;
  OfflineRun run;
  std::shared_ptr<hal::FaultReport> faults;
};

SimRun run_lab(const std::string& faults, const std::string& yaml_overrides = "") {
  SimRun out;
  auto spec = yaml_overrides.empty() ? sim::builtin_scenario("lab")
                                     : sim::parse_scenario_yaml("base: lab\n" + yaml_overrides, "test");
  EXPECT_TRUE(spec.ok()) << spec.status().message();
  if (!spec.ok()) return out;
  auto live = sim::open_sim_live_log(spec.value(), kDurationS);
  EXPECT_TRUE(live.ok()) << live.status().message();
  if (!live.ok()) return out;
  hal::ReplayLog log = std::move(live->log);
  if (!faults.empty()) {
    auto fs = hal::parse_fault_spec(faults);
    EXPECT_TRUE(fs.ok()) << fs.status().message();
    auto faulty = hal::apply_faults(std::move(log), fs.value(), &out.faults);
    EXPECT_TRUE(faulty.ok()) << faulty.status().message();
    log = std::move(faulty.value());
  }
  auto run = run_offline(log, OfflineRunOptions{});
  EXPECT_TRUE(run.ok()) << run.status().message();
  if (!run.ok()) return out;
  out.run = std::move(run.value());
  auto ate = compute_ate(live->groundtruth_T_world_cam_at_frames, out.run.trajectory);
  EXPECT_TRUE(ate.ok()) << ate.status().message();
  if (ate.ok()) out.ate_m = ate->translation_m.rmse;
  std::printf("[ info ] lab %.0f s%s%s: ATE %.4f m, frames %zu, lost %llu, recovered %llu, keyframes %llu\n",
              kDurationS, faults.empty() ? "" : " with faults ", faults.c_str(), out.ate_m, out.run.frames,
              static_cast<unsigned long long>(out.run.counters.tracker.lost),
              static_cast<unsigned long long>(out.run.counters.tracker.recovered),
              static_cast<unsigned long long>(out.run.counters.tracker.keyframes));
  return out;
}

const SimRun& clean_run() {
  static const SimRun run = run_lab("");
  return run;
}

TEST(PoseEstimatorSim, GivenTheLabWhenRunVisualInertialThenTheAteIsUnderTwoCentimetres) {
  const SimRun& r = clean_run();
  EXPECT_TRUE(r.run.counters.imu_initialized);
  EXPECT_FALSE(r.run.counters.visual_only);
  EXPECT_EQ(r.run.counters.tracker.lost, 0u);
  EXPECT_GT(r.run.counters.mekf.updates, 600u);
  EXPECT_GT(r.run.trajectory.size(), 700u);
  EXPECT_LT(r.ate_m, 0.02);
}

TEST(PoseEstimatorSim, GivenATwoSecondCameraDropoutWhenWalkingThenTheImuCarriesItAndTrackingResumes) {
  const SimRun faulty = run_lab("dropout=8:2");
  ASSERT_TRUE(faulty.faults);
  EXPECT_GE(faulty.faults->frames_removed.load(), 59u);
  EXPECT_FALSE(faulty.run.counters.visual_only);
  EXPECT_LT(faulty.ate_m, 2.0 * std::max(clean_run().ate_m, 0.005));
  EXPECT_GT(faulty.run.trajectory.size(), 650u);
}

TEST(PoseEstimatorSim, GivenAnExposureJumpThenTrackingContinues) {
  const SimRun faulty = run_lab("exposure=6:1.8,exposure=14:0.6");
  ASSERT_TRUE(faulty.faults);
  EXPECT_GT(faulty.faults->frames_exposure_changed.load(), 300u);
  EXPECT_LT(faulty.ate_m, 2.0 * std::max(clean_run().ate_m, 0.005));
}

TEST(PoseEstimatorSim, GivenNanDepthHolesThenTrackingContinues) {
  const SimRun faulty = run_lab("depth-nan=4:10:0.4");
  ASSERT_TRUE(faulty.faults);
  EXPECT_GT(faulty.faults->frames_with_depth_holes.load(), 250u);
  EXPECT_EQ(faulty.run.counters.tracker.bad_frames, 0u);
  EXPECT_LT(faulty.ate_m, 2.0 * std::max(clean_run().ate_m, 0.005));
}

TEST(PoseEstimatorSim, GivenAFastTurnInPlaceThenTrackingHolds) {
  // Turns in place at 3 rad/s (172 deg/s) instead of 0.8.
  const SimRun fast = run_lab("", "trajectory:\n  turn_rate_radps: 3.0\n  min_turn_time_s: 0.3\n");
  EXPECT_LT(fast.ate_m, 2.0 * std::max(clean_run().ate_m, 0.005));
}

}  // namespace
}  // namespace hwr::estimation
