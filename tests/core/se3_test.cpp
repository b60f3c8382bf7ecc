// SE(3) helpers against the 4x4 matrix exponential (unsupported/MatrixFunctions) and closed forms.

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <unsupported/Eigen/MatrixFunctions>

#include "hwr/core/se3.hpp"
#include "hwr/core/so3.hpp"

namespace hwr::core {
namespace {

constexpr double kPi = 3.14159265358979323846;

Vector6d random_twist(std::mt19937_64& rng, double max_angle) {
  std::normal_distribution<double> n(0.0, 1.0);
  std::uniform_real_distribution<double> angle(0.0, max_angle);
  Vector6d xi;
  xi.head<3>() = Eigen::Vector3d(n(rng), n(rng), n(rng)) * 2.0;
  xi.tail<3>() = angle(rng) * Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
  return xi;
}

TEST(Se3Exp, GivenTwistWhenExponentiatedThenEqualsTheMatrixExponentialOfItsGenerator) {
  std::mt19937_64 rng(21);
  for (int i = 0; i < 100; ++i) {
    const Vector6d xi = random_twist(rng, kPi);
    Eigen::Matrix4d X = Eigen::Matrix4d::Zero();
    X.topLeftCorner<3, 3>() = hat(xi.tail<3>());
    X.topRightCorner<3, 1>() = xi.head<3>();
    const Eigen::Matrix4d expected = X.exp();
    EXPECT_LT((se3_exp(xi).matrix() - expected).norm(), 1e-12);
  }
}

TEST(Se3Exp, GivenPureTranslationTwistWhenExponentiatedThenTranslationIsRho) {
  Vector6d xi;
  xi << 1.0, -2.0, 3.0, 0.0, 0.0, 0.0;
  const Eigen::Isometry3d T = se3_exp(xi);
  EXPECT_EQ(T.linear(), Eigen::Matrix3d::Identity());
  EXPECT_LT((T.translation() - Eigen::Vector3d(1, -2, 3)).norm(), 1e-15);
}

TEST(Se3Log, GivenTwistsBelowPiWhenLogOfExpThenTheSameTwist) {
  std::mt19937_64 rng(22);
  for (int i = 0; i < 500; ++i) {
    const Vector6d xi = random_twist(rng, kPi - 1e-6);
    EXPECT_LT((se3_log(se3_exp(xi)) - xi).norm(), 1e-10) << xi.transpose();
  }
  Vector6d tiny;
  tiny << 0.5, 0.25, -1.0, 1e-9, -1e-9, 2e-9;
  EXPECT_LT((se3_log(se3_exp(tiny)) - tiny).norm(), 1e-15);
}

TEST(Se3Log, GivenPosesWhenExpOfLogThenTheSamePose) {
  std::mt19937_64 rng(23);
  for (int i = 0; i < 500; ++i) {
    const Eigen::Isometry3d T = se3_exp(random_twist(rng, kPi));
    EXPECT_LT((se3_exp(se3_log(T)).matrix() - T.matrix()).norm(), 1e-11);
  }
  // Half turn: the log is ambiguous in sign but exp(log(T)) is still T.
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() =
      2.0 * Eigen::Vector3d::UnitY() * Eigen::Vector3d::UnitY().transpose() - Eigen::Matrix3d::Identity();
  T.translation() = Eigen::Vector3d(0.3, 0.2, 0.1);
  EXPECT_LT((se3_exp(se3_log(T)).matrix() - T.matrix()).norm(), 1e-12);
}

TEST(Se3Interpolate, GivenTwoPosesWhenInterpolatedThenRotationIsGeodesicAndTranslationLinear) {
  std::mt19937_64 rng(24);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Isometry3d T0 = se3_exp(random_twist(rng, kPi - 1e-3));
    const Eigen::Isometry3d T1 = se3_exp(random_twist(rng, kPi - 1e-3));
    EXPECT_LT((se3_interpolate(T0, T1, 0.0).matrix() - T0.matrix()).norm(), 1e-12);
    EXPECT_LT((se3_interpolate(T0, T1, 1.0).matrix() - T1.matrix()).norm(), 1e-12);
    const Eigen::Isometry3d Tm = se3_interpolate(T0, T1, 0.25);
    EXPECT_LT((Tm.translation() - (0.75 * T0.translation() + 0.25 * T1.translation())).norm(), 1e-12);
    EXPECT_LT((Tm.linear() - so3_interpolate(T0.linear(), T1.linear(), 0.25)).norm(), 1e-15);
  }
}

TEST(Se3Interpolate, GivenBodyMovingAtConstantVelocityAndRateWhenInterpolatedThenExactPose) {
  // p(t) = p0 + v t, R(t) = R0 exp(t w): the pose interpolation model reproduces it exactly.
  const Eigen::Vector3d p0(1, 2, 3), v(0.5, -0.1, 0.2), w(0.1, 0.7, -0.3);
  const Eigen::Matrix3d R0 = so3_exp(Eigen::Vector3d(0.2, 0.1, -1.0));
  auto pose_at = [&](double t) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R0 * so3_exp(t * w);
    T.translation() = p0 + t * v;
    return T;
  };
  for (double alpha : {0.1, 0.5, 0.8}) {
    EXPECT_LT((se3_interpolate(pose_at(0), pose_at(1), alpha).matrix() - pose_at(alpha).matrix()).norm(),
              1e-13);
  }
}

TEST(Orthonormalize, GivenDriftedRotationWhenOrthonormalizedThenNearestRotation) {
  std::mt19937_64 rng(25);
  std::normal_distribution<double> n(0.0, 1e-4);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Matrix3d R = se3_exp(random_twist(rng, kPi)).linear();
    Eigen::Matrix3d noisy = R;
    for (int k = 0; k < 9; ++k) noisy(k / 3, k % 3) += n(rng);
    const Eigen::Matrix3d fixed = orthonormalize(noisy);
    EXPECT_LT((fixed.transpose() * fixed - Eigen::Matrix3d::Identity()).norm(), 1e-14);
    EXPECT_NEAR(fixed.determinant(), 1.0, 1e-14);
    // Nearest: no worse than the true rotation the noise was added to.
    EXPECT_LE((fixed - noisy).norm(), (R - noisy).norm() + 1e-15);
    // An exact rotation is a fixed point.
    EXPECT_LT((orthonormalize(R) - R).norm(), 1e-14);
  }
}

TEST(Orthonormalize, GivenManyChainedIncrementsWhenRenormalizedThenStaysOnSo3) {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  const Eigen::Matrix3d step = so3_exp(Eigen::Vector3d(1e-3, -2e-3, 0.5e-3));
  for (int i = 0; i < 100000; ++i) R = R * step;
  const Eigen::Matrix3d fixed = orthonormalize(R);
  EXPECT_LT((fixed.transpose() * fixed - Eigen::Matrix3d::Identity()).norm(), 1e-14);
  EXPECT_LT((fixed - R).norm(), 1e-9);
}

}  // namespace
}  // namespace hwr::core
