// ATE / RPE (estimation/trajectory_metrics.hpp) against closed-form values.

#include <bitset>
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "hwr/core/tum_trajectory.hpp"
#include "hwr/estimation/trajectory_metrics.hpp"

namespace hwr::estimation {
namespace {

using core::StampedPose;

constexpr int64_t kT0 = 1'000'000'000'000LL;  // 1000 s
constexpr int64_t kDt = 50'000'000LL;         // 20 Hz

StampedPose pose(int64_t t_ns, const Eigen::Matrix3d& R, const Eigen::Vector3d& p) {
  StampedPose s;
  s.t_ns = t_ns;
  s.T_world_body.linear() = R;
  s.T_world_body.translation() = p;
  return s;
}

Eigen::Isometry3d rigid(double angle, const Eigen::Vector3d& axis, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  T.translation() = t;
  return T;
}

// Thue-Morse sign s_k = (-1)^popcount(k): over every aligned block of 16 it is orthogonal to
// 1, k, k^2, k^3, so a cubic trajectory's centred positions have zero cross-covariance with an
// alternating perturbation s_k·d·u.
int thue_morse(size_t k) { return std::bitset<64>(k).count() % 2 == 0 ? 1 : -1; }

// Ground truth on a twisted cubic (positions span 3D), rotating as it goes.
std::vector<StampedPose> cubic_gt(size_t n) {
  std::vector<StampedPose> gt;
  for (size_t k = 0; k < n; ++k) {
    const double s = static_cast<double>(k) / static_cast<double>(n);
    const Eigen::Vector3d p(2.0 * s, 1.5 * s * s, 1.0 * s * s * s);
    gt.push_back(
        pose(kT0 + static_cast<int64_t>(k) * kDt,
             Eigen::AngleAxisd(0.8 * s, Eigen::Vector3d(0.2, 0.3, 1).normalized()).toRotationMatrix(), p));
  }
  return gt;
}

std::vector<StampedPose> transformed(const std::vector<StampedPose>& in, const Eigen::Isometry3d& T) {
  std::vector<StampedPose> out = in;
  for (StampedPose& p : out) p.T_world_body = T * p.T_world_body;
  return out;
}

TEST(ErrorStats, GivenKnownErrors_WhenSummarised_ThenNumpyConventionsHold) {
  const ErrorStats s = compute_error_stats({1, 2, 3, 4});
  EXPECT_EQ(s.count, 4u);
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);  // mean of the middle two
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(30.0 / 4));
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(1.25));  // population std (ddof = 0)
  EXPECT_DOUBLE_EQ(s.min, 1);
  EXPECT_DOUBLE_EQ(s.max, 4);
  EXPECT_DOUBLE_EQ(compute_error_stats({5, 1, 3}).median, 3);
  EXPECT_EQ(compute_error_stats({}).count, 0u);
}

TEST(AssociateByTime, GivenCloseAndFarStamps_WhenAssociated_ThenNearestUniquePairsWithinStrictWindow) {
  std::vector<StampedPose> gt(4);
  std::vector<StampedPose> est(4);
  const int64_t ms = 1'000'000;
  gt[0].t_ns = 0;
  gt[1].t_ns = 100 * ms;
  gt[2].t_ns = 200 * ms;
  gt[3].t_ns = 300 * ms;
  est[0].t_ns = 5 * ms;    // -> gt 0
  est[1].t_ns = 8 * ms;    // gt 0 taken by the closer est 0; gt 1 is 92 ms away: unmatched
  est[2].t_ns = 220 * ms;  // exactly 20 ms: not < max_dt, unmatched
  est[3].t_ns = 299 * ms;  // -> gt 3
  const std::vector<PoseMatch> m = associate_by_time(gt, est, 0.02);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0].gt, 0u);
  EXPECT_EQ(m[0].est, 0u);
  EXPECT_EQ(m[1].gt, 3u);
  EXPECT_EQ(m[1].est, 3u);
  // With an offset of -0.015 s the estimate stamps move earlier: est1 (8-15=-7 ms) and est0 (-10 ms)
  // compete for gt0; est2 lands at 205 ms -> gt2; est3 at 284 ms -> gt3.
  const std::vector<PoseMatch> mo = associate_by_time(gt, est, 0.02, -0.015);
  ASSERT_EQ(mo.size(), 3u);
  EXPECT_EQ(mo[0].est, 1u);
  EXPECT_EQ(mo[1].gt, 2u);
  EXPECT_EQ(mo[1].est, 2u);
  EXPECT_EQ(mo[2].gt, 3u);
}

