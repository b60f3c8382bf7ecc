// SN<serial>.conf (hal/hw/zed_calibration.hpp). A realistic ZED 2i file (all four resolutions,
// numbers in the range the factory writes: fx ≈ 1060 px at FHD, baseline ≈ 120 mm) → the StereoRig
// at each resolution, checked against the file's numbers and against an independent Rodrigues
// formula; the rig's rectification against zed-open-capture's own cv::stereoRectify call on the raw
// file values (the oracle for the frame conventions); every INI spelling the factory and editors
// produce; every missing key named; the comma-locale file, bad numbers, truncations, garbage.
#include "hwr/hal/hw/zed_calibration.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>

#include "hwr/hal/stereo_depth.hpp"

namespace hwr::hal::hw {
namespace {

const char* const kConf =
    "[LEFT_CAM_2K]\n"
    "fx=1059.73\nfy=1059.52\ncx=1108.11\ncy=630.67\n"
    "k1=-0.0411857\nk2=0.00963207\np1=-0.000322616\np2=0.000204186\nk3=-0.00519314\n\n"
    "[RIGHT_CAM_2K]\n"
    "fx=1061.36\nfy=1061.09\ncx=1125.48\ncy=622.985\n"
    "k1=-0.0406893\nk2=0.00927831\np1=-0.000185236\np2=-0.000437622\nk3=-0.00490219\n\n"
    "[LEFT_CAM_FHD]\n"
    "fx=1059.73\nfy=1059.52\ncx=964.11\ncy=549.67\n"
    "k1=-0.0411857\nk2=0.00963207\np1=-0.000322616\np2=0.000204186\nk3=-0.00519314\n\n"
    "[RIGHT_CAM_FHD]\n"
    "fx=1061.36\nfy=1061.09\ncx=981.48\ncy=541.985\n"
    "k1=-0.0406893\nk2=0.00927831\np1=-0.000185236\np2=-0.000437622\nk3=-0.00490219\n\n"
    "[LEFT_CAM_HD]\n"
    "fx=529.865\nfy=529.76\ncx=644.055\ncy=360.335\n"
    "k1=-0.0411857\nk2=0.00963207\np1=-0.000322616\np2=0.000204186\nk3=-0.00519314\n\n"
    "[RIGHT_CAM_HD]\n"
    "fx=530.68\nfy=530.545\ncx=652.74\ncy=356.4925\n"
    "k1=-0.0406893\nk2=0.00927831\np1=-0.000185236\np2=-0.000437622\nk3=-0.00490219\n\n"
    "[LEFT_CAM_VGA]\n"
    "fx=264.9325\nfy=264.88\ncx=338.0275\ncy=187.6675\n"
    "k1=-0.0411857\nk2=0.00963207\np1=-0.000322616\np2=0.000204186\nk3=-0.00519314\n\n"
    "[RIGHT_CAM_VGA]\n"
    "fx=265.34\nfy=265.2725\ncx=342.37\ncy=185.74625\n"
    "k1=-0.0406893\nk2=0.00927831\np1=-0.000185236\np2=-0.000437622\nk3=-0.00490219\n\n"
    "[STEREO]\n"
    "Baseline=119.987\n"
    "TY_2K=0.0291\nTZ_2K=-0.3456\nCV_2K=0.00421\nRX_2K=0.00171\nRZ_2K=-0.00093\n"
    "TY_FHD=0.0291\nTZ_FHD=-0.3456\nCV_FHD=0.00421\nRX_FHD=0.00171\nRZ_FHD=-0.00093\n"
    "TY_HD=0.0291\nTZ_HD=-0.3456\nCV_HD=0.00421\nRX_HD=0.00171\nRZ_HD=-0.00093\n"
    "TY_VGA=0.0291\nTZ_VGA=-0.3456\nCV_VGA=0.00421\nRX_VGA=0.00171\nRZ_VGA=-0.00093\n\n"
    "[MISC]\nSensor_ID=1\n";

constexpr double kRx = 0.00171, kCv = 0.00421, kRz = -0.00093;
constexpr double kBaselineMm = 119.987, kTyMm = 0.0291, kTzMm = -0.3456;

// Rodrigues' formula written out (the oracle; the parser uses Eigen's angle-axis):
// R = I + sin θ · K + (1 − cos θ) · K², K the cross-product matrix of the unit axis.
Eigen::Matrix3d rodrigues(const Eigen::Vector3d& r) {
  const double theta = r.norm();
  const Eigen::Vector3d k = r / theta;
  Eigen::Matrix3d K;
  K << 0, -k.z(), k.y(), k.z(), 0, -k.x(), -k.y(), k.x(), 0;
  return Eigen::Matrix3d::Identity() + std::sin(theta) * K + (1 - std::cos(theta)) * K * K;
}

std::string replace_all(std::string s, const std::string& from, const std::string& to) {
  for (size_t p = s.find(from); p != std::string::npos; p = s.find(from, p + to.size()))
    s.replace(p, from.size(), to);
  return s;
}

// Drops the line "key=..." in the given section (exact spelling of kConf).
std::string without_line(const std::string& conf, const std::string& section, const std::string& key) {
  const size_t s = conf.find("[" + section + "]");
  EXPECT_NE(s, std::string::npos) << section;
  const size_t k = conf.find("\n" + key + "=", s);
  EXPECT_NE(k, std::string::npos) << key;
  const size_t eol = conf.find('\n', k + 1);
  return conf.substr(0, k) + conf.substr(eol);
}

std::string with_value(const std::string& conf, const std::string& section, const std::string& key,
                       const std::string& value) {
  const size_t s = conf.find("[" + section + "]");
  const size_t k = conf.find("\n" + key + "=", s);
  const size_t eol = conf.find('\n', k + 1);
  return conf.substr(0, k) + "\n" + key + "=" + value + conf.substr(eol);
}

void expect_same_rig(const StereoRig& a, const StereoRig& b) {
  for (const auto* pair : {&a.left, &a.right}) {
    const PinholeIntrinsics& x = *pair;
    const PinholeIntrinsics& y = pair == &a.left ? b.left : b.right;
    EXPECT_EQ(x.width, y.width);
    EXPECT_EQ(x.height, y.height);
    EXPECT_EQ(x.fx, y.fx);
    EXPECT_EQ(x.fy, y.fy);
    EXPECT_EQ(x.cx, y.cx);
    EXPECT_EQ(x.cy, y.cy);
    EXPECT_EQ(x.distortion, y.distortion);
  }
  EXPECT_EQ(a.T_left_right.matrix(), b.T_left_right.matrix());
}

TEST(ZedCalibration, GivenTheFhdSectionsThenTheRigHasTheirIntrinsicsAndTheRightEyeAtPlusBaseline) {
  auto rig = parse_zed_calibration(kConf, 1920);
  ASSERT_TRUE(rig.ok()) << rig.status().message();
  EXPECT_EQ(rig->left.width, 1920);
  EXPECT_EQ(rig->left.height, 1080);
  EXPECT_EQ(rig->right.width, 1920);
  EXPECT_EQ(rig->right.height, 1080);
  EXPECT_DOUBLE_EQ(rig->left.fx, 1059.73);
  EXPECT_DOUBLE_EQ(rig->left.fy, 1059.52);
  EXPECT_DOUBLE_EQ(rig->left.cx, 964.11);
  EXPECT_DOUBLE_EQ(rig->left.cy, 549.67);
  const std::array<double, 5> dl{-0.0411857, 0.00963207, -0.000322616, 0.000204186, -0.00519314};
  EXPECT_EQ(rig->left.distortion, dl);  // OpenCV order k1 k2 p1 p2 k3
  EXPECT_DOUBLE_EQ(rig->right.fx, 1061.36);
  EXPECT_DOUBLE_EQ(rig->right.cy, 541.985);
  EXPECT_DOUBLE_EQ(rig->right.distortion[3], -0.000437622);

  // p_left = T_left_right · p_right, T_left_right = [Rᵀ | Rᵀ·t], R = Rodrigues([RX, CV, RZ]).
  const Eigen::Matrix3d R = rodrigues({kRx, kCv, kRz});
  const Eigen::Vector3d t(kBaselineMm * 1e-3, kTyMm * 1e-3, kTzMm * 1e-3);
  EXPECT_TRUE(rig->T_left_right.linear().isApprox(R.transpose(), 1e-14));
  EXPECT_TRUE(rig->T_left_right.translation().isApprox(R.transpose() * t, 1e-14));
  // The right eye sits ~120 mm to the right (+x) of the left eye.
  EXPECT_NEAR(rig->T_left_right.translation().x(), 0.119987, 1e-6);
  EXPECT_NEAR(rig->T_left_right.translation().norm(), t.norm(), 1e-15);
  // The right camera's centre, mapped into the left frame, is that translation.
  EXPECT_TRUE((rig->T_left_right * Eigen::Vector3d::Zero()).isApprox(rig->T_left_right.translation()));
}

TEST(ZedCalibration, GivenEachResolutionThenItsOwnSectionsAndImageSize) {
  struct Case {
    int width, height;
    double left_fx, right_cx;
  };
  for (const Case& c : {Case{2208, 1242, 1059.73, 1125.48}, Case{1920, 1080, 1059.73, 981.48},
                        Case{1280, 720, 529.865, 652.74}, Case{672, 376, 264.9325, 342.37}}) {
    auto rig = parse_zed_calibration(kConf, c.width);
    ASSERT_TRUE(rig.ok()) << c.width << ": " << rig.status().message();
    EXPECT_EQ(rig->left.height, c.height);
    EXPECT_EQ(rig->right.width, c.width);
    EXPECT_DOUBLE_EQ(rig->left.fx, c.left_fx);
    EXPECT_DOUBLE_EQ(rig->right.cx, c.right_cx);
  }
}

TEST(ZedCalibration, GivenTheRigThenStereoDepthRectifiesAsZedOpenCapturesStereoRectifyCall) {
  // zed-open-capture examples/include/calibration.hpp, initCalibration: stereoRectify(K_l, D_l, K_r,
  // D_r, size, Rodrigues([RX, CV, RZ]), [Baseline, TY, TZ], ..., CALIB_ZERO_DISPARITY, 0, size) on the
  // file's raw numbers. Our rig through hal::StereoDepth must give the same rectifying rotation of the
  // left camera (R1), which is the whole of what the frame conventions decide.
  for (int width : {1280, 1920}) {
    auto rig = parse_zed_calibration(kConf, width);
    ASSERT_TRUE(rig.ok());
    auto depth = StereoDepth::create(*rig);
    ASSERT_TRUE(depth.ok()) << depth.status().message();

    const auto K = [](const PinholeIntrinsics& k) {
      return cv::Mat((cv::Mat_<double>(3, 3) << k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1));
    };
    const auto D = [](const PinholeIntrinsics& k) {
      cv::Mat d(5, 1, CV_64F);
      for (int i = 0; i < 5; ++i) d.at<double>(i) = k.distortion[static_cast<size_t>(i)];
      return d;
    };
    cv::Mat R;
    cv::Rodrigues(cv::Mat((cv::Mat_<double>(1, 3) << kRx, kCv, kRz)), R);
    const cv::Mat T = (cv::Mat_<double>(3, 1) << kBaselineMm, kTyMm, kTzMm);
    const cv::Size size(rig->left.width, rig->left.height);
    cv::Mat R1, R2, P1, P2, Q;
    cv::stereoRectify(K(rig->left), D(rig->left), K(rig->right), D(rig->right), size, R, T, R1, R2, P1, P2, Q,
                      cv::CALIB_ZERO_DISPARITY, 0, size);
    const Eigen::Matrix3d R_rect_cam0 = depth->T_cam0_rect().linear().transpose();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(R_rect_cam0(r, c), R1.at<double>(r, c), 1e-12) << width;
    }
    EXPECT_NEAR(depth->rectified_intrinsics().fx, P1.at<double>(0, 0), 1e-9);
    // Same baseline (|T| in m), positive: the right eye to the right.
    EXPECT_NEAR(depth->baseline_m(), cv::norm(T) * 1e-3, 1e-12);
    EXPECT_GT(depth->baseline_m(), 0.119);
  }
}

TEST(ZedCalibration, GivenTheRotationReadTransposedThenRectificationWouldDiffer) {
  // The test above can fail: with R_left_right = Rodrigues(...) instead, R1 is off by ~the angles.
  StereoRig rig = *parse_zed_calibration(kConf, 1280);
  const Eigen::Matrix3d R = rodrigues({kRx, kCv, kRz});
  StereoRig wrong = rig;
  wrong.T_left_right.linear() = R;
  auto a = StereoDepth::create(rig);
  auto b = StereoDepth::create(wrong);
  ASSERT_TRUE(a.ok() && b.ok());
  const Eigen::AngleAxisd diff(a->T_cam0_rect().linear().transpose() * b->T_cam0_rect().linear());
  EXPECT_GT(diff.angle(), 1e-3);
}

TEST(ZedCalibration, GivenEveryIniSpellingThenTheSameRig) {
  const std::string conf(kConf);
  const auto reference = parse_zed_calibration(conf, 1280);
  ASSERT_TRUE(reference.ok());
  std::vector<std::pair<std::string, std::string>> variants = {
      {"CRLF", replace_all(conf, "\n", "\r\n")},
      {"spaces around =", replace_all(conf, "=", " = ")},
      {"tabs", replace_all(replace_all(conf, "=", "\t=\t"), "[", "\t[")},
      {"lower-case sections",
       replace_all(replace_all(conf, "[LEFT_CAM_HD]", "[left_cam_hd]"), "[STEREO]", "[Stereo]")},
      {"upper-case keys", replace_all(replace_all(replace_all(conf, "\nfx=", "\nFX="), "\nk1=", "\nK1="),
                                      "Baseline=", "BASELINE=")},
      {"comments and blank lines",
       "; ZED 2i SN12345\n# factory calibration\n\n" + replace_all(conf, "\n[", "\n\n; section\n#\n   \n[")},
      {"UTF-8 byte-order mark", "\xEF\xBB\xBF" + conf},
      {"no final newline", conf.substr(0, conf.size() - 1)},
      {"spaces inside brackets", replace_all(conf, "[RIGHT_CAM_HD]", "[ RIGHT_CAM_HD ]")},
      {"explicit plus sign", replace_all(conf, "Baseline=119.987", "Baseline=+119.987")},
      {"exponent notation", replace_all(conf, "fx=529.865", "fx=5.29865e+02")},
      {"a key before any section", "version=3\n" + conf},
  };
  for (const auto& [name, text] : variants) {
    auto rig = parse_zed_calibration(text, 1280);
    ASSERT_TRUE(rig.ok()) << name << ": " << rig.status().message();
    SCOPED_TRACE(name);
    expect_same_rig(*rig, *reference);
  }
}

TEST(ZedCalibration, GivenARepeatedKeyThenTheLastValueCounts) {
  const std::string conf = replace_all(kConf, "[LEFT_CAM_HD]\n", "[LEFT_CAM_HD]\nfx=1.5\n");
  auto rig = parse_zed_calibration(conf, 1280);
  ASSERT_TRUE(rig.ok());
  EXPECT_DOUBLE_EQ(rig->left.fx, 529.865);
}

TEST(ZedCalibration, GivenEachRequiredKeyMissingThenTheErrorNamesSectionAndKey) {
  const std::string conf(kConf);
  for (const char* section : {"LEFT_CAM_HD", "RIGHT_CAM_HD"}) {
    for (const char* key : {"fx", "fy", "cx", "cy", "k1", "k2"}) {
      auto rig = parse_zed_calibration(without_line(conf, section, key), 1280, "SN7.conf");
      ASSERT_FALSE(rig.ok()) << section << " " << key;
      EXPECT_EQ(rig.status().code(), core::ErrorCode::kNotFound);
      EXPECT_EQ(rig.status().message(), std::string("SN7.conf: [") + section + "] has no key '" + key + "'");
    }
  }
  for (const char* key : {"Baseline", "TY_HD", "TZ_HD", "RX_HD", "CV_HD", "RZ_HD"}) {
    auto rig = parse_zed_calibration(without_line(conf, "STEREO", key), 1280);
    ASSERT_FALSE(rig.ok()) << key;
    EXPECT_EQ(rig.status().code(), core::ErrorCode::kNotFound);
    std::string lower(key);
    for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    EXPECT_NE(rig.status().message().find("[STEREO] has no key '" + lower + "'"), std::string::npos)
        << rig.status().message();
  }
}

TEST(ZedCalibration, GivenNoP1P2K3ThenTheyDefaultToZero) {
  std::string conf(kConf);
  for (const char* section : {"LEFT_CAM_HD", "RIGHT_CAM_HD"}) {
    for (const char* key : {"p1", "p2", "k3"}) conf = without_line(conf, section, key);
  }
  auto rig = parse_zed_calibration(conf, 1280);
  ASSERT_TRUE(rig.ok()) << rig.status().message();
  EXPECT_EQ(rig->left.distortion[2], 0.0);
  EXPECT_EQ(rig->right.distortion[4], 0.0);
  EXPECT_DOUBLE_EQ(rig->left.distortion[0], -0.0411857);
}

TEST(ZedCalibration, GivenOnlyUnsuffixedTyTzThenTheyAreRead) {
  std::string conf(kConf);
  conf = without_line(conf, "STEREO", "TY_HD");
  conf = without_line(conf, "STEREO", "TZ_HD");
  conf = replace_all(conf, "Baseline=119.987\n", "Baseline=119.987\nTY=0.5\nTZ=-0.25\n");
  auto rig = parse_zed_calibration(conf, 1280);
  ASSERT_TRUE(rig.ok()) << rig.status().message();
  const Eigen::Matrix3d R = rodrigues({kRx, kCv, kRz});
  EXPECT_TRUE(rig->T_left_right.translation().isApprox(
      R.transpose() * Eigen::Vector3d(0.119987, 0.5e-3, -0.25e-3), 1e-14));
}

TEST(ZedCalibration, GivenAResolutionTheFileLacksThenTheMissingSectionIsNamed) {
  std::string conf(kConf);
  conf = replace_all(conf, "[RIGHT_CAM_FHD]", "[RIGHT_CAM_XX]");
  auto rig = parse_zed_calibration(conf, 1920);
  ASSERT_FALSE(rig.ok());
  EXPECT_EQ(rig.status().code(), core::ErrorCode::kNotFound);
  EXPECT_NE(rig.status().message().find("no section [RIGHT_CAM_FHD]"), std::string::npos)
      << rig.status().message();
}

TEST(ZedCalibration, GivenAnEyeWidthWithNoZedModeThenInvalidArgument) {
  for (int width : {0, -1280, 640, 1344, 2560, 3840}) {
    auto rig = parse_zed_calibration(kConf, width);
    ASSERT_FALSE(rig.ok());
    EXPECT_EQ(rig.status().code(), core::ErrorCode::kInvalidArgument);
    EXPECT_NE(rig.status().message().find("eye width " + std::to_string(width)), std::string::npos);
  }
}

TEST(ZedCalibration, GivenTheCommaLocaleFileThenItIsRefusedWithWhatToDo) {
  // A file written under a comma-decimal locale reads back with k1 = k2 = 0 (zed-open-capture's
  // atof stops at the comma) — the factory's own check; ours sees the zeros too.
  std::string conf(kConf);
  for (const char* section : {"LEFT_CAM_HD", "RIGHT_CAM_HD"}) {
    conf = with_value(conf, section, "k1", "0");
    conf = with_value(conf, section, "k2", "-0");
  }
  auto rig = parse_zed_calibration(conf, 1280);
  ASSERT_FALSE(rig.ok());
  EXPECT_EQ(rig.status().code(), core::ErrorCode::kCorruptData);
  EXPECT_NE(rig.status().message().find("comma-decimal locale"), std::string::npos);
  EXPECT_NE(rig.status().message().find("calib.stereolabs.com"), std::string::npos);
  // One camera with distortion is enough.
  conf = with_value(conf, "RIGHT_CAM_HD", "k2", "0.001");
  EXPECT_TRUE(parse_zed_calibration(conf, 1280).ok());
}

TEST(ZedCalibration, GivenValuesThatAreNotFiniteNumbersThenParseErrorWithTheLine) {
  const std::string conf(kConf);
  for (const char* bad :
       {"532,41", "nan", "NaN", "inf", "-inf", "1e999", "", "12abc", "0x10", "--1", "1.2.3", "\"1.5\""}) {
    const std::string text = with_value(conf, "LEFT_CAM_HD", "fy", bad);
    auto rig = parse_zed_calibration(text, 1280, "SN1.conf");
    ASSERT_FALSE(rig.ok()) << bad;
    EXPECT_EQ(rig.status().code(), core::ErrorCode::kParseError) << bad;
    // The line of the bad value: count the lines up to it.
    const size_t at = text.find("\nfy=" + std::string(bad), text.find("[LEFT_CAM_HD]"));
    const int line =
        2 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
    EXPECT_NE(rig.status().message().find("SN1.conf:" + std::to_string(line) + ": [LEFT_CAM_HD] fy = '" +
                                          bad + "'"),
              std::string::npos)
        << rig.status().message();
  }
}

TEST(ZedCalibration, GivenImplausibleNumbersThenOutOfRangeNamingThem) {
  const std::string conf(kConf);
  struct Case {
    const char* section;
    const char* key;
    const char* value;
    const char* says;
  };
  for (const Case& c :
       {Case{"STEREO", "Baseline", "-119.987", "Baseline"}, Case{"STEREO", "Baseline", "0", "Baseline"},
        Case{"STEREO", "Baseline", "0.12e6", "Baseline"}, Case{"LEFT_CAM_HD", "fx", "0", "focal lengths"},
        Case{"RIGHT_CAM_HD", "fy", "-530", "focal"}, Case{"LEFT_CAM_HD", "cx", "1300", "principal point"},
        Case{"RIGHT_CAM_HD", "cy", "-1", "principal point"},
        Case{"STEREO", "CV_HD", "0.241", "more than 0.2 rad"},
        Case{"STEREO", "TY_HD", "-130", "not small against Baseline"},
        Case{"STEREO", "TZ_HD", "1e300", "side by side"},
        Case{"STEREO", "RZ_HD", "-0.3", "degrees instead of radians"}}) {
    auto rig = parse_zed_calibration(with_value(conf, c.section, c.key, c.value), 1280);
    ASSERT_FALSE(rig.ok()) << c.key << "=" << c.value;
    EXPECT_EQ(rig.status().code(), core::ErrorCode::kOutOfRange);
    EXPECT_NE(rig.status().message().find(c.says), std::string::npos) << rig.status().message();
  }
}

TEST(ZedCalibration, GivenMalformedLinesThenParseErrorWithTheLine) {
  std::string conf = replace_all(kConf, "[LEFT_CAM_HD]\n", "[LEFT_CAM_HD]\nthis line has no equals sign\n");
  auto rig = parse_zed_calibration(conf, 1280, "x.conf");
  ASSERT_FALSE(rig.ok());
  EXPECT_EQ(rig.status().code(), core::ErrorCode::kParseError);
  EXPECT_NE(rig.status().message().find("x.conf:"), std::string::npos);
  conf = replace_all(kConf, "[STEREO]", "[STEREO");
  rig = parse_zed_calibration(conf, 1280);
  ASSERT_FALSE(rig.ok());
  EXPECT_NE(rig.status().message().find("unterminated section header"), std::string::npos);
  conf = replace_all(kConf, "\nfx=529.865", "\n=529.865");
  EXPECT_FALSE(parse_zed_calibration(conf, 1280).ok());
}

TEST(ZedCalibration, GivenEveryTruncationThenAnErrorBeforeTheLastKeyAndTheSameRigAfterIt) {
  // Oracle: a cut before the last key the HD rig needs is an error (a key missing); a cut at a line
  // boundary after it gives the full rig; a cut inside a later line gives the full rig or an error
  // for that malformed last line ("TY_V" has no '='); a cut inside the last value's digits gives a
  // shorter number or an error. Never a crash, never an error without a message.
  const std::string conf(kConf);
  const auto full = parse_zed_calibration(conf, 1280);
  ASSERT_TRUE(full.ok());
  // Where the last key the HD rig needs starts and ends (STEREO's HD keys come after all cameras).
  size_t last_start = 0;
  for (const char* key : {"TY_HD=", "TZ_HD=", "CV_HD=", "RX_HD=", "RZ_HD="}) {
    last_start = std::max(last_start, conf.find(std::string("\n") + key) + 1);
  }
  const size_t last_end = conf.find('\n', last_start);
  for (size_t n = 0; n <= conf.size(); ++n) {
    // An exact-size copy, so ASan sees any read past the end.
    const std::string cut = conf.substr(0, n);
    auto rig = parse_zed_calibration(cut, 1280);
    if (n <= last_start) {
      EXPECT_FALSE(rig.ok()) << n;
    } else if (n >= last_end) {
      const bool at_line_boundary = n == conf.size() || cut.back() == '\n';
      if (at_line_boundary) {
        ASSERT_TRUE(rig.ok()) << n << ": " << rig.status().message();
      }
      if (rig.ok()) {
        SCOPED_TRACE(n);
        expect_same_rig(*rig, *full);
      }
    } else if (rig.ok()) {  // cut inside the last value's digits: a shorter number
      EXPECT_EQ(rig->left.fx, full->left.fx);
    }
    if (!rig.ok()) {
      EXPECT_FALSE(rig.status().message().empty());
    }
  }
}

TEST(ZedCalibration, GivenGarbageOrMutatedFilesThenNoCrashAndEveryAcceptedRigIsSane) {
  std::mt19937 rng(5);
  const std::string conf(kConf);
  int accepted = 0;
  for (int i = 0; i < 3000; ++i) {
    std::string text;
    if (i % 3 == 0) {
      text.resize(rng() % 2000);
      for (char& c : text) c = static_cast<char>(rng());
    } else {
      text = conf;
      const int flips = 1 + static_cast<int>(rng() % 4);
      for (int f = 0; f < flips; ++f) text[rng() % text.size()] = static_cast<char>(rng());
    }
    auto rig = parse_zed_calibration(text, 1280);
    if (!rig.ok()) {
      ASSERT_FALSE(rig.status().message().empty());
      continue;
    }
    ++accepted;
    ASSERT_TRUE(rig->left.valid() && rig->right.valid());
    ASSERT_GT(rig->T_left_right.translation().x(), 0);
    const Eigen::Matrix3d R = rig->T_left_right.linear();
    ASSERT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-9);
  }
  EXPECT_GT(accepted, 100);  // most single flips land in another resolution's sections or in digits
}

