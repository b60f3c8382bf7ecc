// SN<serial>.conf (hal/hw/zed_calibration.hpp): a realistic ZED 2i file (numbers in the range the
// factory writes) → the StereoRig at each resolution; the rig rectifies with hal::StereoDepth to
// the file's baseline; missing keys, bad numbers, the comma-locale file and truncations refused.
#include "hwr/hal/hw/zed_calibration.hpp"

#include <gtest/gtest.h>

#include <string>

#include "hwr/hal/stereo_depth.hpp"

namespace hwr::hal::hw {
namespace {

const char* kConf =
    "[LEFT_CAM_2K]\r\n"
    "fx=1064.82\r\nfy=1065.07\r\ncx=1099.05\r\ncy=628.813\r\nk1=-0.0634518\r\nk2=0.0401532\r\n"
    "p1=-0.000273455\r\np2=0.00064619\r\nk3=-0.0167323\r\n\r\n"
    "[LEFT_CAM_FHD]\nfx=1064.82\nfy=1065.07\ncx=955.05\ncy=547.813\nk1=-0.0634518\nk2=0.0401532\n"
    "p1=-0.000273455\np2=0.00064619\nk3=-0.0167323\n\n"
    "; HD: a comment line\n"
    "[LEFT_CAM_HD]\nfx = 532.41\nfy = 532.535\ncx = 636.025\ncy = 362.4065\nk1 = -0.0634518\nk2 = 0.0401532\n"
    "p1 = -0.000273455\np2 = 0.00064619\nk3 = -0.0167323\n\n"
    "[RIGHT_CAM_HD]\nFX=531.9\nFY=532.04\nCX=641.38\nCY=358.75\nK1=-0.0587\nK2=0.0330\nP1=0.00021\nP2=-0."
    "00035\n"
    "K3=-0.0121\n\n"
    "[LEFT_CAM_VGA]\nfx=266.205\nfy=266.2675\ncx=335.0125\ncy=188.70325\nk1=-0.0634518\nk2=0.0401532\n"
    "p1=-0.000273455\np2=0.00064619\nk3=-0.0167323\n\n"
    "[STEREO]\nBaseline=119.907\nTY_HD=0.0242\nTZ_HD=-0.4305\nCV_HD=0.0034\nRX_HD=-0.0012\nRZ_HD=0.0008\n"
    "TY_VGA=0.0242\nTZ_VGA=-0.4305\nCV_VGA=0.0034\nRX_VGA=-0.0012\nRZ_VGA=0.0008\n\n"
    "[MISC]\nSensor_ID=1\n";

TEST(ZedCalibration, GivenTheHdSectionsThenTheRigHasTheirIntrinsicsAndTheBaseline) {
  auto rig = parse_zed_calibration(kConf, 1280);
  ASSERT_TRUE(rig.ok()) << rig.status().message();
  EXPECT_EQ(rig->left.width, 1280);
  EXPECT_EQ(rig->left.height, 720);
  EXPECT_DOUBLE_EQ(rig->left.fx, 532.41);
  EXPECT_DOUBLE_EQ(rig->left.cy, 362.4065);
  EXPECT_DOUBLE_EQ(rig->left.distortion[4], -0.0167323);
  EXPECT_DOUBLE_EQ(rig->right.fx, 531.9);  // upper-case keys
  EXPECT_DOUBLE_EQ(rig->right.distortion[0], -0.0587);
  // The right eye sits 119.907 mm to the right (+x) of the left.
  EXPECT_NEAR(rig->T_left_right.translation().x(), 0.119907, 1e-12);
  EXPECT_NEAR(rig->T_left_right.translation().y(), 0.0242e-3, 1e-15);
  EXPECT_NEAR(rig->T_left_right.translation().z(), -0.4305e-3, 1e-15);
  // R_left_right = Rodrigues([RX, CV, RZ])ᵀ: a rotation by |r| about −r.
  const Eigen::AngleAxisd aa(rig->T_left_right.linear());
  const Eigen::Vector3d r(-0.0012, 0.0034, 0.0008);
  EXPECT_NEAR(aa.angle(), r.norm(), 1e-12);
  EXPECT_TRUE((aa.axis() * aa.angle()).isApprox(-r, 1e-9));
}

TEST(ZedCalibration, GivenTheRigThenStereoDepthRectifiesToTheFileBaseline) {
  auto rig = parse_zed_calibration(kConf, 1280);
  ASSERT_TRUE(rig.ok());
  auto depth = StereoDepth::create(*rig);
  ASSERT_TRUE(depth.ok()) << depth.status().message();
  EXPECT_NEAR(depth->baseline_m(), 0.11991, 2e-5);
  EXPECT_NEAR(depth->rectified_intrinsics().fx, 532.0, 5.0);
}

TEST(ZedCalibration, GivenAResolutionTheFileLacksThenTheMissingSectionIsNamed) {
  auto rig = parse_zed_calibration(kConf, 1920);  // no RIGHT_CAM_FHD, no FHD stereo keys
  ASSERT_FALSE(rig.ok());
  EXPECT_NE(rig.status().message().find("[RIGHT_CAM_FHD]"), std::string::npos) << rig.status().message();
}

TEST(ZedCalibration, GivenAnEyeWidthWithNoZedModeThenInvalidArgument) {
  auto rig = parse_zed_calibration(kConf, 640);
  ASSERT_FALSE(rig.ok());
  EXPECT_EQ(rig.status().code(), core::ErrorCode::kInvalidArgument);
}

TEST(ZedCalibration, GivenTheCommaLocaleFileThenItIsRefusedWithWhatToDo) {
  std::string conf(kConf);
  for (const char* k : {"k1 = -0.0634518", "k2 = 0.0401532"}) {
    conf.replace(conf.find(k), std::string(k).size(), std::string(k).substr(0, 5) + "0");
  }
  for (const char* k : {"K1=-0.0587", "K2=0.0330"})
    conf.replace(conf.find(k), std::string(k).size(), std::string(k).substr(0, 3) + "0");
  auto rig = parse_zed_calibration(conf, 1280);
  ASSERT_FALSE(rig.ok());
  EXPECT_EQ(rig.status().code(), core::ErrorCode::kCorruptData);
  EXPECT_NE(rig.status().message().find("comma-decimal locale"), std::string::npos);
}

TEST(ZedCalibration, GivenACommaDecimalValueThenItIsNotANumber) {
  std::string conf(kConf);
  conf.replace(conf.find("fx = 532.41"), 11, "fx = 532,41");
  auto rig = parse_zed_calibration(conf, 1280, "SN1.conf");
  ASSERT_FALSE(rig.ok());
  EXPECT_NE(rig.status().message().find("SN1.conf:"), std::string::npos);
  EXPECT_NE(rig.status().message().find("'532,41' is not a finite number"), std::string::npos)
      << rig.status().message();
}

TEST(ZedCalibration, GivenANegativeBaselineOrNanThenRefused) {
  std::string neg(kConf);
  neg.replace(neg.find("Baseline=119.907"), 16, "Baseline=-119.90");
  EXPECT_FALSE(parse_zed_calibration(neg, 1280).ok());
  std::string nan(kConf);
  nan.replace(nan.find("CV_HD=0.0034"), 12, "CV_HD=nan   ");
  EXPECT_FALSE(parse_zed_calibration(nan, 1280).ok());
}

TEST(ZedCalibration, GivenEveryTruncationThenAnErrorOrTheSameRigNeverACrash) {
  const std::string conf(kConf);
  const auto full = parse_zed_calibration(conf, 1280);
  ASSERT_TRUE(full.ok());
  for (size_t n = 0; n < conf.size(); ++n) {
    auto rig = parse_zed_calibration(std::string_view(conf).substr(0, n), 1280);
    if (rig.ok()) {
      // Cut inside a later section, or inside the last digits of a value (a shorter number).
      EXPECT_EQ(rig->left.width, 1280);
    }
  }
}

TEST(ZedCalibration, GivenAMissingFileThenTheErrorSaysWhereToGetIt) {
  auto rig = load_zed_calibration_file("/nonexistent/SN12345.conf", 1280);
  ASSERT_FALSE(rig.ok());
  EXPECT_EQ(rig.status().code(), core::ErrorCode::kNotFound);
  EXPECT_NE(rig.status().message().find("calib.stereolabs.com"), std::string::npos);
  EXPECT_EQ(zed_calibration_file_name(12345), "SN12345.conf");
}

}  // namespace
}  // namespace hwr::hal::hw
