// SO(3) property tests on hard inputs (theta = 0, 1e-9, pi - 1e-9, pi) and seeded random ones.
// Oracles: Eigen::AngleAxisd (a second implementation), the matrix exponential series, numeric
// derivatives, and closed-form constant-rate rotations.

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include <unsupported/Eigen/MatrixFunctions>

#include "hwr/core/so3.hpp"

namespace hwr::core {
namespace {

constexpr double kPi = 3.14159265358979323846;

Eigen::Vector3d random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
}

// Axes including ones aligned with the coordinate axes, where the near-pi branch picks columns.
std::vector<Eigen::Vector3d> test_axes() {
  std::vector<Eigen::Vector3d> axes = {Eigen::Vector3d::UnitX(),
                                       Eigen::Vector3d::UnitY(),
                                       Eigen::Vector3d::UnitZ(),
                                       -Eigen::Vector3d::UnitY(),
                                       Eigen::Vector3d(1, 1, 1).normalized(),
                                       Eigen::Vector3d(-1, 2, -3).normalized(),
                                       Eigen::Vector3d(1e-12, 1, 0).normalized()};
  std::mt19937_64 rng(7);
  for (int i = 0; i < 20; ++i) axes.push_back(random_unit(rng));
  return axes;
}

// The hard angles of the brief.
const double kHardAngles[] = {0.0, 1e-12,      1e-9,       1e-5,       1e-3, 0.5,
                              2.0, kPi - 1e-3, kPi - 1e-6, kPi - 1e-9, kPi};

bool is_rotation(const Eigen::Matrix3d& R, double tol) {
  return (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < tol &&
         std::abs(R.determinant() - 1.0) < tol;
}

// Exact rotation by pi about unit a: 2 a a^T - I (no sin/cos rounding).
Eigen::Matrix3d exact_half_turn(const Eigen::Vector3d& a) {
  return 2.0 * a * a.transpose() - Eigen::Matrix3d::Identity();
}

TEST(So3Hat, GivenVectorsWhenHatAppliedThenItIsTheCrossProductAndVeeInvertsIt) {
  const Eigen::Vector3d w(0.3, -1.2, 2.5);
  const Eigen::Vector3d v(-0.7, 0.1, 4.0);
  EXPECT_LT((hat(w) * v - w.cross(v)).norm(), 1e-15);
  EXPECT_EQ(vee(hat(w)), w);
  EXPECT_EQ(hat(w).transpose(), -hat(w));
}

TEST(So3Exp, GivenAxisAngleWhenExponentiatedThenMatchesEigenAngleAxis) {
  for (const Eigen::Vector3d& a : test_axes()) {
    for (double t : kHardAngles) {
      const Eigen::Matrix3d R = so3_exp(t * a);
      const Eigen::Matrix3d expected = Eigen::AngleAxisd(t, a).toRotationMatrix();
      EXPECT_LT((R - expected).norm(), 1e-14) << "t=" << t << " a=" << a.transpose();
      EXPECT_TRUE(is_rotation(R, 1e-14));
    }
  }
}

TEST(So3Exp, GivenGeneratorWhenExponentiatedThenMatchesMatrixExponential) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> angle(0.0, kPi);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d w = angle(rng) * random_unit(rng);
    const Eigen::Matrix3d K = hat(w);
    const Eigen::Matrix3d expected = K.exp();
    EXPECT_LT((so3_exp(w) - expected).norm(), 1e-13);
  }
}

TEST(So3Log, GivenHardAnglesWhenLogThenExpOfLogIsTheSameRotation) {
  for (const Eigen::Vector3d& a : test_axes()) {
    for (double t : kHardAngles) {
      const Eigen::Matrix3d R = Eigen::AngleAxisd(t, a).toRotationMatrix();
      const Eigen::Vector3d w = so3_log(R);
      EXPECT_LE(w.norm(), kPi + 1e-15);
      EXPECT_LT((so3_exp(w) - R).norm(), 1e-12) << "t=" << t << " a=" << a.transpose();
    }
  }
}

TEST(So3Log, GivenExactHalfTurnWhenLogThenAngleIsPiAndAxisIsPlusOrMinusTheAxis) {
  for (const Eigen::Vector3d& a : test_axes()) {
    const Eigen::Matrix3d R = exact_half_turn(a);
    const Eigen::Vector3d w = so3_log(R);
    EXPECT_NEAR(w.norm(), kPi, 1e-15);
    // At exactly pi, w and -w are the same rotation.
    EXPECT_LT(std::min((w - kPi * a).norm(), (w + kPi * a).norm()), 1e-14) << "a=" << a.transpose();
    EXPECT_LT((so3_exp(w) - R).norm(), 1e-12);
    // The documented choice between w and -w: the largest-magnitude component is positive.
    int k = 0;
    w.cwiseAbs().maxCoeff(&k);
    EXPECT_GT(w(k), 0.0) << "a=" << a.transpose();
  }
}

