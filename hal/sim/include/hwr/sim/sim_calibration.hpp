#pragma once
// calibration.yaml of a simulated run: everything a consumer (replay, estimator, evaluation)
// needs to interpret the files: camera intrinsics and depth scale, rates, the camera-IMU
// extrinsic, IMU noise densities, the magnetic field, the GNSS geodetic origin and antenna, and
// T_scene_world (which places this run's world frame in the scene, so revisits have exact
// relative ground truth). Loading is strict (core::ConfigDocument): unknown or missing keys and
// wrong types are errors naming file:line and the key.

#include <cstdint>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hwr/core/geodetic.hpp"
#include "hwr/core/status.hpp"
#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::sim {

struct ScenarioSpec;

struct SimCalibration {
  std::string scenario;
  uint64_t seed = 0;
  int64_t start_time_ns = 0;

  hal::PinholeIntrinsics intrinsics;
  double camera_rate_hz = 0.0;
  double depth_scale = 0.0;  // raw 16-bit units per metre
  Eigen::Isometry3d T_imu_cam = Eigen::Isometry3d::Identity();
  bool stereo = false;
  double baseline_m = 0.0;  // right camera at +baseline along x_cam

  double imu_rate_hz = 0.0;
  double gravity_mps2 = 0.0;
  bool imu_noise_enabled = false;
  double gyro_noise_density = 0.0;   // rad/s/sqrt(Hz)
  double accel_noise_density = 0.0;  // m/s^2/sqrt(Hz)
  double gyro_random_walk = 0.0;     // rad/s^2/sqrt(Hz)
  double accel_random_walk = 0.0;    // m/s^3/sqrt(Hz)

  bool mag_enabled = false;
  double mag_rate_hz = 0.0;
  Eigen::Vector3d mag_field_scene_uT = Eigen::Vector3d::Zero();  // Earth field, ENU
  Eigen::Vector3d mag_field_world_uT = Eigen::Vector3d::Zero();  // same, in the world frame
  Eigen::Vector3d mag_hard_iron_uT = Eigen::Vector3d::Zero();
  double mag_noise_sigma_uT = 0.0;

  bool gnss_enabled = false;
  double gnss_rate_hz = 0.0;
  core::Geodetic gnss_origin;  // WGS-84 position of the scene origin (ENU frame)
  Eigen::Vector3d gnss_antenna_imu_m = Eigen::Vector3d::Zero();
  double gnss_sigma_h_m = 0.0;
  double gnss_sigma_v_m = 0.0;

  Eigen::Isometry3d T_scene_world = Eigen::Isometry3d::Identity();
};

SimCalibration make_sim_calibration(const ScenarioSpec& spec, const Eigen::Isometry3d& T_scene_world);

// Writes YAML (poses as 4x4 row-major lists of 16 numbers, shortest exact decimal text).
std::string sim_calibration_to_yaml(const SimCalibration& calib);
core::Status save_sim_calibration(const std::string& path, const SimCalibration& calib);
core::Expected<SimCalibration> parse_sim_calibration(const std::string& yaml_text,
                                                     const std::string& source_name);
core::Expected<SimCalibration> load_sim_calibration(const std::string& path);

}  // namespace hwr::sim
