#pragma once
// The navigation state of the IMU: the paper's S_t = [R_t T_t V_t b_t] (paper.md item 2), with the
// bias split into gyro and accelerometer parts. World frame: the run's gravity-aligned first IMU
// frame (docs/architecture.md "Frames and time"), z up, gravity (0, 0, -g).

#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hwr::estimation {

struct NavState {
  int64_t t_ns = 0;
  Eigen::Matrix3d R_world_imu = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_world_imu_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_world_mps = Eigen::Vector3d::Zero();      // velocity of the IMU origin, world axes
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();  // IMU axes: gyro = omega + b_g
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();  // IMU axes: accel = f + b_a

  Eigen::Isometry3d T_world_imu() const {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R_world_imu;
    T.translation() = p_world_imu_m;
    return T;
  }
};

}  // namespace hwr::estimation