TEST(Ate, GivenIdenticalTrajectories_WhenEvaluated_ThenErrorIsZeroAndAlignmentIdentity) {
  const auto gt = cubic_gt(64);
  auto r = compute_ate(gt, gt);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_EQ(r->pairs, 64u);
  EXPECT_EQ(r->translation_m.count, 64u);
  EXPECT_LT(r->translation_m.rmse, 1e-12);
  EXPECT_LT(r->translation_m.max, 1e-12);
  EXPECT_TRUE(r->T_gt_est.isApprox(Eigen::Isometry3d::Identity(), 1e-12));
  EXPECT_EQ(r->scale, 1.0);
}

TEST(Ate, GivenARigidMotionPlusAlternatingOffsets_WhenEvaluated_ThenAlignmentIsTheMotionAndEveryErrorIsD) {
  // GIVEN est_k = A^-1 (gt_k + s_k·d·u): the optimal alignment is exactly A, every residual is d.
  const size_t n = 64;  // 4 blocks of 16
  const double d = 0.037;
  const Eigen::Vector3d u = Eigen::Vector3d(1, -2, 0.5).normalized();
  const Eigen::Isometry3d A = rigid(1.1, Eigen::Vector3d(1, 1, 0), Eigen::Vector3d(4, -3, 2));
  const auto gt = cubic_gt(n);
  std::vector<StampedPose> est = gt;
  for (size_t k = 0; k < n; ++k) {
    est[k].T_world_body.translation() = gt[k].T_world_body.translation() + thue_morse(k) * d * u;
    est[k].T_world_body = A.inverse() * est[k].T_world_body;
  }
  // WHEN
  auto r = compute_ate(gt, est);
  // THEN
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_EQ(r->pairs, n);
  EXPECT_NEAR(r->translation_m.rmse, d, 1e-9);
  EXPECT_NEAR(r->translation_m.mean, d, 1e-9);
  EXPECT_NEAR(r->translation_m.median, d, 1e-9);
  EXPECT_NEAR(r->translation_m.max, d, 1e-9);
  EXPECT_NEAR(r->translation_m.min, d, 1e-9);
  EXPECT_NEAR(r->translation_m.std, 0.0, 1e-9);
  EXPECT_LT((r->T_gt_est.matrix() - A.matrix()).cwiseAbs().maxCoeff(), 1e-9);
  for (double e : r->errors_m) EXPECT_NEAR(e, d, 1e-9);
}

TEST(Ate, GivenAnEstimateInAnyWorldFrame_WhenEvaluated_ThenErrorsAreInvariant) {
  const size_t n = 48;
  const auto gt = cubic_gt(n);
  std::vector<StampedPose> est = gt;
  for (size_t k = 0; k < n; ++k) {  // an arbitrary, non-structured perturbation
    est[k].T_world_body.translation() +=
        0.01 * Eigen::Vector3d(std::sin(3.0 * k), std::cos(5.0 * k), std::sin(k * k));
  }
  auto base = compute_ate(gt, est);
  ASSERT_TRUE(base.ok());
  const Eigen::Isometry3d G = rigid(-2.3, Eigen::Vector3d(0.3, -1, 2), Eigen::Vector3d(-100, 50, 7));
  auto moved = compute_ate(gt, transformed(est, G));
  ASSERT_TRUE(moved.ok());
  EXPECT_NEAR(moved->translation_m.rmse, base->translation_m.rmse, 1e-9);
  EXPECT_NEAR(moved->translation_m.max, base->translation_m.max, 1e-9);
  ASSERT_EQ(moved->errors_m.size(), base->errors_m.size());
  for (size_t k = 0; k < n; ++k) EXPECT_NEAR(moved->errors_m[k], base->errors_m[k], 1e-9);
  // The alignment absorbs G: T_moved = T_base · G^-1.
  EXPECT_LT(((moved->T_gt_est * G).matrix() - base->T_gt_est.matrix()).cwiseAbs().maxCoeff(), 1e-8);
}

