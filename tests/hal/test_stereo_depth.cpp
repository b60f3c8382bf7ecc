// Stereo depth (hal/stereo_depth.hpp): a synthetic fronto-parallel plane with a known disparity,
// and the real EuRoC V1_01 static-start pairs.

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "hal_test_util.hpp"
#include "hwr/hal/euroc_dataset.hpp"
#include "hwr/hal/stereo_depth.hpp"

namespace hwr::hal {
namespace {

using testing::expect_one_line_error;
using testing::kEurocStaticMav0;

PinholeIntrinsics ideal_camera(int w, int h, double f) {
  PinholeIntrinsics k;
  k.width = w;
  k.height = h;
  k.fx = k.fy = f;
  k.cx = (w - 1) / 2.0;
  k.cy = (h - 1) / 2.0;
  return k;
}

StereoRig ideal_rig(int w, int h, double f, double baseline_m) {
  StereoRig rig;
  rig.left = rig.right = ideal_camera(w, h, f);
  rig.T_left_right.translation() = Eigen::Vector3d(baseline_m, 0, 0);  // right camera at +x
  return rig;
}

// Median of the non-zero values.
double median_valid(const cv::Mat& depth_m, size_t* valid_count) {
  std::vector<float> v;
  for (int y = 0; y < depth_m.rows; ++y) {
    for (int x = 0; x < depth_m.cols; ++x) {
      if (depth_m.at<float>(y, x) > 0) v.push_back(depth_m.at<float>(y, x));
    }
  }
  *valid_count = v.size();
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

TEST(StereoDepth, GivenAFrontoParallelPlaneAtAKnownDisparity_WhenComputed_ThenDepthIsFBOverDWithin1Percent) {
  // GIVEN a textured plane seen by an ideal rig, f = 400 px, B = 0.1 m, at Z = 2 m: d = f·B/Z = 20 px.
  const int w = 320;
  const int h = 240;
  const double f = 400;
  const double B = 0.1;
  const int d = 20;
  const double z_true = f * B / d;
  cv::Mat texture(h, w + d, CV_8UC1);
  cv::RNG rng(12345);
  rng.fill(texture, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(texture, texture, cv::Size(3, 3), 0.8);
  // A point at left column x appears at right column x - d: right(x) = left(x + d).
  const cv::Mat left = texture(cv::Rect(0, 0, w, h)).clone();
  const cv::Mat right = texture(cv::Rect(d, 0, w, h)).clone();

  auto sd = StereoDepth::create(ideal_rig(w, h, f, B));
  ASSERT_TRUE(sd.ok()) << sd.status().to_string();
  EXPECT_NEAR(sd->baseline_m(), B, 1e-12);
  EXPECT_TRUE(sd->T_cam0_rect().isApprox(Eigen::Isometry3d::Identity(), 1e-12))
      << "identical parallel cameras";

  // WHEN
  RgbdFrame out;
  ASSERT_TRUE(sd->compute(left, right, 42, 7, &out).ok());

  // THEN
  EXPECT_EQ(out.t_ns, 42);
  EXPECT_EQ(out.seq, 7u);
  ASSERT_EQ(out.bgr.type(), CV_8UC3);
  ASSERT_EQ(out.depth_m.type(), CV_32FC1);
  EXPECT_EQ(out.right_gray.type(), CV_8UC1);
  EXPECT_EQ(out.depth_m.size(), cv::Size(w, h));
  size_t valid = 0;
  const double median = median_valid(out.depth_m, &valid);
  EXPECT_EQ(out.invalid_depth_px, static_cast<uint32_t>(out.depth_m.total() - valid));
  // Columns left of num_disparities cannot match; most of the rest must.
  EXPECT_GT(valid, static_cast<size_t>(0.7 * (w - 64) * h));
  EXPECT_NEAR(median, z_true, 0.01 * z_true);
  // Every valid pixel on the plane, not only the median.
  size_t within = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float z = out.depth_m.at<float>(y, x);
      if (z > 0 && std::fabs(z - z_true) < 0.01 * z_true) ++within;
    }
  }
  EXPECT_GT(within, static_cast<size_t>(0.95 * valid));
  // The rectified left image of an ideal rig is the left image.
  cv::Mat gray;
  cv::cvtColor(out.bgr, gray, cv::COLOR_BGR2GRAY);
  EXPECT_LE(
      cv::norm(gray(cv::Rect(5, 5, w - 10, h - 10)), left(cv::Rect(5, 5, w - 10, h - 10)), cv::NORM_INF),
      1.0);
}

// A colour plane: random colours, blurred a little (texture for the matcher), and its gray.
struct ColourPair {
  cv::Mat left_bgr, right_bgr, left_gray, right_gray;
};

ColourPair colour_plane(int w, int h, int d) {
  cv::Mat texture(h, w + d, CV_8UC3);
  cv::RNG rng(777);
  rng.fill(texture, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(texture, texture, cv::Size(3, 3), 0.8);
  ColourPair p;
  p.left_bgr = texture(cv::Rect(0, 0, w, h)).clone();
  p.right_bgr = texture(cv::Rect(d, 0, w, h)).clone();
  cv::cvtColor(p.left_bgr, p.left_gray, cv::COLOR_BGR2GRAY);
  cv::cvtColor(p.right_bgr, p.right_gray, cv::COLOR_BGR2GRAY);
  return p;
}

TEST(StereoDepth, GivenTheLeftColourImage_WhenComputed_ThenBgrIsItRectifiedAndTheDepthIsTheGrayPairs) {
  // GIVEN the plane of the test above in colour, an ideal rig (rectification is the identity).
  const int w = 320;
  const int h = 240;
  const ColourPair p = colour_plane(w, h, 20);
  auto sd = StereoDepth::create(ideal_rig(w, h, 400, 0.1));
  ASSERT_TRUE(sd.ok()) << sd.status().to_string();
  RgbdFrame gray_only;
  ASSERT_TRUE(sd->compute(p.left_gray, p.right_gray, 1, 2, &gray_only).ok());
  // Preallocated as SensorStreams does: written in place.
  RgbdFrame colour;
  colour.bgr.create(h, w, CV_8UC3);
  colour.depth_m.create(h, w, CV_32FC1);
  colour.right_gray.create(h, w, CV_8UC1);
  const uint8_t* bgr_buffer = colour.bgr.data;

  // WHEN
  ASSERT_TRUE(sd->compute(p.left_gray, p.right_gray, p.left_bgr, 42, 7, &colour).ok());

  // THEN matching saw the same gray pair: identical depth and right image.
  EXPECT_EQ(colour.t_ns, 42);
  EXPECT_EQ(colour.seq, 7u);
  EXPECT_EQ(cv::norm(colour.depth_m, gray_only.depth_m, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(colour.right_gray, gray_only.right_gray, cv::NORM_INF), 0.0);
  EXPECT_EQ(colour.invalid_depth_px, gray_only.invalid_depth_px);
  EXPECT_EQ(colour.intrinsics.fx, gray_only.intrinsics.fx);
  // bgr is the colour image itself (identity rectification), not gray.
  EXPECT_EQ(colour.bgr.data, bgr_buffer) << "no reallocation";
  ASSERT_EQ(colour.bgr.type(), CV_8UC3);
  const cv::Rect inner(5, 5, w - 10, h - 10);
  EXPECT_LE(cv::norm(colour.bgr(inner), p.left_bgr(inner), cv::NORM_INF), 1.0);
  EXPECT_GT(cv::norm(gray_only.bgr(inner), p.left_bgr(inner), cv::NORM_INF), 50.0) << "the gray path is gray";
}

TEST(StereoDepth, GivenARigThatNeedsRectifying_WhenColourIsGiven_ThenItGoesThroughTheLeftGraysMaps) {
  // GIVEN distortion and a rotated right eye: the left rectification is not the identity.
  const int w = 320;
  const int h = 240;
  StereoRig rig = ideal_rig(w, h, 400, 0.1);
  rig.left.distortion = {-0.2, 0.05, 0.001, -0.001, 0.0};
  rig.right.distortion = {-0.18, 0.04, 0.0, 0.0, 0.0};
  rig.T_left_right.linear() =
      Eigen::AngleAxisd(0.03, Eigen::Vector3d(0.2, 1.0, 0.1).normalized()).toRotationMatrix();
  auto sd = StereoDepth::create(rig);
  ASSERT_TRUE(sd.ok()) << sd.status().to_string();
  ASSERT_FALSE(sd->T_cam0_rect().isApprox(Eigen::Isometry3d::Identity(), 1e-3));
  const ColourPair p = colour_plane(w, h, 16);

  RgbdFrame gray_only, colour;
  ASSERT_TRUE(sd->compute(p.left_gray, p.right_gray, 0, 0, &gray_only).ok());
  ASSERT_TRUE(sd->compute(p.left_gray, p.right_gray, p.left_bgr, 0, 0, &colour).ok());

  // THEN the gray of the rectified colour is the rectified gray (both linear: equal up to rounding),
  // pixel for pixel, including where the maps leave the image (0 in both).
  cv::Mat gray_of_colour;
  cv::cvtColor(colour.bgr, gray_of_colour, cv::COLOR_BGR2GRAY);
  cv::Mat rect_gray;
  cv::extractChannel(gray_only.bgr, rect_gray, 0);
  EXPECT_LE(cv::norm(gray_of_colour, rect_gray, cv::NORM_INF), 2.0);
  // And the rectified colour is not the input colour (the maps moved it).
  EXPECT_GT(cv::norm(colour.bgr, p.left_bgr, cv::NORM_INF), 50.0);
  EXPECT_EQ(cv::norm(colour.depth_m, gray_only.depth_m, cv::NORM_INF), 0.0);
}

TEST(StereoDepth, GivenAColourImageOfTheWrongSizeOrType_WhenComputed_ThenOneLineErrorAndNothingWritten) {
  auto sd = StereoDepth::create(ideal_rig(320, 240, 400, 0.1));
  ASSERT_TRUE(sd.ok());
  const cv::Mat gray(240, 320, CV_8UC1, cv::Scalar(0));
  RgbdFrame out;
  out.t_ns = -1;
  expect_one_line_error(sd->compute(gray, gray, cv::Mat(100, 100, CV_8UC3), 5, 5, &out),
                        "left colour image is 100x100");
  expect_one_line_error(sd->compute(gray, gray, cv::Mat(240, 320, CV_8UC1), 5, 5, &out),
                        "expected 320x240 8-bit BGR");
  expect_one_line_error(sd->compute(gray, gray, cv::Mat(), 5, 5, &out), "left colour image is 0x0");
  out.bgr.create(240, 320, CV_8UC3);
  expect_one_line_error(sd->compute(gray, gray, out.bgr, 5, 5, &out), "is the output frame's bgr");
  EXPECT_EQ(out.t_ns, -1);
}

TEST(StereoDepth, GivenBadRigsOrParameters_WhenCreated_ThenOneLineErrors) {
  StereoRig swapped = ideal_rig(320, 240, 400, -0.1);  // right camera on the left
  expect_one_line_error(StereoDepth::create(swapped).status(), "right camera is not to the right");
  StereoRig same_place = ideal_rig(320, 240, 400, 0.0);
  expect_one_line_error(StereoDepth::create(same_place).status(), "no baseline");
  StereoRig sizes = ideal_rig(320, 240, 400, 0.1);
  sizes.right.width = 640;
  expect_one_line_error(StereoDepth::create(sizes).status(), "left camera is 320x240, right is 640x240");
  StereoSgbmParams p;
  p.num_disparities = 40;
  expect_one_line_error(StereoDepth::create(ideal_rig(320, 240, 400, 0.1), p).status(),
                        "num_disparities must be a positive multiple of 16, got 40");
  p = StereoSgbmParams{};
  p.block_size = 4;
  expect_one_line_error(StereoDepth::create(ideal_rig(320, 240, 400, 0.1), p).status(),
                        "block_size must be odd");

  auto sd = StereoDepth::create(ideal_rig(320, 240, 400, 0.1));
  ASSERT_TRUE(sd.ok());
  RgbdFrame out;
  expect_one_line_error(sd->compute(cv::Mat(100, 100, CV_8UC1), cv::Mat(240, 320, CV_8UC1), 0, 0, &out),
                        "left image is 100x100");
}

class EurocStereo : public ::testing::Test {
 protected:
  void SetUp() override {
    HWR_REQUIRE_DATASET(kEurocStaticMav0);
    auto ds = EurocDataset::open(kEurocStaticMav0);
    ASSERT_TRUE(ds.ok()) << ds.status().to_string();
    ds_ = std::move(ds).value();
    rig_.left = ds_->cam0().intrinsics;
    rig_.right = ds_->cam1().intrinsics;
    rig_.T_left_right = ds_->T_cam0_cam1();
  }
  std::optional<EurocDataset> ds_;
  StereoRig rig_;
};

TEST_F(EurocStereo, GivenTheEurocRig_WhenRectified_ThenBaselineIsKeptAndTheRectifiedXAxisPointsAtCam1) {
  auto sd = StereoDepth::create(rig_);
  ASSERT_TRUE(sd.ok()) << sd.status().to_string();
  const Eigen::Vector3d t01 = rig_.T_left_right.translation();
  // Rectification only rotates: the baseline length is the distance between the optical centres.
  EXPECT_NEAR(sd->baseline_m(), t01.norm(), 1e-9);
  const Eigen::Matrix3d R = sd->T_cam0_rect().linear();
  EXPECT_NEAR((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-12);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  EXPECT_TRUE(sd->T_cam0_rect().translation().isZero(0));
  // In the rectified frame, cam1's centre lies on the +x axis at the baseline.
  const Eigen::Vector3d c1_rect = sd->T_cam0_rect().inverse() * t01;
  EXPECT_NEAR(c1_rect.x(), t01.norm(), 1e-9);
  EXPECT_NEAR(c1_rect.y(), 0.0, 1e-9);
  EXPECT_NEAR(c1_rect.z(), 0.0, 1e-9);
  // The two VI-sensor cameras are nearly parallel: a small rectifying rotation.
  EXPECT_LT(Eigen::AngleAxisd(R).angle(), 3.0 * M_PI / 180.0);
  const PinholeIntrinsics& k = sd->rectified_intrinsics();
  EXPECT_EQ(k.width, 752);
  EXPECT_EQ(k.height, 480);
  for (double c : k.distortion) EXPECT_EQ(c, 0.0);
}

TEST_F(EurocStereo, GivenStaticStartPairs_WhenDepthIsComputed_ThenMostPixelsHavePlausibleViconRoomDepth) {
  auto sd = StereoDepth::create(rig_);
  ASSERT_TRUE(sd.ok()) << sd.status().to_string();
  cv::Mat l, r;
  RgbdFrame out;
  for (size_t i : {size_t{0}, size_t{47}, size_t{94}}) {
    ASSERT_TRUE(ds_->load_stereo(i, &l, &r).ok());
    ASSERT_TRUE(sd->compute(l, r, ds_->frame_time_ns(i), i, &out).ok());
    EXPECT_EQ(out.t_ns, ds_->frame_time_ns(i));
    size_t valid = 0;
    const double median = median_valid(out.depth_m, &valid);
    const double valid_fraction = static_cast<double>(valid) / static_cast<double>(out.depth_m.total());
    // The Vicon room is about 8 m across; seen from inside, most surfaces are 1..8 m away.
    EXPECT_GT(valid_fraction, 0.6) << "pair " << i;
    EXPECT_GT(median, 1.0) << "pair " << i;
    EXPECT_LT(median, 8.0) << "pair " << i;
    for (int y = 0; y < out.depth_m.rows; y += 7) {
      for (int x = 0; x < out.depth_m.cols; x += 7) {
        const float z = out.depth_m.at<float>(y, x);
        ASSERT_TRUE(z == 0.0f || (z >= sd->params().min_depth_m && z <= sd->params().max_depth_m));
      }
    }
    RecordProperty("pair" + std::to_string(i) + "_valid_fraction", std::to_string(valid_fraction));
    RecordProperty("pair" + std::to_string(i) + "_median_depth_m", std::to_string(median));
  }
}

TEST_F(EurocStereo, GivenTheSameStaticScene_WhenTwoPairsSecondsApartAreMatched_ThenTheirDepthAgrees) {
  // The sensor moves 1.7 cm over the static start: the depth maps of pairs 0 and 94 must agree.
  auto sd = StereoDepth::create(rig_);
  ASSERT_TRUE(sd.ok());
  cv::Mat l, r;
  RgbdFrame a, b;
  ASSERT_TRUE(ds_->load_stereo(0, &l, &r).ok());
  ASSERT_TRUE(sd->compute(l, r, 0, 0, &a).ok());
  ASSERT_TRUE(ds_->load_stereo(94, &l, &r).ok());
  ASSERT_TRUE(sd->compute(l, r, 0, 0, &b).ok());
  size_t both = 0;
  size_t close = 0;
  for (int y = 0; y < a.depth_m.rows; ++y) {
    for (int x = 0; x < a.depth_m.cols; ++x) {
      const float za = a.depth_m.at<float>(y, x);
      const float zb = b.depth_m.at<float>(y, x);
      if (za > 0 && zb > 0) {
        ++both;
        if (std::fabs(za - zb) < 0.05f * za) ++close;
      }
    }
  }
  ASSERT_GT(both, a.depth_m.total() / 4);
  EXPECT_GT(static_cast<double>(close) / static_cast<double>(both), 0.8);
}

}  // namespace
}  // namespace hwr::hal
