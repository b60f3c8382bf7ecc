// PoseHistory (estimation/pose_history.hpp): interpolation exact on the motions it claims to be
// exact for (constant angular rate about a fixed axis, cubic positions), camera composition,
// range errors, eviction, and no allocation.

#include <cmath>
#include <cstdint>
#include <string>

#include <gtest/gtest.h>

#include "hwr/core/alloc_counter.hpp"
#include "hwr/core/so3.hpp"
#include "hwr/core/time.hpp"
#include "hwr/estimation/pose_history.hpp"

namespace hwr::estimation {
namespace {

constexpr int64_t kT0 = 1'403'715'273'262'142'976LL;  // a EuRoC-sized stamp: doubles would lose ns
constexpr int64_t kDt = 5'000'000;                    // 200 Hz

const Eigen::Matrix3d kR0 = core::so3_exp(Eigen::Vector3d(0.4, -1.1, 2.0));
const Eigen::Vector3d kW(0.3, -1.7, 2.2);  // rad/s, world axes: R(t) = Exp(w t) R0

// Constant rate about a fixed axis and a cubic position p(t) = p0 + v0 t + a t^2/2 + j t^3/6.
NavState motion(int64_t t_ns) {
  const double t = core::ns_to_s(t_ns - kT0);
  const Eigen::Vector3d p0(1, -2, 0.5), v0(0.8, 0.1, -0.2), a(0.3, -0.5, 0.1), j(-0.2, 0.4, 0.9);
  NavState x;
  x.t_ns = t_ns;
  x.R_world_imu = core::so3_exp(kW * t) * kR0;
  x.p_world_imu_m = p0 + v0 * t + a * (t * t / 2) + j * (t * t * t / 6);
  x.v_world_mps = v0 + a * t + j * (t * t / 2);
  return x;
}

TEST(PoseHistory, ExactForConstantRateRotationAndCubicPosition) {
  // GIVEN 200 Hz states of a constant-rate rotation (|w| = 2.8 rad/s) and a cubic position
  PoseHistory history(800);
  for (int k = 0; k < 100; ++k) ASSERT_TRUE(history.push(motion(kT0 + k * kDt)));
  // WHEN interpolated at times between the samples (odd offsets, like camera stamps)
  for (int64_t t_ns = kT0 + 1'234'567; t_ns < kT0 + 99 * kDt; t_ns += 3'333'333) {
    Eigen::Isometry3d T;
    ASSERT_TRUE(history.interpolate(t_ns, &T).ok());
    const NavState truth = motion(t_ns);
    // THEN the rotation equals Exp(w t) R0 and the position the cubic, to round-off
    EXPECT_LT((T.linear() - truth.R_world_imu).cwiseAbs().maxCoeff(), 1e-12) << t_ns;
    EXPECT_LT((T.translation() - truth.p_world_imu_m).cwiseAbs().maxCoeff(), 1e-12) << t_ns;
    EXPECT_LT((T.linear().transpose() * T.linear() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(),
              1e-14);
  }
}

TEST(PoseHistory, LinearMatrixInterpolationWouldFailTheSameOracle) {
  // The paper's eq. (2) (R = (1 - a) R0 + a R1) on the same motion is off by ~1e-4 at mid-step:
  // the oracle above distinguishes the two.
  const NavState s0 = motion(kT0), s1 = motion(kT0 + kDt), mid = motion(kT0 + kDt / 2);
  const Eigen::Matrix3d R_lin = 0.5 * (s0.R_world_imu + s1.R_world_imu);
  EXPECT_GT((R_lin - mid.R_world_imu).cwiseAbs().maxCoeff(), 1e-5);
  PoseHistory history(4);
  ASSERT_TRUE(history.push(s0));
  ASSERT_TRUE(history.push(s1));
  Eigen::Isometry3d T;
  ASSERT_TRUE(history.interpolate(mid.t_ns, &T).ok());
  EXPECT_LT((T.linear() - mid.R_world_imu).cwiseAbs().maxCoeff(), 1e-13);
}

TEST(PoseHistory, ConstantVelocityTranslationExactAndSampleTimesReturnTheSample) {
  PoseHistory history(8);
  const Eigen::Vector3d v(0.7, -0.2, 0.05);
  for (int k = 0; k < 5; ++k) {
    NavState x;
    x.t_ns = kT0 + k * kDt;
    x.p_world_imu_m = v * core::ns_to_s(k * kDt);
    x.v_world_mps = v;
    ASSERT_TRUE(history.push(x));
  }
  Eigen::Isometry3d T;
  ASSERT_TRUE(history.interpolate(kT0 + 7'654'321, &T).ok());
  EXPECT_LT((T.translation() - v * 7.654321e-3).norm(), 1e-15);
  EXPECT_TRUE(T.linear().isIdentity(0.0));
  ASSERT_TRUE(history.interpolate(kT0 + 2 * kDt, &T).ok());
  EXPECT_EQ(T.translation(), history.at(2).p_world_imu_m);
  ASSERT_TRUE(history.interpolate(kT0 + 4 * kDt, &T).ok());  // the newest, inclusive
  EXPECT_EQ(T.translation(), history.newest().p_world_imu_m);
  NavState s;
  ASSERT_TRUE(history.interpolate_state(kT0 + 2 * kDt + kDt / 4, &s).ok());
  EXPECT_LT((s.v_world_mps - v).norm(), 1e-15);
  EXPECT_EQ(s.t_ns, kT0 + 2 * kDt + kDt / 4);
}

TEST(PoseHistory, CameraPoseComposesTheExtrinsics) {
  PoseHistory history(16);
  for (int k = 0; k < 10; ++k) ASSERT_TRUE(history.push(motion(kT0 + k * kDt)));
  Eigen::Isometry3d T_imu_cam = Eigen::Isometry3d::Identity();
  T_imu_cam.linear() = core::so3_exp(Eigen::Vector3d(-1.2, 0.0, -1.2));
  T_imu_cam.translation() = Eigen::Vector3d(0.1, 0.0, 0.3);
  const int64_t t_img = kT0 + 3 * kDt + 1'700'000;
  Eigen::Isometry3d T_world_cam, T_world_imu;
  ASSERT_TRUE(history.interpolate_camera(t_img, T_imu_cam, &T_world_cam).ok());
  ASSERT_TRUE(history.interpolate(t_img, &T_world_imu).ok());
  const Eigen::Isometry3d expected = motion(t_img).T_world_imu() * T_imu_cam;
  EXPECT_LT((T_world_cam.matrix() - expected.matrix()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((T_world_cam.matrix() - (T_world_imu * T_imu_cam).matrix()).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(PoseHistory, OutOfRangeTimesGiveClearErrors) {
  PoseHistory history(4);
  Eigen::Isometry3d T;
  const core::Status empty = history.interpolate(kT0, &T);
  EXPECT_EQ(empty.code(), core::ErrorCode::kUnavailable);
  // GIVEN a 4-state ring fed 6 states: the first two are evicted
  for (int k = 0; k < 6; ++k) ASSERT_TRUE(history.push(motion(kT0 + k * kDt)));
  EXPECT_EQ(history.size(), 4u);
  EXPECT_EQ(history.oldest_t_ns(), kT0 + 2 * kDt);
  // THEN a time before the oldest kept state is "evicted" (kOutOfRange) ...
  const core::Status old = history.interpolate(kT0 + kDt, &T);
  EXPECT_EQ(old.code(), core::ErrorCode::kOutOfRange);
  EXPECT_NE(old.message().find("evicted"), std::string::npos) << old.message();
  EXPECT_NE(old.message().find("older than the oldest"), std::string::npos) << old.message();
  // ... one after the newest is "not yet propagated" (kUnavailable: retry later)
  const core::Status future = history.interpolate(kT0 + 5 * kDt + 1, &T);
  EXPECT_EQ(future.code(), core::ErrorCode::kUnavailable);
  EXPECT_NE(future.message().find("not yet propagated"), std::string::npos) << future.message();
  EXPECT_EQ(history.interpolate_camera(kT0, Eigen::Isometry3d::Identity(), &T).code(),
            core::ErrorCode::kOutOfRange);
  // and the edges are inside
  EXPECT_TRUE(history.interpolate(kT0 + 2 * kDt, &T).ok());
  EXPECT_TRUE(history.interpolate(kT0 + 5 * kDt, &T).ok());
}

TEST(PoseHistory, RefusesNonIncreasingTimes) {
  PoseHistory history(4);
  ASSERT_TRUE(history.push(motion(kT0)));
  EXPECT_FALSE(history.push(motion(kT0)));
  EXPECT_FALSE(history.push(motion(kT0 - 1)));
  EXPECT_EQ(history.refused_pushes(), 2u);
  EXPECT_EQ(history.size(), 1u);
}

TEST(PoseHistory, PushAndInterpolateAllocateNothing) {
  PoseHistory history(800);
  NavState states[64];
  for (int k = 0; k < 64; ++k) states[k] = motion(kT0 + k * kDt);
  uint64_t allocations = 0;
  int ok = 0;
  {
    core::AllocationScope scope;
    for (int k = 0; k < 2000; ++k) {
      NavState x = states[k % 64];
      x.t_ns = kT0 + k * kDt;
      history.push(x);
      Eigen::Isometry3d T;
      if (k > 0) ok += history.interpolate(x.t_ns - kDt / 3, &T).ok() ? 1 : 0;
    }
    allocations = scope.allocations();
  }
  EXPECT_EQ(allocations, 0u);
  EXPECT_EQ(ok, 1999);
}

}  // namespace
}  // namespace hwr::estimation
