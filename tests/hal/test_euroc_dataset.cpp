// EuRoC replay (hal/euroc_dataset.hpp) on the real V1_01 static start and V1_02 IMU folders, and
// on folders written here for the errors.

#include <optional>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "hal_test_util.hpp"
#include "hwr/hal/euroc_dataset.hpp"

namespace hwr::hal {
namespace {

namespace fs = std::filesystem;
using testing::expect_one_line_error;
using testing::kEurocImu40sMav0;
using testing::kEurocStaticMav0;
using testing::scratch_dir;
using testing::write_text;

class EurocStatic : public ::testing::Test {
 protected:
  void SetUp() override {
    HWR_REQUIRE_DATASET(kEurocStaticMav0);
    auto ds = EurocDataset::open(kEurocStaticMav0);
    ASSERT_TRUE(ds.ok()) << ds.status().to_string();
    ds_ = std::move(ds).value();
  }
  std::optional<EurocDataset> ds_;
};

TEST_F(EurocStatic, GivenV101StaticStart_WhenOpened_ThenPairsSkippedFramesImuAndGroundTruthMatchTheFiles) {
  ASSERT_TRUE(ds_->has_stereo());
  // cam0 lists 95 frames, cam1 99 of which the last 4 (…278012… to …278162…) have no PNG.
  EXPECT_EQ(ds_->listed_frames(0), 95u);
  EXPECT_EQ(ds_->missing_images(0), 0u);
  EXPECT_EQ(ds_->listed_frames(1), 99u);
  EXPECT_EQ(ds_->missing_images(1), 4u);
  ASSERT_EQ(ds_->size(), 95u);
  EXPECT_EQ(ds_->frame_time_ns(0), 1403715273262142976LL);
  EXPECT_EQ(ds_->frame_time_ns(94), 1403715277962142976LL);
  for (size_t i = 0; i < ds_->size(); ++i) EXPECT_EQ(ds_->frame_time_ns(i), ds_->right_time_ns(i)) << i;
  EXPECT_EQ(ds_->left_path(0), kEurocStaticMav0 + "/cam0/data/1403715273262142976.png");

  ASSERT_EQ(ds_->imu().size(), 29120u);
  EXPECT_EQ(ds_->imu().front().t_ns, 1403715273262142976LL);
  EXPECT_EQ(ds_->imu().back().t_ns, 1403715418857143040LL);

  ASSERT_EQ(ds_->state_groundtruth().size(), 2895u);
  EXPECT_EQ(ds_->state_groundtruth().front().t_ns, 1403715273262142976LL);
  EXPECT_EQ(ds_->state_groundtruth().back().t_ns, 1403715417962142976LL);

  // groundtruth_ov_data/V1_01_easy_original.txt: the Vicon ground truth, 28712 poses from 1403715274.30214.
  EXPECT_NE(ds_->tum_groundtruth_path().find("V1_01_easy_original.txt"), std::string::npos);
  ASSERT_EQ(ds_->tum_groundtruth().size(), 28712u);
  EXPECT_EQ(ds_->tum_groundtruth().front().t_ns, 1403715274302140000LL);
  EXPECT_EQ(ds_->tum_groundtruth().back().t_ns, 1403715417857140000LL);
}

TEST_F(EurocStatic, GivenSensorYaml_WhenRead_ThenIntrinsicsDistortionAndExtrinsicsMatchTheFile) {
  const PinholeIntrinsics& k0 = ds_->cam0().intrinsics;
  EXPECT_EQ(k0.width, 752);
  EXPECT_EQ(k0.height, 480);
  EXPECT_DOUBLE_EQ(k0.fx, 458.654);
  EXPECT_DOUBLE_EQ(k0.fy, 457.296);
  EXPECT_DOUBLE_EQ(k0.cx, 367.215);
  EXPECT_DOUBLE_EQ(k0.cy, 248.375);
  EXPECT_DOUBLE_EQ(k0.distortion[0], -0.28340811);
  EXPECT_DOUBLE_EQ(k0.distortion[3], 1.76187114e-05);
  EXPECT_EQ(k0.distortion[4], 0.0);
  EXPECT_DOUBLE_EQ(ds_->cam1().intrinsics.cx, 379.999);
  EXPECT_DOUBLE_EQ(ds_->cam0().rate_hz, 20.0);
  EXPECT_NEAR(ds_->cam0().T_body_cam.translation().x(), -0.0216401454975, 1e-15);
  EXPECT_NEAR(ds_->cam0().T_body_cam.linear()(0, 1), -0.999880929698, 1e-9);
  // The VI-sensor stereo baseline is about 11 cm, mostly along cam0's x axis.
  const Eigen::Vector3d t01 = ds_->T_cam0_cam1().translation();
  EXPECT_NEAR(t01.norm(), 0.110, 0.002);
  EXPECT_GT(t01.x(), 0.105);

  const EurocImuCalib& imu = ds_->imu_calib();
  EXPECT_TRUE(imu.present);
  EXPECT_DOUBLE_EQ(imu.rate_hz, 200.0);
  EXPECT_DOUBLE_EQ(imu.gyro_noise_density, 1.6968e-04);
  EXPECT_DOUBLE_EQ(imu.gyro_random_walk, 1.9393e-05);
  EXPECT_DOUBLE_EQ(imu.accel_noise_density, 2.0e-3);
  EXPECT_DOUBLE_EQ(imu.accel_random_walk, 3.0e-3);
  EXPECT_TRUE(imu.T_body_imu.isApprox(Eigen::Isometry3d::Identity()));
}

TEST_F(EurocStatic, GivenPair0_WhenLoaded_ThenBothImagesAreGray752x480AndEqualTheFiles) {
  cv::Mat l;
  cv::Mat r;
  ASSERT_TRUE(ds_->load_stereo(0, &l, &r).ok());
  ASSERT_EQ(l.type(), CV_8UC1);
  ASSERT_EQ(r.type(), CV_8UC1);
  EXPECT_EQ(l.size(), cv::Size(752, 480));
  EXPECT_EQ(r.size(), cv::Size(752, 480));
  EXPECT_EQ(cv::norm(l, cv::imread(ds_->left_path(0), cv::IMREAD_GRAYSCALE), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(r, cv::imread(ds_->right_path(0), cv::IMREAD_GRAYSCALE), cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(l, r, cv::NORM_L1), 0.0);
  EXPECT_EQ(ds_->load_stereo(95, &l, &r).code(), core::ErrorCode::kOutOfRange);
}

TEST(EurocDataset, GivenV102ImuOnlyFolder_WhenOpened_ThenNoStereoAndImuAndGt0AreRead) {
  HWR_REQUIRE_DATASET(kEurocImu40sMav0);
  auto ds = EurocDataset::open(kEurocImu40sMav0);
  ASSERT_TRUE(ds.ok()) << ds.status().to_string();
  EXPECT_FALSE(ds->has_stereo());
  EXPECT_EQ(ds->size(), 0u);
  ASSERT_EQ(ds->imu().size(), 7999u);
  EXPECT_EQ(ds->imu().front().t_ns, 1403715523912140000LL);
  EXPECT_EQ(ds->imu().back().t_ns, 1403715563902140000LL);
  ASSERT_EQ(ds->state_groundtruth().size(), 3340u);  // from gt0/data.csv
  EXPECT_EQ(ds->state_groundtruth().front().t_ns, 1403715524922140000LL);
  EXPECT_FALSE(ds->imu_calib().present);
  EXPECT_TRUE(ds->tum_groundtruth().empty());
}

// A minimal mav0 folder: the real sensor.yaml files and 2 synthetic 752x480 stereo pairs.
fs::path write_mini_mav0(const std::string& name) {
  const fs::path mav0 = scratch_dir(name) / "mav0";
  for (const char* cam : {"cam0", "cam1"}) {
    fs::create_directories(mav0 / cam / "data");
    fs::copy_file(fs::path(kEurocStaticMav0) / cam / "sensor.yaml", mav0 / cam / "sensor.yaml");
    std::string csv = "#timestamp [ns],filename\n";
    for (int k = 0; k < 2; ++k) {
      const std::string stamp = std::to_string(1000000000LL + k * 50000000LL);
      cv::imwrite((mav0 / cam / "data" / (stamp + ".png")).string(),
                  cv::Mat(480, 752, CV_8UC1, cv::Scalar(80 + k)));
      csv += stamp + "," + stamp + ".png\n";
    }
    write_text(mav0 / cam / "data.csv", csv);
  }
  write_text(mav0 / "imu0" / "data.csv",
             "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n1000000000,0,0,0,0,0,9.81\n");
  return mav0;
}

TEST(EurocDataset, GivenAMinimalFolder_WhenOpened_ThenItReplaysWithoutOptionalParts) {
  HWR_REQUIRE_DATASET(kEurocStaticMav0);
  const fs::path mav0 = write_mini_mav0("mini");
  auto ds = EurocDataset::open(mav0.string());
  ASSERT_TRUE(ds.ok()) << ds.status().to_string();
  EXPECT_EQ(ds->size(), 2u);
  EXPECT_EQ(ds->imu().size(), 1u);
  EXPECT_TRUE(ds->state_groundtruth().empty());
  cv::Mat l, r;
  ASSERT_TRUE(ds->load_stereo(1, &l, &r).ok());
  EXPECT_EQ(l.at<uint8_t>(0, 0), 81);
}

TEST(EurocDataset, GivenMissingFolders_WhenOpened_ThenOneLineErrorNamesThem) {
  HWR_REQUIRE_DATASET(kEurocStaticMav0);
  expect_one_line_error(EurocDataset::open("/nonexistent/hwr/mav0").status(),
                        "/nonexistent/hwr/mav0: EuRoC mav0 folder not found");
  const fs::path mav0 = write_mini_mav0("no_cam1");
  fs::remove_all(mav0 / "cam1");
  expect_one_line_error(EurocDataset::open(mav0.string()).status(),
                        "/cam1: camera folder not found (cam0 exists");
  const fs::path mav0b = write_mini_mav0("no_imu");
  fs::remove_all(mav0b / "imu0");
  expect_one_line_error(EurocDataset::open(mav0b.string()).status(), "/imu0/data.csv: file not found");
}

TEST(EurocDataset, GivenBadSensorYaml_WhenOpened_ThenTheFileAndKeyAreNamed) {
  HWR_REQUIRE_DATASET(kEurocStaticMav0);
  const fs::path mav0 = write_mini_mav0("bad_yaml");
  const std::string yaml = (mav0 / "cam0" / "sensor.yaml").string();
  const std::string base =
      "%YAML:1.0\nsensor_type: camera\nunknown_vendor_key: [1, 2]\n"
      "T_BS:\n  cols: 4\n  rows: 4\n  data: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]\n"
      "rate_hz: 20\nresolution: [752, 480]\ncamera_model: pinhole\n"
      "distortion_model: radial-tangential\ndistortion_coefficients: [0, 0, 0, 0]\n";
  // Unknown keys in a third-party file are fine.
  write_text(yaml, base + "intrinsics: [450, 450, 376, 240]\n");
  ASSERT_TRUE(EurocDataset::open(mav0.string()).ok());

  write_text(yaml, base + "intrinsics: [450, 450, 376]\n");
  expect_one_line_error(EurocDataset::open(mav0.string()).status(),
                        yaml + ":13: key 'intrinsics': expected 4 numbers, got 3");
  write_text(yaml, base);
  expect_one_line_error(EurocDataset::open(mav0.string()).status(), "key 'intrinsics': required but missing");
  write_text(yaml, base + "intrinsics: [450, fast, 376, 240]\n");
  expect_one_line_error(EurocDataset::open(mav0.string()).status(),
                        "key 'intrinsics': element 1: expected a number");
  std::string no_rigid = base;
  no_rigid.replace(no_rigid.find("[1, 0, 0, 0"), 4, "[2, 0");
  write_text(yaml, no_rigid + "intrinsics: [450, 450, 376, 240]\n");
  expect_one_line_error(EurocDataset::open(mav0.string()).status(), "key 'T_BS' is not a rigid transform");
  std::string fisheye = base;
  fisheye.replace(fisheye.find("radial-tangential"), 17, "equidistant");
  write_text(yaml, fisheye + "intrinsics: [450, 450, 376, 240]\n");
  expect_one_line_error(EurocDataset::open(mav0.string()).status(),
                        "distortion_model 'equidistant' is not supported");
  write_text(yaml, "%YAML:1.0\nintrinsics: [1, 2\n");
  expect_one_line_error(EurocDataset::open(mav0.string()).status(), "YAML syntax error");
}

TEST(EurocDataset, GivenBadCameraCsvOrImages_WhenOpenedOrLoaded_ThenErrorsNameFileAndLine) {
  HWR_REQUIRE_DATASET(kEurocStaticMav0);
  const fs::path mav0 = write_mini_mav0("bad_csv");
  write_text(mav0 / "cam1" / "data.csv", "#timestamp [ns],filename\n1000000000;1000000000.png\n");
  expect_one_line_error(EurocDataset::open(mav0.string()).status(),
                        (mav0 / "cam1" / "data.csv").string() + ":2: expected 2 comma-separated fields");

  const fs::path mav0b = write_mini_mav0("bad_png");
  const fs::path png = mav0b / "cam0" / "data" / "1000000000.png";
  testing::write_truncated_copy(fs::path(kEurocStaticMav0) / "cam0" / "data" / "1403715273262142976.png", png,
                                5000);
  auto ds = EurocDataset::open(mav0b.string());
  ASSERT_TRUE(ds.ok()) << ds.status().to_string();
  cv::Mat l, r;
  const core::Status st = ds->load_stereo(0, &l, &r);
  EXPECT_EQ(st.code(), core::ErrorCode::kCorruptData);
  expect_one_line_error(st, png.string() + ": cannot decode image (truncated or corrupt file, 5000 bytes)");

  cv::imwrite(png.string(), cv::Mat(240, 376, CV_8UC1, cv::Scalar(1)));
  expect_one_line_error(ds->load_stereo(0, &l, &r),
                        png.string() + ": image is 376x240 8UC1, sensor.yaml says 752x480");
  fs::remove(png);
  expect_one_line_error(ds->load_stereo(0, &l, &r), png.string() + ": image file not found");
}

}  // namespace
}  // namespace hwr::hal