TEST(ZedCalibration, GivenTheFileOnDiskThenTheSameRigAndThePathInErrors) {
  const std::string path = ::testing::TempDir() + "/" + zed_calibration_file_name(31415926);
  EXPECT_EQ(zed_calibration_file_name(31415926), "SN31415926.conf");
  EXPECT_EQ(zed_calibration_file_name(0), "SN0.conf");
  EXPECT_EQ(zed_calibration_file_name(4294967295u), "SN4294967295.conf");
  FILE* f = std::fopen(path.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  std::fputs(kConf, f);
  std::fclose(f);
  auto from_disk = load_zed_calibration_file(path, 1920);
  ASSERT_TRUE(from_disk.ok()) << from_disk.status().message();
  expect_same_rig(*from_disk, *parse_zed_calibration(kConf, 1920));
  auto wrong_mode = load_zed_calibration_file(path, 1000);
  ASSERT_FALSE(wrong_mode.ok());
  EXPECT_NE(wrong_mode.status().message().find(path), std::string::npos);
  std::remove(path.c_str());
}

TEST(ZedCalibration, GivenAMissingFileThenTheErrorSaysWhereToGetIt) {
  auto rig = load_zed_calibration_file("/nonexistent/SN12345.conf", 1280);
  ASSERT_FALSE(rig.ok());
  EXPECT_EQ(rig.status().code(), core::ErrorCode::kNotFound);
  EXPECT_NE(rig.status().message().find("/nonexistent/SN12345.conf"), std::string::npos);
  EXPECT_NE(rig.status().message().find("calib.stereolabs.com"), std::string::npos);
}

}  // namespace
}  // namespace hwr::hal::hw