TEST(Ate, GivenAScaledEstimate_WhenEvaluatedWithSim3_ThenScaleIsRecoveredAndErrorVanishes) {
  const auto gt = cubic_gt(40);
  const double s = 0.25;  // the estimate is 4x too small
  const Eigen::Isometry3d A = rigid(0.7, Eigen::Vector3d(0, 1, 1), Eigen::Vector3d(1, 2, 3));
  std::vector<StampedPose> est = gt;
  for (StampedPose& p : est) p.T_world_body.translation() = s * (A * p.T_world_body.translation());
  AteOptions sim3;
  sim3.sim3 = true;
  auto r = compute_ate(gt, est, sim3);
  ASSERT_TRUE(r.ok());
  EXPECT_NEAR(r->scale, 1.0 / s, 1e-9);
  EXPECT_LT(r->translation_m.max, 1e-9);
  // SE(3) alignment cannot absorb the scale.
  auto se3 = compute_ate(gt, est);
  ASSERT_TRUE(se3.ok());
  EXPECT_GT(se3->translation_m.rmse, 0.1);
  EXPECT_EQ(se3->scale, 1.0);
}

TEST(Ate, GivenAnEstimateWithAClockOffset_WhenTheOffsetIsGiven_ThenAllPosesAssociate) {
  const auto gt = cubic_gt(30);
  std::vector<StampedPose> est = gt;
  // Estimate clock 0.525 s ahead: every stamp falls 25 ms from the nearest ground truth.
  for (StampedPose& p : est) p.t_ns += 525'000'000;
  EXPECT_FALSE(compute_ate(gt, est).ok());
  AteOptions o;
  o.offset_s = -0.525;
  auto r = compute_ate(gt, est, o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_EQ(r->pairs, 30u);
  EXPECT_LT(r->translation_m.rmse, 1e-12);
}

TEST(Ate, GivenFewerThanThreePairs_WhenEvaluated_ThenErrorSaysHowManyWereFound) {
  const auto gt = cubic_gt(10);
  std::vector<StampedPose> est(gt.begin(), gt.begin() + 2);
  auto r = compute_ate(gt, est);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), core::ErrorCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("at least 3 associated poses, found 2"), std::string::npos)
      << r.status().message();
  EXPECT_FALSE(compute_ate(gt, {}).ok());
}

TEST(Ate, GivenTheRealTeddyGroundTruthMovedRigidly_WhenEvaluated_ThenErrorIsZero) {
  const std::string path = HWR_DATA_DIR "/tum-fr3-teddy-200/rgbd_dataset_freiburg3_teddy/groundtruth.txt";
  auto gt = core::read_tum_trajectory(path);
  ASSERT_TRUE(gt.ok()) << "dataset missing or unreadable: " << gt.status().to_string()
                       << " (see shared/data/README.md)";
  const Eigen::Isometry3d G = rigid(2.0, Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(10, -20, 30));
  auto r = compute_ate(*gt, transformed(*gt, G));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->pairs, 8080u);
  EXPECT_LT(r->translation_m.max, 1e-9);
  EXPECT_LT((r->T_gt_est.matrix() - G.inverse().matrix()).cwiseAbs().maxCoeff(), 1e-9);
}

// Straight-line ground truth along x at 1 m per frame, identity attitude.
std::vector<StampedPose> line_gt(size_t n) {
  std::vector<StampedPose> gt;
  for (size_t k = 0; k < n; ++k) {
    gt.push_back(pose(kT0 + static_cast<int64_t>(k) * kDt, Eigen::Matrix3d::Identity(),
                      Eigen::Vector3d(static_cast<double>(k), 0, 0)));
  }
  return gt;
}

