#pragma once
// Static initialisation of the MEKF (paper.md item 2: the world frame is the first IMU frame;
// docs/architecture.md: made gravity-aligned). IMU samples (and optionally magnetometer samples)
// are kept over a sliding window; once the newest window_s seconds are stationary (per-axis
// standard deviation of gyro and accel under the thresholds) the initial NavState is:
//
//  - R_world_imu from the mean specific force f (at rest f = R^T (0, 0, g) + b_a): world z = f/|f|
//    in IMU axes, world x = the IMU x axis projected on the horizontal (yaw 0; the IMU y axis,
//    turned by -90 deg, when x is vertical), exactly hal/sim/world_frame.hpp's convention, so
//    estimates and simulated ground truth share the world frame.
//  - p = 0, v = 0, t_ns = the newest sample's time.
//  - gyro bias = mean gyro (the Earth rate, <= 7.3e-5 rad/s, is absorbed into it).
//  - accel bias = config.accel_bias_mps2 (default 0). From one static attitude the accelerometer
//    bias is not observable apart from gravity: its component along gravity changes |f| only, the
//    horizontal part is indistinguishable from a tilt of |b_a,horizontal| / g rad. That tilt error
//    is the floor of this method; P0 states it (tilt sigma = accel_bias_sigma / g).
//  - yaw_from_mag_rad (diagnostics, only with magnetometer samples in the window): the heading of
//    the IMU x axis w.r.t. magnetic north, tilt-compensated with the roll/pitch above: the angle
//    about world z (up), counter-clockwise positive, from the horizontal magnetic field to the IMU
//    x axis's horizontal projection (facing magnetic west: +pi/2; compass heading = -yaw). Not
//    hard-iron compensated. The world frame stays yaw 0; relocalization uses this (paper.md item
//    11). ENU check: with true north along ENU +y and no declination, the ENU heading (from east,
//    counter-clockwise) of the IMU x axis is yaw_from_mag_rad + pi/2.
//
// add_imu()/add_mag() are allocation-free: the windows are rings sized at construction from
// max_imu_rate_hz / max_mag_rate_hz.

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "hwr/core/status.hpp"
#include "hwr/estimation/imu_mekf.hpp"
#include "hwr/estimation/nav_state.hpp"
#include "hwr/hal/imu_sample.hpp"
#include "hwr/hal/mag_sample.hpp"

namespace hwr::estimation {

struct StaticInitConfig {
  double window_s = 1.0;
  // Per axis. EuRoC V1_01 standing with idling rotors exceeds 0.01 rad/s and 0.1 m/s^2.
  double max_gyro_std_radps = 0.02;
  double max_accel_std_mps2 = 0.3;
  double gravity_mps2 = 9.81;
  // Ring capacities: the window holds window_s * rate + 2 samples at these rates at most.
  double max_imu_rate_hz = 1000.0;
  double max_mag_rate_hz = 200.0;
  // Known accelerometer bias (calibration), subtracted from the mean specific force; 0 = unknown.
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();
  // P0: the accel bias prior (also sets the tilt sigma, bias / g), the yaw sigma (yaw is 0 by the
  // world frame's definition, so tiny), position and velocity sigmas, a floor on the gyro bias
  // sigma (Earth rate, bias drift).
  double accel_bias_sigma_mps2 = 0.1;
  double yaw_sigma_rad = 1e-4;
  double position_sigma_m = 1e-3;
  double velocity_sigma_mps = 0.01;
  double gyro_bias_sigma_floor_radps = 2e-4;
};

struct StaticInitDiagnostics {
  size_t imu_samples = 0;    // in the current window
  double window_span_s = 0;  // newest minus oldest sample time in the window
  bool window_full = false;  // span >= window_s
  bool stationary = false;   // window_full and both std thresholds met
  Eigen::Vector3d gyro_mean_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_std_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_mean_mps2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_std_mps2 = Eigen::Vector3d::Zero();
  double accel_norm_mps2 = 0;  // |mean specific force|; minus g shows the bias along gravity
  size_t mag_samples = 0;      // magnetometer samples within the IMU window's time span
  bool has_yaw_from_mag = false;
  double yaw_from_mag_rad = 0;
};

class StaticInitializer {
 public:
  explicit StaticInitializer(const StaticInitConfig& config = {});

  // Samples must come in time order; a non-finite or non-increasing sample is ignored and counted.
  void add_imu(const hal::ImuSample& sample);
  void add_mag(const hal::MagSample& sample);
  void reset();

  // The newest window spans window_s and is stationary.
  bool ready() const { return diag_.stationary; }
  // The initial state (see the header comment); Unavailable with the reason while not ready.
  core::Expected<NavState> result() const;
  // P0 for ImuMekf::initialize, in its error-state order and local rotation error.
  ImuMekf::Cov15 initial_covariance() const;
  const StaticInitDiagnostics& diagnostics() const { return diag_; }
  uint64_t rejected_samples() const { return rejected_; }
  const StaticInitConfig& config() const { return config_; }

 private:
  void evaluate_window();
  Eigen::Matrix3d gravity_aligned_R_world_imu() const;

  StaticInitConfig config_;
  std::vector<hal::ImuSample> imu_;  // ring, capacity fixed at construction
  size_t imu_head_ = 0, imu_count_ = 0;
  std::vector<hal::MagSample> mag_;
  size_t mag_head_ = 0, mag_count_ = 0;
  uint64_t rejected_ = 0;
  StaticInitDiagnostics diag_;
};

}  // namespace hwr::estimation
