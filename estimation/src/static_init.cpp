#include "hwr/estimation/static_init.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "hwr/core/time.hpp"

namespace hwr::estimation {
namespace {

size_t ring_capacity(double window_s, double rate_hz) {
  const double n = std::ceil(std::max(window_s, 0.0) * std::max(rate_hz, 1.0));
  return static_cast<size_t>(n) + 2;
}

std::string vec_text(const Eigen::Vector3d& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.4g, %.4g, %.4g)", v.x(), v.y(), v.z());
  return buf;
}

}  // namespace

StaticInitializer::StaticInitializer(const StaticInitConfig& config)
    : config_(config),
      imu_(ring_capacity(config.window_s, config.max_imu_rate_hz)),
      mag_(ring_capacity(config.window_s, config.max_mag_rate_hz)) {}

void StaticInitializer::reset() {
  imu_head_ = imu_count_ = 0;
  mag_head_ = mag_count_ = 0;
  rejected_ = 0;
  diag_ = StaticInitDiagnostics{};
}

void StaticInitializer::add_imu(const hal::ImuSample& sample) {
  const size_t cap = imu_.size();
  const bool finite = sample.gyro_radps.allFinite() && sample.accel_mps2.allFinite();
  if (!finite || (imu_count_ > 0 && sample.t_ns <= imu_[(imu_head_ + imu_count_ - 1) % cap].t_ns)) {
    ++rejected_;
    return;
  }
  if (imu_count_ == cap) {  // faster than max_imu_rate_hz: drop the oldest (window never full)
    imu_head_ = (imu_head_ + 1) % cap;
    --imu_count_;
  }
  imu_[(imu_head_ + imu_count_) % cap] = sample;
  ++imu_count_;
  // Keep the shortest suffix that still spans window_s: drop the oldest while the second oldest
  // is already window_s older than the newest.
  const int64_t window_ns = core::s_to_ns(config_.window_s);
  while (imu_count_ >= 2 && sample.t_ns - imu_[(imu_head_ + 1) % cap].t_ns >= window_ns) {
    imu_head_ = (imu_head_ + 1) % cap;
    --imu_count_;
  }
  evaluate_window();
}

void StaticInitializer::add_mag(const hal::MagSample& sample) {
  const size_t cap = mag_.size();
  if (!sample.field_uT.allFinite() ||
      (mag_count_ > 0 && sample.t_ns <= mag_[(mag_head_ + mag_count_ - 1) % cap].t_ns)) {
    ++rejected_;
    return;
  }
  if (mag_count_ == cap) {
    mag_head_ = (mag_head_ + 1) % cap;
    --mag_count_;
  }
  mag_[(mag_head_ + mag_count_) % cap] = sample;
  ++mag_count_;
  evaluate_window();
}

void StaticInitializer::evaluate_window() {
  const size_t cap = imu_.size();
  StaticInitDiagnostics d;
  d.imu_samples = imu_count_;
  if (imu_count_ == 0) {
    diag_ = d;
    return;
  }
  const int64_t t_first = imu_[imu_head_].t_ns;
  const int64_t t_last = imu_[(imu_head_ + imu_count_ - 1) % cap].t_ns;
  d.window_span_s = core::ns_to_s(t_last - t_first);
  d.window_full = t_last - t_first >= core::s_to_ns(config_.window_s);

  // Two-pass mean and (population) standard deviation per axis.
  for (size_t i = 0; i < imu_count_; ++i) {
    const hal::ImuSample& s = imu_[(imu_head_ + i) % cap];
    d.gyro_mean_radps += s.gyro_radps;
    d.accel_mean_mps2 += s.accel_mps2;
  }
  const double n = static_cast<double>(imu_count_);
  d.gyro_mean_radps /= n;
  d.accel_mean_mps2 /= n;
  Eigen::Vector3d var_g = Eigen::Vector3d::Zero(), var_a = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < imu_count_; ++i) {
    const hal::ImuSample& s = imu_[(imu_head_ + i) % cap];
    var_g += (s.gyro_radps - d.gyro_mean_radps).cwiseAbs2();
    var_a += (s.accel_mps2 - d.accel_mean_mps2).cwiseAbs2();
  }
  d.gyro_std_radps = (var_g / n).cwiseSqrt();
  d.accel_std_mps2 = (var_a / n).cwiseSqrt();
  d.accel_norm_mps2 = d.accel_mean_mps2.norm();
  d.stationary = d.window_full && d.gyro_std_radps.maxCoeff() <= config_.max_gyro_std_radps &&
                 d.accel_std_mps2.maxCoeff() <= config_.max_accel_std_mps2 &&
                 (d.accel_mean_mps2 - config_.accel_bias_mps2).norm() > 0.5 * config_.gravity_mps2;

  // Magnetometer samples inside the IMU window's time span.
  const size_t mcap = mag_.size();
  Eigen::Vector3d m_imu = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < mag_count_; ++i) {
    const hal::MagSample& m = mag_[(mag_head_ + i) % mcap];
    if (m.t_ns < t_first || m.t_ns > t_last) continue;
    m_imu += m.field_uT;
    ++d.mag_samples;
  }
  diag_ = d;
  if (d.mag_samples > 0 && (d.accel_mean_mps2 - config_.accel_bias_mps2).norm() > 0.0) {
    m_imu /= static_cast<double>(d.mag_samples);
    // Tilt compensation: the field in the yaw-0 world frame; its horizontal part points to
    // magnetic north, at heading psi_N from world x (= the IMU x axis's projection).
    const Eigen::Vector3d m_world = gravity_aligned_R_world_imu() * m_imu;
    if (std::hypot(m_world.x(), m_world.y()) > 1e-9) {
      diag_.has_yaw_from_mag = true;
      diag_.yaw_from_mag_rad = -std::atan2(m_world.y(), m_world.x());
    }
  }
}

