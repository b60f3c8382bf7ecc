// hwr-robot --source hw:CONFIG without the hardware: each missing piece is one clear line and exit
// code 1 (the live-hardware checklist in docs/hardware.md quotes these lines).

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "cli_run.hpp"
#include "temp_dir.hpp"

namespace {

const std::string kRobot = HWR_BINARY_DIR "/apps/hwr-robot/hwr-robot";

hwr::testing::CliRun robot(const std::string& args) { return hwr::testing::run_cli(kRobot, args); }

void expect_one_line(const hwr::testing::CliRun& r, const std::string& part) {
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find(part), std::string::npos) << r.out;
}

const char* kConf =
    "[LEFT_CAM_HD]\nfx=532.41\nfy=532.535\ncx=636.025\ncy=362.4065\nk1=-0.0634518\nk2=0.0401532\n"
    "p1=-0.000273455\np2=0.00064619\nk3=-0.0167323\n"
    "[RIGHT_CAM_HD]\nfx=531.9\nfy=532.04\ncx=641.38\ncy=358.75\nk1=-0.0587\nk2=0.0330\np1=0.00021\n"
    "p2=-0.00035\nk3=-0.0121\n"
    "[STEREO]\nBaseline=119.907\nTY_HD=0.0242\nTZ_HD=-0.4305\nCV_HD=0.0034\nRX_HD=-0.0012\nRZ_HD=0.0008\n";

TEST(HwrRobotHw, GivenAMissingConfigThenItIsNamed) {
  expect_one_line(robot("--source hw:/nonexistent/hw.yaml"), "/nonexistent/hw.yaml: file not found");
}

TEST(HwrRobotHw, GivenTheTemplateWithoutItsCalibrationFileThenItIsNamed) {
  expect_one_line(robot("--source hw:" HWR_SOURCE_DIR "/config/hw.yaml"), "/etc/hwr/SN12345678.conf");
}

TEST(HwrRobotHw, GivenEachMissingDeviceThenItsLine) {
  hwr::testing::TempDir tmp("hwr_robot_hw");
  { std::ofstream(tmp.file("SN1.conf")) << kConf; }
  const std::string base = "imu: a9\nzed_sensors: {enabled: false}\nsysfs_root: " + tmp.path() +
                           "\na9: {enabled: true, device: " + tmp.file("no-a9") + "}\n";
  // No calibration file.
  std::ofstream(tmp.file("a.yaml")) << base << "camera: {calibration: " << tmp.file("none.conf") << "}\n";
  expect_one_line(robot("--source hw:" + tmp.file("a.yaml")), "calib.stereolabs.com");
  // No ZED in (a fake, empty) sysfs.
  std::filesystem::create_directories(tmp.path() + "/class/video4linux");
  std::ofstream(tmp.file("b.yaml")) << base << "camera: {calibration: " << tmp.file("SN1.conf") << "}\n";
  expect_one_line(robot("--source hw:" + tmp.file("b.yaml")), "no video device with USB id 2b03:f880");
  // A9 absent (the camera disabled so the A9 is the first device checked).
  std::ofstream(tmp.file("c.yaml")) << base << "camera: {enabled: false}\n";
  expect_one_line(robot("--source hw:" + tmp.file("c.yaml")), "a9: " + tmp.file("no-a9"));
  // No ZED 2i sensor MCU on the USB bus (the camera disabled so the MCU is the first device checked).
  std::ofstream(tmp.file("e.yaml")) << "imu: zed\ncamera: {enabled: false}\n";
  expect_one_line(robot("--source hw:" + tmp.file("e.yaml")), "zed_sensors: ZED 2i sensor MCU 2b03:f881");
  // A bad key.
  std::ofstream(tmp.file("d.yaml")) << base << "camera: {calibration: x, fsp: 30}\n";
  expect_one_line(robot("--source hw:" + tmp.file("d.yaml")), "camera.fsp");
}

TEST(HwrRobotHw, GivenFaultsWithALiveSourceThenRefused) {
  const auto r = robot("--source hw:" HWR_SOURCE_DIR "/config/hw.yaml --faults dropout=1:1");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("--faults applies to replayed sources"), std::string::npos) << r.out;
}

}  // namespace
