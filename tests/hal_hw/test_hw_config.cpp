// hw:CONFIG parsing: the shipped template is valid and says what it says; impossible set-ups are
// refused with the key and the reason.
#include "hwr/hal/hw/hw_config.hpp"

#include <gtest/gtest.h>

#include <string>

using hwr::hal::hw::HwConfig;
using hwr::hal::hw::ImuKind;
using hwr::hal::hw::load_hw_config;
using hwr::hal::hw::parse_hw_config;

TEST(HwConfig, ShippedTemplateParses) {
  auto c = load_hw_config(std::string(HWR_SOURCE_DIR) + "/config/hw.yaml");
  ASSERT_TRUE(c.ok()) << c.status().message();
  EXPECT_TRUE(c->camera.enabled);
  EXPECT_EQ(c->camera.device, "auto");
  EXPECT_EQ(c->camera.eye_width, 1280);
  EXPECT_EQ(c->camera.eye_height, 720);
  EXPECT_EQ(c->camera.fps, 30);
  EXPECT_EQ(c->camera.sgbm.num_disparities, 128);
  EXPECT_EQ(c->camera.sgbm.p2, 800);
  EXPECT_DOUBLE_EQ(c->camera.sgbm.min_depth_m, 0.3);
  EXPECT_EQ(c->imu, ImuKind::kZed);
  EXPECT_TRUE(c->zed_sensors);
  EXPECT_FALSE(c->a9_enabled);
  EXPECT_EQ(c->a9_baud, 921600);
  EXPECT_FALSE(c->gnss_enabled);
  EXPECT_DOUBLE_EQ(c->gnss_rate_hz, 10.0);
  EXPECT_TRUE(c->T_imu_cam.isApprox(Eigen::Isometry3d::Identity()));
}

TEST(HwConfig, DefaultsWhenOnlyTheCalibrationIsGiven) {
  auto c = parse_hw_config("camera: {calibration: SN1.conf}\n", "t.yaml");
  ASSERT_TRUE(c.ok()) << c.status().message();
  EXPECT_EQ(c->camera.calibration, "SN1.conf");
  EXPECT_EQ(c->camera.buffers, 4);
  EXPECT_EQ(c->sysfs_root, "/sys");
}

TEST(HwConfig, ReadsTheA9AndGnssAndExtrinsics) {
  const std::string y =
      "imu: a9\n"
      "camera: {enabled: false}\n"
      "zed_sensors: {enabled: false}\n"
      "a9: {enabled: true, device: /dev/ttyUSB3, baud: 921600}\n"
      "gnss: {enabled: true, device: /dev/ttyACM0, rate_hz: 5, configure: false}\n"
      "extrinsics:\n"
      "  T_imu_cam: [0, 0, 1, 0.1,  -1, 0, 0, 0.2,  0, -1, 0, 0.3,  0, 0, 0, 1]\n"
      "  gnss_antenna_imu_m: [0.0, 0.1, 0.5]\n";
  auto c = parse_hw_config(y, "t.yaml");
  ASSERT_TRUE(c.ok()) << c.status().message();
  EXPECT_EQ(c->imu, ImuKind::kA9);
  EXPECT_EQ(c->a9_device, "/dev/ttyUSB3");
  EXPECT_EQ(c->gnss_device, "/dev/ttyACM0");
  EXPECT_DOUBLE_EQ(c->gnss_rate_hz, 5.0);
  EXPECT_FALSE(c->gnss_configure);
  // The camera's z (optical axis) is the IMU's x: column 2 of the rotation.
  EXPECT_TRUE(c->T_imu_cam.linear().col(2).isApprox(Eigen::Vector3d(1, 0, 0)));
  EXPECT_TRUE(c->T_imu_cam.translation().isApprox(Eigen::Vector3d(0.1, 0.2, 0.3)));
  EXPECT_TRUE(c->gnss_antenna_imu_m.isApprox(Eigen::Vector3d(0, 0.1, 0.5)));
}

struct BadCase {
  const char* yaml;
  const char* message_part;
};

TEST(HwConfig, RefusesImpossibleSetUpsNamingTheKey) {
  const BadCase cases[] = {
      {"camera: {eye_width: 1280, eye_height: 720, fps: 100, calibration: a}\n", "no mode 1280x720@100"},
      {"camera: {eye_width: 640, eye_height: 480, calibration: a}\n", "camera.eye_width"},
      {"camera: {enabled: true}\n", "calibration"},
      {"camera: {calibration: a, buffers: 1}\n", "camera.buffers"},
      {"camera: {calibration: a}\nimu: xsens\n", "'xsens'"},
      {"camera: {calibration: a}\nimu: a9\n", "a9.enabled is false"},
      {"camera: {calibration: a}\nzed_sensors: {enabled: false}\n", "zed_sensors.enabled is false"},
      {"camera: {calibration: a}\ngnss: {rate_hz: 20}\n", "gnss.rate_hz"},
      {"camera: {calibration: a}\nextrinsics: {T_imu_cam: [1, 0, 0]}\n", "16 numbers"},
      {"camera: {calibration: a}\nextrinsics: {T_imu_cam: [2,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]}\n",
       "extrinsics.T_imu_cam"},
      {"camera: {calibration: a, sgbm: {blocksize: 5}}\n", "camera.sgbm.blocksize"},
      {"camera: {calibration: a}\ngnss: {baudrate: 9600}\n", "gnss.baudrate"},
  };
  for (const BadCase& b : cases) {
    auto c = parse_hw_config(b.yaml, "t.yaml");
    ASSERT_FALSE(c.ok()) << b.yaml;
    EXPECT_NE(c.status().message().find(b.message_part), std::string::npos)
        << b.yaml << " -> " << c.status().message();
  }
}

TEST(HwConfig, MissingFileIsNotFound) {
  auto c = load_hw_config("/nonexistent/hw.yaml");
  ASSERT_FALSE(c.ok());
  EXPECT_EQ(c.status().code(), hwr::core::ErrorCode::kNotFound);
  EXPECT_NE(c.status().message().find("/nonexistent/hw.yaml"), std::string::npos);
}