Eigen::Matrix3d StaticInitializer::gravity_aligned_R_world_imu() const {
  // World z (up) in IMU axes: at rest the accelerometer measures R^T (0, 0, g) + b_a.
  const Eigen::Vector3d z_w = (diag_.accel_mean_mps2 - config_.accel_bias_mps2).normalized();
  // World x: the IMU x axis projected on the horizontal plane (hal/sim/world_frame.hpp); when x is
  // (nearly) vertical, the y axis's projection turned by -90 deg about z.
  const Eigen::Vector3d x_proj = Eigen::Vector3d::UnitX() - z_w.x() * z_w;
  Eigen::Vector3d x_w, y_w;
  if (x_proj.norm() > 1e-9) {
    x_w = x_proj.normalized();
    y_w = z_w.cross(x_w);
  } else {
    y_w = (Eigen::Vector3d::UnitY() - z_w.y() * z_w).normalized();
    x_w = y_w.cross(z_w);
  }
  Eigen::Matrix3d R_imu_world;  // columns: the world axes in IMU coordinates
  R_imu_world.col(0) = x_w;
  R_imu_world.col(1) = y_w;
  R_imu_world.col(2) = z_w;
  return R_imu_world.transpose();
}

core::Expected<NavState> StaticInitializer::result() const {
  const StaticInitDiagnostics& d = diag_;
  if (!d.window_full) {
    char buf[160];
    std::snprintf(buf, sizeof buf,
                  "static init: the IMU window spans %.3f s of the %.3f s needed (%zu samples)",
                  d.window_span_s, config_.window_s, d.imu_samples);
    return core::Unavailable(buf);
  }
  if (!d.stationary) {
    return core::Unavailable("static init: not stationary over the last " + std::to_string(config_.window_s) +
                             " s: gyro std " + vec_text(d.gyro_std_radps) + " rad/s (max " +
                             std::to_string(config_.max_gyro_std_radps) + "), accel std " +
                             vec_text(d.accel_std_mps2) + " m/s^2 (max " +
                             std::to_string(config_.max_accel_std_mps2) + "), |mean accel| " +
                             std::to_string(d.accel_norm_mps2) + " m/s^2");
  }
  NavState x;
  x.t_ns = imu_[(imu_head_ + imu_count_ - 1) % imu_.size()].t_ns;
  x.R_world_imu = gravity_aligned_R_world_imu();
  x.gyro_bias_radps = d.gyro_mean_radps;
  x.accel_bias_mps2 = config_.accel_bias_mps2;
  return x;
}

ImuMekf::Cov15 StaticInitializer::initial_covariance() const {
  using M = ImuMekf;
  M::Cov15 P = M::Cov15::Zero();
  const Eigen::Matrix3d I3 = Eigen::Matrix3d::Identity();
  // Rotation: tilt sigma from the unobservable horizontal accel bias (b / g), yaw by definition;
  // stated in world axes, then turned into the local (IMU-axes) error: dtheta_imu = R^T dtheta_w.
  const double tilt = config_.accel_bias_sigma_mps2 / config_.gravity_mps2;
  const Eigen::Vector3d var_w(tilt * tilt, tilt * tilt, config_.yaw_sigma_rad * config_.yaw_sigma_rad);
  const Eigen::Matrix3d R = diag_.window_full ? gravity_aligned_R_world_imu() : I3;
  P.block<3, 3>(M::kTheta, M::kTheta) = R.transpose() * var_w.asDiagonal() * R;
  P.block<3, 3>(M::kPos, M::kPos) = I3 * (config_.position_sigma_m * config_.position_sigma_m);
  P.block<3, 3>(M::kVel, M::kVel) = I3 * (config_.velocity_sigma_mps * config_.velocity_sigma_mps);
  // Gyro bias: the standard error of the window mean plus the floor.
  const double n = std::max<double>(1.0, static_cast<double>(diag_.imu_samples));
  const Eigen::Vector3d var_bg =
      diag_.gyro_std_radps.cwiseAbs2() / n +
      Eigen::Vector3d::Constant(config_.gyro_bias_sigma_floor_radps * config_.gyro_bias_sigma_floor_radps);
  P.block<3, 3>(M::kBg, M::kBg) = var_bg.asDiagonal();
  P.block<3, 3>(M::kBa, M::kBa) = I3 * (config_.accel_bias_sigma_mps2 * config_.accel_bias_sigma_mps2);
  return P;
}

}  // namespace hwr::estimation