TEST(Rpe, GivenAConstantPerFrameTranslationError_WhenEvaluatedOverNFrames_ThenErrorIsNTimesIt) {
  // est moves (1, 0.02, -0.01) per frame instead of (1, 0, 0): over delta frames the relative
  // translation is off by delta·e, the rotation not at all.
  const size_t n = 30;
  const auto gt = line_gt(n);
  const Eigen::Vector3d e(0, 0.02, -0.01);
  std::vector<StampedPose> est = gt;
  for (size_t k = 0; k < n; ++k) est[k].T_world_body.translation() += static_cast<double>(k) * e;
  RpeOptions o;
  o.delta = 3;
  o.delta_unit = DeltaUnit::kFrames;
  auto r = compute_rpe(gt, est, o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  // Pairs (i, i+3) with i + 3 < n - 1 (the script drops pairs ending on the last pose).
  EXPECT_EQ(r->pairs, n - 4);
  EXPECT_EQ(r->est_pairs.front(), std::make_pair(size_t{0}, size_t{3}));
  EXPECT_NEAR(r->translation_m.rmse, 3 * e.norm(), 1e-12);
  EXPECT_NEAR(r->translation_m.max, 3 * e.norm(), 1e-12);
  EXPECT_NEAR(r->translation_m.min, 3 * e.norm(), 1e-12);
  EXPECT_LT(r->rotation_rad.max, 1e-12);

  // The same delta in seconds: 3 frames at 20 Hz = 0.15 s.
  RpeOptions s;
  s.delta = 0.15;
  auto rs = compute_rpe(gt, est, s);
  ASSERT_TRUE(rs.ok());
  EXPECT_EQ(rs->pairs, r->pairs);
  EXPECT_NEAR(rs->translation_m.rmse, 3 * e.norm(), 1e-12);
}

TEST(Rpe, GivenAConstantYawRateError_WhenEvaluated_ThenRotationErrorIsDeltaTimesIt) {
  // Ground truth spins about z in place by alpha per frame; the estimate by alpha + omega.
  const size_t n = 25;
  const double alpha = 0.05;
  const double omega = 0.003;
  std::vector<StampedPose> gt;
  std::vector<StampedPose> est;
  for (size_t k = 0; k < n; ++k) {
    const int64_t t = kT0 + static_cast<int64_t>(k) * kDt;
    gt.push_back(pose(t, Eigen::AngleAxisd(alpha * k, Eigen::Vector3d::UnitZ()).toRotationMatrix(),
                      Eigen::Vector3d::Zero()));
    est.push_back(pose(t, Eigen::AngleAxisd((alpha + omega) * k, Eigen::Vector3d::UnitZ()).toRotationMatrix(),
                       Eigen::Vector3d::Zero()));
  }
  RpeOptions o;
  o.delta = 2;
  o.delta_unit = DeltaUnit::kFrames;
  auto r = compute_rpe(gt, est, o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_EQ(r->pairs, n - 3);
  EXPECT_NEAR(r->rotation_rad.mean, 2 * omega, 1e-12);
  EXPECT_NEAR(r->rotation_rad.max, 2 * omega, 1e-12);
  EXPECT_LT(r->translation_m.max, 1e-12);
}

TEST(Rpe, GivenAnEstimateInAnotherWorldFrame_WhenEvaluated_ThenRpeIsUnchanged) {
  const auto gt = cubic_gt(40);
  std::vector<StampedPose> est = gt;
  for (size_t k = 0; k < est.size(); ++k) {
    est[k].T_world_body = est[k].T_world_body * rigid(0.01 * std::sin(k), Eigen::Vector3d(1, 0, 1),
                                                      0.005 * Eigen::Vector3d(std::cos(k), 1, 0));
  }
  RpeOptions o;
  o.delta = 5;
  o.delta_unit = DeltaUnit::kFrames;
  auto base = compute_rpe(gt, est, o);
  ASSERT_TRUE(base.ok());
  EXPECT_GT(base->translation_m.rmse, 1e-4);
  auto moved =
      compute_rpe(gt, transformed(est, rigid(1.0, Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(5, 6, 7))), o);
  ASSERT_TRUE(moved.ok());
  EXPECT_NEAR(moved->translation_m.rmse, base->translation_m.rmse, 1e-12);
  EXPECT_NEAR(moved->rotation_rad.rmse, base->rotation_rad.rmse, 1e-12);
}

TEST(Rpe, GivenEstimatePosesFarFromAnyGroundTruth_WhenEvaluated_ThenThosePairsAreSkippedAndCounted) {
  const auto gt = line_gt(20);  // 1000.00 .. 1000.95 s
  std::vector<StampedPose> est = gt;
  for (size_t k = 10; k < est.size(); ++k) est[k].t_ns += 5'000'000'000LL;  // second half 5 s later
  RpeOptions o;
  o.delta = 1;
  o.delta_unit = DeltaUnit::kFrames;
  auto r = compute_rpe(gt, est, o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  // Pairs (i, i+1) for i = 0..17; those touching the shifted half (i >= 9) have no ground truth.
  EXPECT_EQ(r->pairs, 9u);
  EXPECT_EQ(r->skipped_no_gt, 9u);
}

TEST(Rpe, GivenTooFewPairs_WhenEvaluated_ThenError) {
  const auto gt = line_gt(4);
  RpeOptions o;
  o.delta = 1;
  o.delta_unit = DeltaUnit::kFrames;
  auto r = compute_rpe(gt, gt, o);  // pairs (0,1), (1,2) only
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("at least 3 pose pairs"), std::string::npos) << r.status().message();
  EXPECT_FALSE(compute_rpe(gt, {}, o).ok());
}

}  // namespace
}  // namespace hwr::estimation
