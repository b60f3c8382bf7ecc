// Trajectory generator: analytic derivatives against central finite differences, exact rest at
// stops, continuity across phase boundaries, path lengths of the presets.

#include <gtest/gtest.h>

#include <cmath>

#include "hwr/core/so3.hpp"
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/trajectory.hpp"
#include "hwr/sim/world_frame.hpp"

namespace hwr::sim {
namespace {

Trajectory build_or_die(const TrajectorySpec& spec) {
  auto t = Trajectory::build(spec);
  EXPECT_TRUE(t.ok()) << t.status().to_string();
  return std::move(t.value());
}

Trajectory preset_trajectory(const std::string& name) {
  auto s = builtin_scenario(name);
  EXPECT_TRUE(s.ok());
  return build_or_die(s->trajectory);
}

TEST(Trajectory, GivenLabWalkWhenDifferentiatedNumericallyThenAnalyticVelocityAccelerationAndRateAgree) {
  const Trajectory traj = preset_trajectory("lab");
  const double h = 1e-4;
  double max_dv = 0, max_da = 0, max_dw = 0;
  for (double t = 0.05; t < traj.duration_s() - 0.05; t += 0.0731) {
    const TrajectoryState s = traj.evaluate(t);
    const TrajectoryState a = traj.evaluate(t - h), b = traj.evaluate(t + h);
    const Eigen::Vector3d v_fd = (b.T_scene_imu.translation() - a.T_scene_imu.translation()) / (2 * h);
    const Eigen::Vector3d a_fd = (b.v_scene_mps - a.v_scene_mps) / (2 * h);
    // Body rate: R(t+h) = R(t-h) exp(2h w) to second order.
    const Eigen::Vector3d w_fd =
        core::so3_log(a.T_scene_imu.linear().transpose() * b.T_scene_imu.linear()) / (2 * h);
    max_dv = std::max(max_dv, (s.v_scene_mps - v_fd).norm());
    max_da = std::max(max_da, (s.a_scene_mps2 - a_fd).norm());
    max_dw = std::max(max_dw, (s.omega_imu_radps - w_fd).norm());
  }
  EXPECT_LT(max_dv, 1e-6);
  EXPECT_LT(max_da, 1e-4);
  EXPECT_LT(max_dw, 1e-6);
}

TEST(Trajectory, GivenStopsWhenEvaluatedThroughoutThenVelocityAndAccelerationAreExactlyZero) {
  const Trajectory traj = preset_trajectory("lab");
  ASSERT_GE(traj.stops().size(), 8u);
  for (const TrajectoryStop& stop : traj.stops()) {
    for (int i = 0; i <= 10; ++i) {
      const double t = stop.t_arrive_s + (stop.t_depart_s - stop.t_arrive_s) * i / 10.0;
      const TrajectoryState s = traj.evaluate(t);
      EXPECT_EQ(s.v_scene_mps.norm(), 0.0) << "t = " << t;
      EXPECT_EQ(s.a_scene_mps2.norm(), 0.0) << "t = " << t;
      EXPECT_LT((s.T_scene_imu.translation().head<2>() - stop.xy_m).norm(), 1e-9);
    }
    // While dwelling the robot faces its target and does not turn.
    const TrajectoryState mid = traj.evaluate(0.5 * (stop.t_dwell_begin_s + stop.t_dwell_end_s));
    EXPECT_EQ(mid.omega_imu_radps.norm(), 0.0);
    const Eigen::Vector3d x = mid.T_scene_imu.linear().col(0);
    EXPECT_NEAR(std::atan2(x.y(), x.x()), std::remainder(stop.dwell_yaw_rad, 2 * M_PI), 1e-12);
  }
}

TEST(Trajectory, GivenPhaseBoundariesWhenApproachedFromBothSidesThenStateIsContinuous) {
  const Trajectory traj = preset_trajectory("lab");
  const double eps = 1e-7;
  for (const TrajectoryStop& stop : traj.stops()) {
    for (double t : {stop.t_arrive_s, stop.t_dwell_begin_s, stop.t_dwell_end_s, stop.t_depart_s}) {
      if (t <= eps || t >= traj.duration_s() - eps) continue;
      const TrajectoryState a = traj.evaluate(t - eps), b = traj.evaluate(t + eps);
      EXPECT_LT((a.T_scene_imu.translation() - b.T_scene_imu.translation()).norm(), 1e-6);
      EXPECT_LT((a.v_scene_mps - b.v_scene_mps).norm(), 1e-5);
      EXPECT_LT((a.a_scene_mps2 - b.a_scene_mps2).norm(), 1e-4);
      EXPECT_LT((a.omega_imu_radps - b.omega_imu_radps).norm(), 1e-5);
      EXPECT_LT((a.T_scene_imu.linear() - b.T_scene_imu.linear()).norm(), 1e-6);
    }
  }
}

TEST(Trajectory, GivenWalkingWhenHeadingComparedWithVelocityThenHeadingFollowsThePathTangent) {
  const Trajectory traj = preset_trajectory("outdoor");
  int checked = 0;
  for (double t = 0; t < traj.duration_s(); t += 0.5) {
    const TrajectoryState s = traj.evaluate(t);
    if (s.speed_mps < 0.05) continue;
    const Eigen::Vector2d heading = s.T_scene_imu.linear().col(0).head<2>().normalized();
    const Eigen::Vector2d dir = s.v_scene_mps.head<2>().normalized();
    EXPECT_GT(heading.dot(dir), 1.0 - 1e-12) << "t = " << t;
    EXPECT_LE(s.speed_mps, 0.9 + 1e-12);
    ++checked;
  }
  EXPECT_GT(checked, 300);
}

TEST(Trajectory, GivenSpeedWhenWalkingThenBobAndRollScaleWithSpeedAndVanishAtRest) {
  const Trajectory traj = preset_trajectory("lab");
  const TrajectorySpec& spec = traj.spec();
  double max_dz = 0, max_roll = 0;
  for (double t = 0; t < traj.duration_s(); t += 0.01) {
    const TrajectoryState s = traj.evaluate(t);
    const double dz = std::abs(s.T_scene_imu.translation().z() - spec.imu_height_m);
    const Eigen::Matrix3d& R = s.T_scene_imu.linear();
    const double roll = std::abs(std::atan2(R(2, 1), R(2, 2)));
    EXPECT_LE(dz, spec.bob_m_per_mps * s.speed_mps + 1e-12);
    EXPECT_LE(roll, spec.roll_rad_per_mps * s.speed_mps + 1e-12);
    max_dz = std::max(max_dz, dz);
    max_roll = std::max(max_roll, roll);
  }
  // The bob really happens (amplitude * cruise speed, reached near the crests).
  EXPECT_GT(max_dz, 0.9 * spec.bob_m_per_mps * spec.cruise_speed_mps);
  EXPECT_GT(max_roll, 0.9 * spec.roll_rad_per_mps * spec.cruise_speed_mps);
}

TEST(Trajectory, GivenPresetsWhenMeasuredThenPathLengthsAreInTheirBands) {
  const double lab = preset_trajectory("lab").length_m();
  const double outdoor = preset_trajectory("outdoor").length_m();
  EXPECT_GE(lab, 45.0);
  EXPECT_LE(lab, 55.0);
  EXPECT_GE(outdoor, 270.0);
  EXPECT_LE(outdoor, 330.0);
  // The walked distance reported at the end equals the path length.
  const Trajectory t = preset_trajectory("lab");
  EXPECT_NEAR(t.evaluate(t.duration_s()).distance_m, t.length_m(), 1e-9);
}

TEST(Trajectory, GivenStraightLineWhenEvaluatedThenArcLengthAndPositionsAreExact) {
  TrajectorySpec spec;
  spec.waypoints.resize(2);
  spec.waypoints[0].xy_m = {1.0, 2.0};
  spec.waypoints[1].xy_m = {4.0, 6.0};  // 5 m
  spec.bob_m_per_mps = 0.0;
  spec.roll_rad_per_mps = 0.0;
  const Trajectory traj = build_or_die(spec);
  EXPECT_NEAR(traj.length_m(), 5.0, 1e-12);
  // Smooth trapezoid: 2 ramps of ramp_time_s plus cruise (5 - v * ramp) / v.
  EXPECT_NEAR(traj.duration_s(), 2 * 1.5 + (5.0 - 0.8 * 1.5) / 0.8, 1e-12);
  const TrajectoryState mid = traj.evaluate(0.5 * traj.duration_s());
  EXPECT_LT((mid.T_scene_imu.translation() - Eigen::Vector3d(2.5, 4.0, spec.imu_height_m)).norm(), 1e-12);
  EXPECT_NEAR(mid.speed_mps, 0.8, 1e-12);
  EXPECT_LT(mid.omega_imu_radps.norm(), 1e-12);
}

TEST(Trajectory, GivenStartPoseWhenWorldFrameBuiltThenItIsTheFirstImuFrame) {
  const Trajectory traj = preset_trajectory("lab-revisit");
  const Eigen::Isometry3d T0 = traj.evaluate(0.0).T_scene_imu;
  const Eigen::Isometry3d T_scene_world = world_frame_from_first_imu_pose(T0);
  // The walk starts level, so world is exactly the first IMU frame.
  EXPECT_LT((T_scene_world.matrix() - T0.matrix()).norm(), 1e-12);
  // Gravity-aligned in any case: z axes coincide.
  EXPECT_LT((T_scene_world.linear().col(2) - Eigen::Vector3d::UnitZ()).norm(), 1e-15);
}

TEST(Trajectory, GivenBadSpecsWhenBuiltThenErrorsNameTheProblem) {
  TrajectorySpec spec;
  spec.waypoints.resize(1);
  EXPECT_FALSE(Trajectory::build(spec).ok());
  spec.waypoints.resize(3);
  spec.waypoints[1].xy_m = {1, 0};
  spec.waypoints[2].xy_m = {1, 0};
  auto t = Trajectory::build(spec);
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.status().message().find("waypoint 2"), std::string::npos) << t.status().message();
  spec.waypoints[2].xy_m = {2, 0};
  spec.cruise_speed_mps = 0.0;
  t = Trajectory::build(spec);
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.status().message().find("cruise_speed_mps"), std::string::npos);
}

TEST(Trajectory, GivenTimesOutsideTheRunWhenEvaluatedThenTheRobotStandsStill) {
  const Trajectory traj = preset_trajectory("lab");
  const TrajectoryState before = traj.evaluate(-5.0), after = traj.evaluate(traj.duration_s() + 100.0);
  EXPECT_EQ(before.v_scene_mps.norm(), 0.0);
  EXPECT_EQ(after.v_scene_mps.norm(), 0.0);
  EXPECT_LT(
      (after.T_scene_imu.translation() - traj.evaluate(traj.duration_s()).T_scene_imu.translation()).norm(),
      1e-15);
}

}  // namespace
}  // namespace hwr::sim
