// TUM RGB-D replay (hal/tum_dataset.hpp) on the real fr3/teddy frames and on folders written here.

#include <algorithm>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "hal_test_util.hpp"
#include "hwr/core/log.hpp"
#include "hwr/hal/tum_dataset.hpp"

namespace hwr::hal {
namespace {

namespace fs = std::filesystem;
using testing::expect_one_line_error;
using testing::kTeddyDir;
using testing::scratch_dir;
using testing::write_text;

class TumTeddy : public ::testing::Test {
 protected:
  void SetUp() override {
    HWR_REQUIRE_DATASET(kTeddyDir);
    auto ds = TumDataset::open(kTeddyDir);
    ASSERT_TRUE(ds.ok()) << ds.status().to_string();
    ds_ = std::move(ds).value();
  }
  std::optional<TumDataset> ds_;
};

TEST_F(TumTeddy, GivenTheTeddyFolder_WhenOpened_ThenListsAssociationAndGroundTruthMatchTheFiles) {
  // rgb.txt and depth.txt list 200 frames each; TUM's associate.py (max 0.02 s) pairs 193 of them.
  EXPECT_EQ(ds_->rgb_count(), 200u);
  EXPECT_EQ(ds_->depth_count(), 200u);
  ASSERT_EQ(ds_->size(), 193u);
  EXPECT_EQ(ds_->frame_time_ns(0), 1341841873273798000LL);
  EXPECT_EQ(ds_->depth_time_ns(0), 1341841873273820000LL);
  EXPECT_EQ(ds_->frame_time_ns(192), 1341841879970851000LL);
  EXPECT_EQ(ds_->depth_time_ns(192), 1341841879970889000LL);
  EXPECT_EQ(ds_->rgb_path(0), kTeddyDir + "/rgb/1341841873.273798.png");
  for (size_t i = 0; i < ds_->size(); ++i) {
    EXPECT_LT(std::abs(ds_->frame_time_ns(i) - ds_->depth_time_ns(i)), 20'000'000) << i;
    if (i > 0) {
      EXPECT_GT(ds_->frame_time_ns(i), ds_->frame_time_ns(i - 1));
    }
  }
  ASSERT_EQ(ds_->groundtruth().size(), 8080u);
  EXPECT_EQ(ds_->groundtruth().front().t_ns, 1341841873415100000LL);
  EXPECT_TRUE(ds_->accelerometer().empty());  // fr3 has no accelerometer.txt
}

TEST_F(TumTeddy, GivenFrame0_WhenLoaded_ThenImagesSizesIntrinsicsAndMetricDepthAreRight) {
  RgbdFrame f;
  ASSERT_TRUE(ds_->load_frame(0, &f).ok());
  EXPECT_EQ(f.t_ns, 1341841873273798000LL);
  EXPECT_EQ(f.seq, 0u);
  ASSERT_EQ(f.bgr.type(), CV_8UC3);
  ASSERT_EQ(f.depth_m.type(), CV_32FC1);
  EXPECT_EQ(f.bgr.size(), cv::Size(640, 480));
  EXPECT_EQ(f.depth_m.size(), cv::Size(640, 480));
  EXPECT_TRUE(f.right_gray.empty());
  EXPECT_DOUBLE_EQ(f.intrinsics.fx, 535.4);
  EXPECT_DOUBLE_EQ(f.intrinsics.fy, 539.2);
  EXPECT_DOUBLE_EQ(f.intrinsics.cx, 320.1);
  EXPECT_DOUBLE_EQ(f.intrinsics.cy, 247.6);

  // Oracle: the raw 16-bit PNG read independently; metres = raw / 5000, raw 0 = invalid.
  const cv::Mat raw = cv::imread(ds_->depth_path(0), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(raw.type(), CV_16UC1);
  const cv::Mat colour = cv::imread(ds_->rgb_path(0), cv::IMREAD_COLOR);
  EXPECT_EQ(cv::norm(colour, f.bgr, cv::NORM_INF), 0.0);
  uint32_t zeros = 0;
  std::vector<float> valid;
  for (int y = 0; y < raw.rows; ++y) {
    for (int x = 0; x < raw.cols; ++x) {
      const uint16_t r = raw.at<uint16_t>(y, x);
      const float d = f.depth_m.at<float>(y, x);
      if (r == 0) {
        ++zeros;
        ASSERT_EQ(d, 0.0f);
      } else {
        ASSERT_NEAR(d, r / 5000.0, 1e-6);
        valid.push_back(d);
      }
    }
  }
  EXPECT_EQ(f.invalid_depth_px, zeros);
  ASSERT_GT(valid.size(), raw.total() / 2) << "most of a Kinect frame has depth";
  std::nth_element(valid.begin(), valid.begin() + static_cast<long>(valid.size() / 2), valid.end());
  const float median = valid[valid.size() / 2];
  // A teddy bear on a table seen from about a metre or two: Kinect depth 0.5..4 m.
  EXPECT_GT(median, 0.5f);
  EXPECT_LT(median, 4.0f);
}

TEST_F(TumTeddy, GivenAnUnmatchedColourFrame_WhenLoaded_ThenSeqShowsTheGap) {
  // Colour frames 0..199 with 7 unpaired; seq is the colour index, so seq of the last pair is 199.
  RgbdFrame f;
  ASSERT_TRUE(ds_->load_frame(ds_->size() - 1, &f).ok());
  EXPECT_EQ(f.seq, 199u);
  EXPECT_EQ(ds_->load_frame(ds_->size(), &f).code(), core::ErrorCode::kOutOfRange);
}

// A small TUM-layout folder, as our simulator writes it: 3 colour and 3 depth frames.
struct MiniTum {
  fs::path dir;
  cv::Mat depth_raw;  // CV_16U, scale 1000
};

MiniTum write_mini_tum(const std::string& name) {
  MiniTum m;
  m.dir = scratch_dir(name);
  cv::Mat bgr(48, 64, CV_8UC3, cv::Scalar(10, 20, 30));
  m.depth_raw = cv::Mat(48, 64, CV_16UC1, cv::Scalar(1500));
  m.depth_raw(cv::Rect(0, 0, 8, 4)).setTo(0);  // 32 invalid pixels
  fs::create_directories(m.dir / "rgb");
  fs::create_directories(m.dir / "depth");
  std::string rgb_txt = "# color images\n# timestamp filename\n";
  std::string depth_txt = "# depth maps\n";
  const char* stamps[3] = {"10.000000", "10.100000", "10.200000"};
  // Depth 5 ms after colour for frames 0 and 1, 50 ms for frame 2 (too far: unpaired).
  const char* dstamps[3] = {"10.005000", "10.105000", "10.250000"};
  for (int k = 0; k < 3; ++k) {
    cv::imwrite((m.dir / "rgb" / (std::string(stamps[k]) + ".png")).string(), bgr);
    cv::imwrite((m.dir / "depth" / (std::string(dstamps[k]) + ".png")).string(), m.depth_raw);
    rgb_txt += std::string(stamps[k]) + " rgb/" + stamps[k] + ".png\n";
    depth_txt += std::string(dstamps[k]) + " depth/" + dstamps[k] + ".png\n";
  }
  write_text(m.dir / "rgb.txt", rgb_txt);
  write_text(m.dir / "depth.txt", depth_txt);
  write_text(m.dir / "groundtruth.txt",
             "# t tx ty tz qx qy qz qw\n10.0 1 2 3 0 0 0 1\n10.1 1 2 3.5 0 0 0 1\n");
  write_text(m.dir / "accelerometer.txt",
             "# accelerometer data\n10.000 0.1 -9.8 0.2\n10.010 0.0 -9.81 0.1\n");
  return m;
}

TumDatasetOptions mini_options() {
  TumDatasetOptions o;
  o.intrinsics.width = 64;
  o.intrinsics.height = 48;
  o.intrinsics.fx = o.intrinsics.fy = 50;
  o.intrinsics.cx = 31.5;
  o.intrinsics.cy = 23.5;
  o.depth_scale = 1000;
  return o;
}

TEST(TumDataset, GivenASimulatorStyleFolder_WhenOpenedWithItsOptions_ThenPairsDepthScaleAndSideFilesApply) {
  const MiniTum m = write_mini_tum("mini");
  auto ds = TumDataset::open(m.dir.string(), mini_options());
  ASSERT_TRUE(ds.ok()) << ds.status().to_string();
  ASSERT_EQ(ds->size(), 2u);  // the third depth frame is 50 ms off
  EXPECT_EQ(ds->frame_time_ns(1), 10'100'000'000LL);
  EXPECT_EQ(ds->depth_time_ns(1), 10'105'000'000LL);
  ASSERT_EQ(ds->groundtruth().size(), 2u);
  EXPECT_DOUBLE_EQ(ds->groundtruth()[1].T_world_body.translation().z(), 3.5);
  ASSERT_EQ(ds->accelerometer().size(), 2u);
  EXPECT_EQ(ds->accelerometer()[1].t_ns, 10'010'000'000LL);
  EXPECT_EQ(ds->accelerometer()[1].accel_mps2, Eigen::Vector3d(0.0, -9.81, 0.1));

  RgbdFrame f;
  ASSERT_TRUE(ds->load_frame(1, &f).ok());
  EXPECT_EQ(f.invalid_depth_px, 32u);
  EXPECT_FLOAT_EQ(f.depth_m.at<float>(47, 63), 1.5f);  // 1500 / 1000
  EXPECT_EQ(f.depth_m.at<float>(0, 0), 0.0f);
  EXPECT_DOUBLE_EQ(f.intrinsics.fx, 50);
  EXPECT_EQ(f.bgr.at<cv::Vec3b>(5, 5), cv::Vec3b(10, 20, 30));

  // A wider association window pairs the third frame too.
  TumDatasetOptions wide = mini_options();
  wide.max_association_dt_s = 0.06;
  auto ds_wide = TumDataset::open(m.dir.string(), wide);
  ASSERT_TRUE(ds_wide.ok());
  EXPECT_EQ(ds_wide->size(), 3u);
}

TEST(TumDataset, GivenMissingFolderOrFiles_WhenOpened_ThenOneLineErrorNamesThem) {
  auto none = TumDataset::open("/nonexistent/hwr/tum");
  EXPECT_EQ(none.status().code(), core::ErrorCode::kNotFound);
  expect_one_line_error(none.status(), "/nonexistent/hwr/tum: TUM dataset folder not found");

  const MiniTum m = write_mini_tum("missing_files");
  fs::remove(m.dir / "depth.txt");
  expect_one_line_error(TumDataset::open(m.dir.string(), mini_options()).status(),
                        (m.dir / "depth.txt").string() + ": file not found");

  const MiniTum m2 = write_mini_tum("missing_image");
  fs::remove(m2.dir / "rgb" / "10.100000.png");
  auto st = TumDataset::open(m2.dir.string(), mini_options()).status();
  EXPECT_EQ(st.code(), core::ErrorCode::kNotFound);
  expect_one_line_error(st, (m2.dir / "rgb.txt").string() + ":4: listed image 'rgb/10.100000.png' not found");

  const MiniTum m3 = write_mini_tum("missing_gt");
  fs::remove(m3.dir / "groundtruth.txt");
  auto ok = TumDataset::open(m3.dir.string(), mini_options());
  ASSERT_TRUE(ok.ok()) << "ground truth is optional by default";
  EXPECT_TRUE(ok->groundtruth().empty());
  TumDatasetOptions strict = mini_options();
  strict.require_groundtruth = true;
  expect_one_line_error(TumDataset::open(m3.dir.string(), strict).status(),
                        "groundtruth.txt: ground truth file not found");
}

TEST(TumDataset, GivenMalformedListLines_WhenOpened_ThenErrorsNameFileAndLine) {
  struct Case {
    const char* file;
    const char* text;
    const char* message;
  };
  const Case cases[] = {
      {"rgb.txt", "# c\n10.0 rgb/10.000000.png extra\n",
       "rgb.txt:2: expected 'timestamp filename', got 3 fields"},
      {"rgb.txt", "10.0\n", "rgb.txt:1: expected 'timestamp filename', got 1 fields"},
      {"depth.txt", "ten depth/10.005000.png\n",
       "depth.txt:1: bad timestamp 'ten' (expected decimal seconds)"},
      {"depth.txt", "10.105000 depth/10.105000.png\n10.005000 depth/10.005000.png\n",
       "depth.txt:2: timestamps must increase"},
      {"groundtruth.txt", "10.0 1 2 3 0 0 1\n", "groundtruth.txt:1: expected 8 numbers"},
      {"accelerometer.txt", "10.0 0 0 x\n", "accelerometer.txt:1: field 4: not a finite number: 'x'"},
      {"accelerometer.txt", "10.0 0 0\n", "accelerometer.txt:1: expected 'timestamp ax ay az', got 3 fields"},
  };
  int k = 0;
  for (const Case& c : cases) {
    const MiniTum m = write_mini_tum("bad_list_" + std::to_string(k++));
    write_text(m.dir / c.file, c.text);
    const core::Status st = TumDataset::open(m.dir.string(), mini_options()).status();
    EXPECT_EQ(st.code(), core::ErrorCode::kParseError) << c.message;
    expect_one_line_error(st, c.message);
  }
}

TEST(TumDataset, GivenListsThatNeverMeet_WhenOpened_ThenNoPairsIsAnError) {
  const MiniTum m = write_mini_tum("no_pairs");
  TumDatasetOptions o = mini_options();
  o.max_association_dt_s = 0.001;
  expect_one_line_error(TumDataset::open(m.dir.string(), o).status(), "no colour/depth pairs closer than");
}

TEST(TumDataset, GivenATruncatedRealDepthPng_WhenLoaded_ThenCorruptDataNotACrash) {
  HWR_REQUIRE_DATASET(kTeddyDir);
  const fs::path dir = scratch_dir("truncated");
  const std::string rgb = "rgb/1341841873.273798.png";
  const std::string depth = "depth/1341841873.273820.png";
  fs::create_directories(dir / "rgb");
  fs::copy_file(fs::path(kTeddyDir) / rgb, dir / rgb);
  const auto full = fs::file_size(fs::path(kTeddyDir) / depth);
  testing::write_truncated_copy(fs::path(kTeddyDir) / depth, dir / depth, static_cast<size_t>(full / 2));
  write_text(dir / "rgb.txt", "1341841873.273798 " + rgb + "\n");
  write_text(dir / "depth.txt", "1341841873.273820 " + depth + "\n");
  auto ds = TumDataset::open(dir.string());
  ASSERT_TRUE(ds.ok()) << ds.status().to_string();
  RgbdFrame f;
  const core::Status st = ds->load_frame(0, &f);  // libpng may print its own diagnostic here
  EXPECT_EQ(st.code(), core::ErrorCode::kCorruptData);
  expect_one_line_error(st, (dir / depth).string() + ": cannot decode image (truncated or corrupt file");

  // A file that is not a PNG at all, and an empty one.
  write_text(dir / depth, "this is not a png");
  expect_one_line_error(ds->load_frame(0, &f), "cannot decode image");
  write_text(dir / depth, "");
  expect_one_line_error(ds->load_frame(0, &f), "cannot decode image (truncated or corrupt file, 0 bytes)");
}

TEST(TumDataset, GivenAn8BitDepthPng_WhenLoaded_ThenTheWrongTypeIsNamed) {
  const MiniTum m = write_mini_tum("depth8");
  cv::Mat depth8(48, 64, CV_8UC1, cv::Scalar(100));
  cv::imwrite((m.dir / "depth" / "10.005000.png").string(), depth8);
  auto ds = TumDataset::open(m.dir.string(), mini_options());
  ASSERT_TRUE(ds.ok());
  RgbdFrame f;
  const core::Status st = ds->load_frame(0, &f);
  EXPECT_EQ(st.code(), core::ErrorCode::kParseError);
  expect_one_line_error(st, "10.005000.png: depth image is 64x48 8UC1, expected a 16-bit single-channel PNG");
}

TEST(TumDataset, GivenMismatchedImageSizes_WhenLoaded_ThenBothSizesAreNamed) {
  const MiniTum m = write_mini_tum("sizes");
  cv::imwrite((m.dir / "depth" / "10.005000.png").string(), cv::Mat(24, 32, CV_16UC1, cv::Scalar(1000)));
  auto ds = TumDataset::open(m.dir.string(), mini_options());
  ASSERT_TRUE(ds.ok());
  RgbdFrame f;
  expect_one_line_error(ds->load_frame(0, &f), "depth image is 32x24 16UC1 but colour image");

  // Images consistent with each other but not with the configured camera.
  TumDatasetOptions other = mini_options();
  other.intrinsics.width = 640;
  other.intrinsics.height = 480;
  auto ds2 = TumDataset::open(m.dir.string(), other);
  ASSERT_TRUE(ds2.ok());
  expect_one_line_error(ds2->load_frame(1, &f), "image is 64x48 8UC3, camera is 640x480");
}

}  // namespace
}  // namespace hwr::hal
