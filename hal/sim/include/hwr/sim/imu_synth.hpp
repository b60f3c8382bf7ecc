#pragma once
// Synthetic 6-axis IMU from an analytic trajectory (trajectory.hpp):
//   gyro  = omega_imu + b_g + n_g
//   accel = R_scene_imu^T (a_scene - g_scene) + b_a + n_a,   g_scene = (0, 0, -gravity)
// White noise from continuous densities, sigma_d = density * sqrt(rate); biases start at the
// configured values and random-walk by density * sqrt(dt) per step (the Kalibr / EuRoC IMU noise
// model, Furgale et al., "Unified temporal and spatial calibration", IROS 2013, and Kalibr's
// "IMU Noise Model" page).

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "hwr/hal/imu_sample.hpp"
#include "hwr/sim/trajectory.hpp"

namespace hwr::sim {

struct ImuNoiseSpec {
  // false: ideal measurements (no white noise, no random walk, zero biases).
  bool enabled = true;
  // Defaults near a MEMS IMU of the ZED 2i / Handsfree A9 class (BMI085-like datasheet values).
  double gyro_noise_density = 2.4e-4;   // rad/s/sqrt(Hz)   (0.014 deg/s/sqrt(Hz))
  double accel_noise_density = 1.6e-3;  // m/s^2/sqrt(Hz)   (160 ug/sqrt(Hz))
  double gyro_random_walk = 2.0e-5;     // rad/s^2/sqrt(Hz)
  double accel_random_walk = 3.0e-4;    // m/s^3/sqrt(Hz)
  Eigen::Vector3d gyro_bias_initial_radps{0.002, -0.0015, 0.001};
  Eigen::Vector3d accel_bias_initial_mps2{0.03, -0.02, 0.04};
};

struct ImuSpec {
  double rate_hz = 200.0;
  double gravity_mps2 = 9.81;
  ImuNoiseSpec noise;
};

// One synthesized sample with the biases that were in effect.
struct ImuRecord {
  hal::ImuSample sample;  // t_ns = run start + offset
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();
};

// Noise-free, bias-free measurement of a state (the oracle of the integration tests).
hal::ImuSample ideal_imu(const TrajectoryState& state, double gravity_mps2);

// Samples at sample_offsets_ns(rate_hz, duration_s) (sample_times.hpp); t_ns = t0_ns + offset.
// Deterministic in seed; a shorter duration gives a prefix of a longer one.
std::vector<ImuRecord> synthesize_imu(const Trajectory& trajectory, const ImuSpec& spec, uint64_t seed,
                                      double duration_s, int64_t t0_ns);

}  // namespace hwr::sim