TEST(So3Log, GivenRotationVectorBelowPiWhenLogOfExpThenTheSameVector) {
  for (const Eigen::Vector3d& a : test_axes()) {
    for (double t : kHardAngles) {
      if (t >= kPi) continue;
      const Eigen::Vector3d w = t * a;
      const Eigen::Vector3d back = so3_log(so3_exp(w));
      // Relative accuracy is what matters at t = 1e-12; absolute near pi.
      EXPECT_LT((back - w).norm(), 1e-15 + 1e-14 * t) << "t=" << t << " a=" << a.transpose();
    }
  }
}

TEST(So3Log, GivenNearHalfTurnWhenLogThenSignFollowsTheSkewPart) {
  // pi - 1e-9 about a and about -a are different rotations; the log must not confuse them.
  const Eigen::Vector3d a = Eigen::Vector3d(0.2, -0.5, 0.8).normalized();
  const double t = kPi - 1e-9;
  EXPECT_LT((so3_log(so3_exp(t * a)) - t * a).norm(), 1e-14);
  EXPECT_LT((so3_log(so3_exp(-t * a)) + t * a).norm(), 1e-14);
}

TEST(So3Log, GivenSeededRandomRotationsWhenLogThenMatchesEigenAngleAxisAndRoundTrips) {
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> angle(0.0, kPi);
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3d w = angle(rng) * random_unit(rng);
    const Eigen::Matrix3d R = so3_exp(w);
    const Eigen::Vector3d back = so3_log(R);
    EXPECT_LT((back - w).norm(), 1e-12);
    EXPECT_LT((so3_exp(back) - R).norm(), 1e-12);
    const Eigen::AngleAxisd aa(R);
    EXPECT_LT((back - aa.angle() * aa.axis()).norm(), 1e-10);
  }
}

TEST(So3Log, GivenIdentityWhenLogThenZero) {
  EXPECT_EQ(so3_log(Eigen::Matrix3d::Identity()), Eigen::Vector3d::Zero());
}

// d/dd log(exp(w)^T exp(w + d)) at d = 0, by central differences.
Eigen::Matrix3d numeric_right_jacobian(const Eigen::Vector3d& w) {
  const double h = 1e-6;
  Eigen::Matrix3d J;
  const Eigen::Matrix3d Rt = so3_exp(w).transpose();
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d e = h * Eigen::Vector3d::Unit(i);
    J.col(i) = (so3_log(Rt * so3_exp(w + e)) - so3_log(Rt * so3_exp(w - e))) / (2 * h);
  }
  return J;
}

// d/dd log(exp(w + d) exp(w)^T).
Eigen::Matrix3d numeric_left_jacobian(const Eigen::Vector3d& w) {
  const double h = 1e-6;
  Eigen::Matrix3d J;
  const Eigen::Matrix3d Rt = so3_exp(w).transpose();
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d e = h * Eigen::Vector3d::Unit(i);
    J.col(i) = (so3_log(so3_exp(w + e) * Rt) - so3_log(so3_exp(w - e) * Rt)) / (2 * h);
  }
  return J;
}

// d/dd log(exp(w) exp(d)).
Eigen::Matrix3d numeric_right_jacobian_inverse(const Eigen::Vector3d& w) {
  const double h = 1e-6;
  Eigen::Matrix3d J;
  const Eigen::Matrix3d R = so3_exp(w);
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d e = h * Eigen::Vector3d::Unit(i);
    J.col(i) = (so3_log(R * so3_exp(e)) - so3_log(R * so3_exp(-e))) / (2 * h);
  }
  return J;
}

TEST(So3Jacobian, GivenRotationVectorsWhenDifferentiatedNumericallyThenAnalyticJacobiansAgree) {
  std::vector<Eigen::Vector3d> ws = {Eigen::Vector3d::Zero(), Eigen::Vector3d(1e-9, -2e-9, 0.5e-9),
                                     Eigen::Vector3d(1e-4, 2e-4, -1e-4), Eigen::Vector3d(0.3, -0.2, 0.9),
                                     (kPi - 0.3) * Eigen::Vector3d(1, 2, 3).normalized()};
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> angle(0.0, kPi - 0.2);  // keep w +- h below pi
  for (int i = 0; i < 30; ++i) ws.push_back(angle(rng) * random_unit(rng));
  for (const Eigen::Vector3d& w : ws) {
    EXPECT_LT((so3_right_jacobian(w) - numeric_right_jacobian(w)).norm(), 1e-8) << w.transpose();
    EXPECT_LT((so3_left_jacobian(w) - numeric_left_jacobian(w)).norm(), 1e-8) << w.transpose();
    EXPECT_LT((so3_right_jacobian_inverse(w) - numeric_right_jacobian_inverse(w)).norm(), 1e-8)
        << w.transpose();
    EXPECT_LT((so3_right_jacobian(w) * so3_right_jacobian_inverse(w) - Eigen::Matrix3d::Identity()).norm(),
              1e-12);
    EXPECT_LT((so3_left_jacobian(w) * so3_left_jacobian_inverse(w) - Eigen::Matrix3d::Identity()).norm(),
              1e-12);
  }
}

