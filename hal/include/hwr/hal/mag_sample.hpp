#pragma once
// One magnetometer sample in the IMU body frame, microtesla.

#include <cstdint>

#include <Eigen/Core>

namespace hwr::hal {

struct MagSample {
  int64_t t_ns = 0;
  Eigen::Vector3d field_uT = Eigen::Vector3d::Zero();
};

}  // namespace hwr::hal
