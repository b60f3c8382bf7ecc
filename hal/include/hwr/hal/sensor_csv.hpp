#pragma once
// Readers for the per-sensor CSV logs of EuRoC (ASL format) and of our own recorder/simulator,
// which writes the same layouts. Each file has a '#' header line, one row per sample, the first
// column an integer timestamp in nanoseconds that strictly increases. Reading is strict: a wrong
// column count, a field that is not a number, or a timestamp that does not increase is an error
// naming file and line, e.g. "imu0/data.csv:17: expected 7 comma-separated fields (...), got 6".
//
//   imu.csv   #timestamp [ns],w_x [rad s^-1],w_y,w_z,a_x [m s^-2],a_y,a_z          (EuRoC imu0)
//   mag.csv   #timestamp [ns],m_x [uT],m_y [uT],m_z [uT]
//   gnss.csv  #timestamp [ns],lat [deg],lon [deg],height [m],h_acc [m],v_acc [m],fix_type,num_sv
//             (rows with fix_type 0 may write nan for the five real-valued fields)
//   state     #timestamp [ns],p_x,p_y,p_z,q_w,q_x,q_y,q_z,v_x,v_y,v_z,bw_x,bw_y,bw_z,ba_x,ba_y,ba_z
//             (EuRoC state_groundtruth_estimate0: p_RS_R, q_RS, v_RS_R, b_w_RS_S, b_a_RS_S)

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/hal/gnss_fix.hpp"
#include "hwr/hal/imu_sample.hpp"
#include "hwr/hal/mag_sample.hpp"

namespace hwr::hal {

// One row of EuRoC's state ground truth: the IMU body pose in the world (Vicon) frame, its
// velocity, and the IMU biases. The quaternion is normalised on load.
struct EurocState {
  int64_t t_ns = 0;
  Eigen::Vector3d p_world_body = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_world_body = Eigen::Quaterniond::Identity();
  Eigen::Vector3d v_world_body_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();

  Eigen::Isometry3d T_world_body() const {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = q_world_body.toRotationMatrix();
    T.translation() = p_world_body;
    return T;
  }
};

core::Expected<std::vector<ImuSample>> read_imu_csv(const std::string& path);
core::Expected<std::vector<MagSample>> read_mag_csv(const std::string& path);
// fix_type must be 0..5 (u-blox NAV-PVT) and num_sv 0..255; positions and accuracies must be
// finite unless fix_type is 0.
core::Expected<std::vector<GnssFix>> read_gnss_csv(const std::string& path);
// Quaternion norms must be within 1e-2 of 1.
core::Expected<std::vector<EurocState>> read_euroc_state_csv(const std::string& path);

}  // namespace hwr::hal