TEST(So3Jacobian, GivenAnglesAroundTheSeriesThresholdWhenEvaluatedThenJacobiansAreContinuous) {
  // The series branch switches at 1e-3; both sides must agree to far better than the step.
  const Eigen::Vector3d a = Eigen::Vector3d(0.3, -0.4, 0.5).normalized();
  for (double t : {1e-3 * (1 - 1e-9), 1e-3 * (1 + 1e-9)}) {
    EXPECT_LT((so3_right_jacobian(t * a) - numeric_right_jacobian(t * a)).norm(), 1e-9);
    EXPECT_LT(
        (so3_right_jacobian(t * a) * so3_right_jacobian_inverse(t * a) - Eigen::Matrix3d::Identity()).norm(),
        1e-15);
  }
}

TEST(So3Jacobian, GivenHalfTurnWhenInverseEvaluatedThenFinite) {
  const Eigen::Matrix3d J = so3_right_jacobian_inverse(kPi * Eigen::Vector3d::UnitZ());
  EXPECT_TRUE(J.allFinite());
  EXPECT_LT((so3_right_jacobian(kPi * Eigen::Vector3d::UnitZ()) * J - Eigen::Matrix3d::Identity()).norm(),
            1e-12);
}

TEST(So3Interpolate, GivenConstantRateRotationWhenInterpolatedThenEqualsTheRotationAtThatTime) {
  // R(t) = R0 exp(t w): the geodesic between R(0) and R(1) is R(alpha) exactly.
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> angle(0.0, kPi - 1e-6);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Matrix3d R0 = so3_exp(angle(rng) * random_unit(rng));
    const Eigen::Vector3d w = angle(rng) * random_unit(rng);
    const Eigen::Matrix3d R1 = R0 * so3_exp(w);
    for (double alpha : {0.0, 0.1, 0.25, 0.5, 0.9, 1.0}) {
      const Eigen::Matrix3d expected = R0 * so3_exp(alpha * w);
      const Eigen::Matrix3d got = so3_interpolate(R0, R1, alpha);
      EXPECT_LT((got - expected).norm(), 1e-12) << "alpha=" << alpha;
      EXPECT_TRUE(is_rotation(got, 1e-13));
    }
  }
}

TEST(So3Interpolate, GivenLargeRotationWhenInterpolatedThenStaysOnSo3UnlikeLinearBlend) {
  // The paper's eq. (2) blends matrices linearly; at 170 deg the blend is far from a rotation.
  const Eigen::Matrix3d R0 = Eigen::Matrix3d::Identity();
  const Eigen::Matrix3d R1 = so3_exp(170.0 * kPi / 180.0 * Eigen::Vector3d::UnitZ());
  const Eigen::Matrix3d linear = 0.5 * R0 + 0.5 * R1;
  EXPECT_FALSE(is_rotation(linear, 1e-3));
  const Eigen::Matrix3d geo = so3_interpolate(R0, R1, 0.5);
  EXPECT_TRUE(is_rotation(geo, 1e-14));
  EXPECT_LT((geo - so3_exp(85.0 * kPi / 180.0 * Eigen::Vector3d::UnitZ())).norm(), 1e-14);
}

TEST(So3Quaternion, GivenRotationVectorsWhenUsingQuaternionsThenSameAsMatrices) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> angle(0.0, kPi);
  std::vector<Eigen::Vector3d> ws = {Eigen::Vector3d::Zero(), Eigen::Vector3d(1e-9, 0, 0),
                                     (kPi - 1e-9) * Eigen::Vector3d::UnitY(), kPi * Eigen::Vector3d::UnitZ()};
  for (int i = 0; i < 200; ++i) ws.push_back(angle(rng) * random_unit(rng));
  for (const Eigen::Vector3d& w : ws) {
    const Eigen::Quaterniond q = quat_exp(w);
    EXPECT_NEAR(q.norm(), 1.0, 1e-15);
    EXPECT_LT((q.toRotationMatrix() - so3_exp(w)).norm(), 1e-14);
    EXPECT_LT((quat_log(q) - w).norm(), 1e-15 + 1e-14 * w.norm());
    // Double cover: -q is the same rotation and has the same log (away from exactly pi).
    if (w.norm() < kPi - 1e-6) {
      EXPECT_LT((quat_log(Eigen::Quaterniond(-q.coeffs())) - w).norm(), 1e-13);
    }
  }
}

TEST(So3Quaternion, GivenTwoOrientationsWhenInterpolatedThenMatchesSlerpAndMatrixGeodesic) {
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<double> angle(0.0, kPi - 1e-3);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Quaterniond q0 = quat_exp(angle(rng) * random_unit(rng));
    const Eigen::Quaterniond q1 = quat_exp(angle(rng) * random_unit(rng));
    for (double alpha : {0.0, 0.3, 0.5, 1.0}) {
      const Eigen::Quaterniond q = quat_interpolate(q0, q1, alpha);
      EXPECT_LT((q.toRotationMatrix() - q0.slerp(alpha, q1).toRotationMatrix()).norm(), 1e-12);
      EXPECT_LT((q.toRotationMatrix() - so3_interpolate(q0.toRotationMatrix(), q1.toRotationMatrix(), alpha))
                    .norm(),
                1e-12);
    }
  }
}

}  // namespace
}  // namespace hwr::core
