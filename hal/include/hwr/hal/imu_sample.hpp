#pragma once
// One inertial sample in the IMU body frame (SI units: rad/s, m/s^2). Accelerometers measure
// specific force: at rest, level, z up, accel_mps2 = (0, 0, +9.81).

#include <cstdint>

#include <Eigen/Core>

namespace hwr::hal {

struct ImuSample {
  int64_t t_ns = 0;
  Eigen::Vector3d gyro_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_mps2 = Eigen::Vector3d::Zero();
};

}  // namespace hwr::hal
