#pragma once
// The robot's sensor set-up for `hwr-robot --source hw:CONFIG` (config/hw.yaml is the annotated
// template). Strict YAML (core/config.hpp): an unknown key, a wrong type or an impossible value is an
// error naming the file, line and key. Devices and USB ids: ../shared/hardware.md.

#include <string>

#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/hal/stereo_depth.hpp"

namespace hwr::hal::hw {

// ZED 2i video over V4L2; depth from the rectified pair (hal::StereoDepth, OpenCV SGBM).
struct ZedCameraConfig {
  bool enabled = true;
  std::string device = "auto";  // a /dev/videoN path, or "auto": the node of USB 2b03:f880 in sysfs
  int eye_width = 1280;         // per eye: 2208x1242@15, 1920x1080@15/30, 1280x720@15/30/60,
  int eye_height = 720;         //          672x376@15/30/60/100 (hardware.md)
  int fps = 30;
  std::string calibration;  // the camera's SN<serial>.conf (required when enabled)
  int buffers = 4;          // V4L2 mmap buffers requested
  StereoSgbmParams sgbm;    // disparity search: see the sgbm: keys in config/hw.yaml
};

// Which inertial sensor feeds the estimator.
enum class ImuKind { kZed, kA9 };

struct HwConfig {
  ZedCameraConfig camera;
  bool zed_sensors = true;  // ZED 2i IMU / magnetometer over USB HID (2b03:f881); frame sync
  ImuKind imu = ImuKind::kZed;
  bool a9_enabled = false;  // Handsfree A9 over USB serial
  std::string a9_device = "/dev/hwr-a9";
  int a9_baud = 921600;
  bool gnss_enabled = false;  // u-blox M8T
  std::string gnss_device = "/dev/hwr-gnss";
  int gnss_baud = 115200;
  double gnss_rate_hz = 10;    // CFG-RATE sent at start (1..10 Hz on the M8T)
  bool gnss_configure = true;  // send CFG-RATE and CFG-MSG (NAV-PVT on) and wait for their ACKs

  // Extrinsics (T_a_b maps points from b to a): the left camera in the IMU frame that feeds the
  // estimator, the GNSS antenna's phase centre in that IMU frame, the magnetometer's hard iron.
  Eigen::Isometry3d T_imu_cam = Eigen::Isometry3d::Identity();
  Eigen::Vector3d gnss_antenna_imu_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d mag_hard_iron_uT = Eigen::Vector3d::Zero();

  std::string sysfs_root = "/sys";  // where "auto" looks for the video node (tests use a fake tree)
};

core::Expected<HwConfig> parse_hw_config(const std::string& yaml_text, const std::string& source_name);
core::Expected<HwConfig> load_hw_config(const std::string& path);

}  // namespace hwr::hal::hw
