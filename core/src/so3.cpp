#include "hwr/core/so3.hpp"

#include <algorithm>
#include <cmath>

namespace hwr::core {
namespace {

// Below this angle the closed forms lose digits to cancellation (1 - cos t, t - sin t) or divide
// 0 by 0; their Taylor series truncated after t^4 are exact to double precision there.
constexpr double kSmallAngle = 1e-4;
constexpr double kSmallAngleJacobian = 1e-3;
// Beyond this cos(theta) (theta > ~154 deg) sin(theta) is too small to carry the axis; it is read
// from the symmetric part of R instead.
constexpr double kNearPiCos = -0.9;

// sin(t)/t
double sinc(double t) {
  const double t2 = t * t;
  if (t < kSmallAngle) return 1.0 - t2 / 6.0 + t2 * t2 / 120.0;
  return std::sin(t) / t;
}

// (1 - cos t)/t^2, written as 2 sin^2(t/2)/t^2 to avoid cancellation.
double one_minus_cos_over_t2(double t) {
  const double t2 = t * t;
  if (t < kSmallAngle) return 0.5 - t2 / 24.0 + t2 * t2 / 720.0;
  const double h = std::sin(0.5 * t) / t;
  return 2.0 * h * h;
}

// (t - sin t)/t^3
double t_minus_sin_over_t3(double t) {
  const double t2 = t * t;
  if (t < kSmallAngleJacobian) return 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0;
  return (t - std::sin(t)) / (t2 * t);
}

// 1/t^2 - (1 + cos t)/(2 t sin t) = 1/t^2 - cot(t/2)/(2t); the cot form stays finite at t = pi.
double jacobian_inverse_coeff(double t) {
  const double t2 = t * t;
  if (t < kSmallAngleJacobian) return 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0;
  const double half = 0.5 * t;
  return 1.0 / t2 - std::cos(half) / (2.0 * t * std::sin(half));
}

}  // namespace

Eigen::Matrix3d hat(const Eigen::Vector3d& w) {
  Eigen::Matrix3d K;
  K << 0.0, -w.z(), w.y(),  //
      w.z(), 0.0, -w.x(),   //
      -w.y(), w.x(), 0.0;
  return K;
}

Eigen::Vector3d vee(const Eigen::Matrix3d& M) {
  return 0.5 * Eigen::Vector3d(M(2, 1) - M(1, 2), M(0, 2) - M(2, 0), M(1, 0) - M(0, 1));
}

Eigen::Matrix3d so3_exp(const Eigen::Vector3d& omega) {
  const double t = omega.norm();
  const Eigen::Matrix3d K = hat(omega);
  return Eigen::Matrix3d::Identity() + sinc(t) * K + one_minus_cos_over_t2(t) * (K * K);
}

Eigen::Vector3d so3_log(const Eigen::Matrix3d& R) {
  // R = cos(t) I + sin(t) [a]x + (1 - cos(t)) a a^T: the trace gives cos(t), the skew part
  // sin(t) a, the symmetric part (1 - cos(t)) a a^T + cos(t) I.
  const double c = std::clamp(0.5 * (R.trace() - 1.0), -1.0, 1.0);
  const Eigen::Vector3d s_axis = vee(R);  // sin(t) * a
  const double s = s_axis.norm();
  const double t = std::atan2(s, c);  // accurate at both ends, unlike acos(c) or asin(s)

  if (c > kNearPiCos) {
    // t / sin(t) with its series 1 + t^2/6 + 7 t^4/360 near 0.
    const double t2 = t * t;
    const double k = t < kSmallAngle ? 1.0 + t2 / 6.0 + 7.0 * t2 * t2 / 360.0 : t / s;
    return k * s_axis;
  }

  // Near pi: (R + R^T)/2 - c I = (1 - c) a a^T. The column of the largest diagonal entry is the
  // best conditioned multiple of a.
  const Eigen::Matrix3d S = 0.5 * (R + R.transpose()) - c * Eigen::Matrix3d::Identity();
  int i = 0;
  S.diagonal().maxCoeff(&i);
  Eigen::Vector3d a = S.col(i).normalized();
  // The skew part still fixes the sign whenever sin(t) is not exactly 0.
  if (a.dot(s_axis) < 0.0) a = -a;
  return t * a;
}

Eigen::Matrix3d so3_right_jacobian(const Eigen::Vector3d& omega) {
  const double t = omega.norm();
  const Eigen::Matrix3d K = hat(omega);
  return Eigen::Matrix3d::Identity() - one_minus_cos_over_t2(t) * K + t_minus_sin_over_t3(t) * (K * K);
}

Eigen::Matrix3d so3_right_jacobian_inverse(const Eigen::Vector3d& omega) {
  const double t = omega.norm();
  const Eigen::Matrix3d K = hat(omega);
  return Eigen::Matrix3d::Identity() + 0.5 * K + jacobian_inverse_coeff(t) * (K * K);
}

Eigen::Matrix3d so3_left_jacobian(const Eigen::Vector3d& omega) { return so3_right_jacobian(-omega); }

Eigen::Matrix3d so3_left_jacobian_inverse(const Eigen::Vector3d& omega) {
  return so3_right_jacobian_inverse(-omega);
}

Eigen::Matrix3d so3_interpolate(const Eigen::Matrix3d& R0, const Eigen::Matrix3d& R1, double alpha) {
  return R0 * so3_exp(alpha * so3_log(R0.transpose() * R1));
}

Eigen::Quaterniond quat_exp(const Eigen::Vector3d& omega) {
  const double t = omega.norm();
  // q = (cos(t/2), sin(t/2)/t * w); sin(t/2)/t = sinc(t/2)/2.
  const double k = 0.5 * sinc(0.5 * t);
  return Eigen::Quaterniond(std::cos(0.5 * t), k * omega.x(), k * omega.y(), k * omega.z());
}

Eigen::Vector3d quat_log(const Eigen::Quaterniond& q_in) {
  // q and -q are the same rotation; w >= 0 picks |t| <= pi.
  const double sign = q_in.w() < 0.0 ? -1.0 : 1.0;
  const double w = sign * q_in.w();
  const Eigen::Vector3d v = sign * q_in.vec();
  const double n = v.norm();  // sin(t/2)
  if (n < kSmallAngle) {
    // 2 atan(n/w)/n = (2/w)(1 - n^2/(3 w^2) + n^4/(5 w^4)); w ~ 1 here.
    const double r2 = (n * n) / (w * w);
    return (2.0 / w) * (1.0 - r2 / 3.0 + r2 * r2 / 5.0) * v;
  }
  return (2.0 * std::atan2(n, w) / n) * v;
}

Eigen::Quaterniond quat_interpolate(const Eigen::Quaterniond& q0, const Eigen::Quaterniond& q1,
                                    double alpha) {
  Eigen::Quaterniond q = q0 * quat_exp(alpha * quat_log(q0.conjugate() * q1));
  q.normalize();
  return q;
}

}  // namespace hwr::core
