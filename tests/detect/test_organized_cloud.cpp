// OrganizedCloud: eq. 3 at a stride, invalid pixels, errors, no allocation in build().
#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "hwr/core/alloc_counter.hpp"
#include "hwr/detect/organized_cloud.hpp"

namespace hwr::detect {
namespace {

hal::PinholeIntrinsics intrinsics(int w, int h) {
  hal::PinholeIntrinsics K;
  K.width = w;
  K.height = h;
  K.fx = 525.0;
  K.fy = 520.0;
  K.cx = 0.5 * (w - 1) + 3.25;  // off-centre: a swapped cx/cy or u/v shows
  K.cy = 0.5 * (h - 1) - 2.5;
  return K;
}

TEST(OrganizedCloud, GivenADepthImageThenEachValidPointIsEquation3AtItsGridPixel) {
  const hal::PinholeIntrinsics K = intrinsics(61, 47);  // not a multiple of the stride
  OrganizedCloudConfig config;
  config.stride_px = 3;
  auto cloud = OrganizedCloud::create(config, K);
  ASSERT_TRUE(cloud.ok()) << cloud.status().to_string();
  EXPECT_EQ(cloud->width(), 21);   // ceil(61 / 3)
  EXPECT_EQ(cloud->height(), 16);  // ceil(47 / 3)

  cv::Mat depth(K.height, K.width, CV_32FC1);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> z(0.4f, 3.4f);
  for (int v = 0; v < K.height; ++v) {
    for (int u = 0; u < K.width; ++u) depth.at<float>(v, u) = z(rng);
  }
  ASSERT_TRUE(cloud->build(depth).ok());
  EXPECT_EQ(cloud->valid_count(), 21 * 16);
  for (int y = 0; y < cloud->height(); ++y) {
    for (int x = 0; x < cloud->width(); ++x) {
      const int u = 3 * x, v = 3 * y;
      const double zd = depth.at<float>(v, u);
      ASSERT_TRUE(cloud->valid(x, y));
      const Eigen::Vector3f& p = cloud->point(x, y);
      EXPECT_NEAR(p.x(), (u - K.cx) * zd / K.fx, 1e-6);
      EXPECT_NEAR(p.y(), (v - K.cy) * zd / K.fy, 1e-6);
      EXPECT_NEAR(p.z(), zd, 1e-6);
    }
  }
}

TEST(OrganizedCloud, GivenNaNInfZeroNegativeOrOutOfRangeDepthThenThosePointsAreInvalidAndNotCounted) {
  const hal::PinholeIntrinsics K = intrinsics(8, 2);
  OrganizedCloudConfig config;
  config.stride_px = 1;
  config.min_depth_m = 0.3f;
  config.max_depth_m = 3.5f;
  auto cloud = OrganizedCloud::create(config, K);
  ASSERT_TRUE(cloud.ok());
  cv::Mat depth(K.height, K.width, CV_32FC1, cv::Scalar(1.0f));
  const float bad[8] = {std::numeric_limits<float>::quiet_NaN(),
                        std::numeric_limits<float>::infinity(),
                        -std::numeric_limits<float>::infinity(),
                        0.0f,
                        -1.0f,
                        0.29f,
                        3.51f,
                        1.0f};
  for (int u = 0; u < 8; ++u) depth.at<float>(0, u) = bad[u];
  depth.at<float>(1, 3) = 0.3f;  // the range's ends are valid
  depth.at<float>(1, 4) = 3.5f;
  ASSERT_TRUE(cloud->build(depth).ok());
  for (int u = 0; u < 7; ++u) EXPECT_FALSE(cloud->valid(u, 0)) << "pixel " << u << " depth " << bad[u];
  EXPECT_TRUE(cloud->valid(7, 0));
  for (int u = 0; u < 8; ++u) EXPECT_TRUE(cloud->valid(u, 1));
  EXPECT_EQ(cloud->valid_count(), 9);

  // A second build overwrites the first: nothing of it stays valid.
  depth.setTo(cv::Scalar(0.0f));
  ASSERT_TRUE(cloud->build(depth).ok());
  EXPECT_EQ(cloud->valid_count(), 0);
  EXPECT_FALSE(cloud->valid(7, 0));
}

TEST(OrganizedCloud, GivenAWrongTypeOrSizeThenBuildIsInvalidArgument) {
  const hal::PinholeIntrinsics K = intrinsics(16, 12);
  auto cloud = OrganizedCloud::create(OrganizedCloudConfig{}, K);
  ASSERT_TRUE(cloud.ok());
  EXPECT_EQ(cloud->build(cv::Mat(12, 16, CV_64FC1, cv::Scalar(1.0))).code(),
            core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(cloud->build(cv::Mat(12, 16, CV_16UC1, cv::Scalar(1000))).code(),
            core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(cloud->build(cv::Mat(12, 15, CV_32FC1, cv::Scalar(1.0f))).code(),
            core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(cloud->build(cv::Mat()).code(), core::ErrorCode::kInvalidArgument);
  EXPECT_TRUE(cloud->build(cv::Mat(12, 16, CV_32FC1, cv::Scalar(1.0f))).ok());
}

TEST(OrganizedCloud, GivenABadStrideRangeOrIntrinsicsThenCreateIsInvalidArgumentNamingIt) {
  const hal::PinholeIntrinsics K = intrinsics(16, 12);
  OrganizedCloudConfig config;
  config.stride_px = 0;
  auto bad_stride = OrganizedCloud::create(config, K);
  ASSERT_FALSE(bad_stride.ok());
  EXPECT_NE(bad_stride.status().message().find("stride_px"), std::string::npos);

  config = OrganizedCloudConfig{};
  config.min_depth_m = 2.0f;
  config.max_depth_m = 1.0f;
  auto bad_range = OrganizedCloud::create(config, K);
  ASSERT_FALSE(bad_range.ok());
  EXPECT_NE(bad_range.status().message().find("min_depth_m"), std::string::npos);

  hal::PinholeIntrinsics bad_K = K;
  bad_K.fx = 0.0;
  auto bad_intrinsics = OrganizedCloud::create(OrganizedCloudConfig{}, bad_K);
  ASSERT_FALSE(bad_intrinsics.ok());
  EXPECT_EQ(bad_intrinsics.status().code(), core::ErrorCode::kInvalidArgument);
  EXPECT_NE(bad_intrinsics.status().message().find("intrinsics"), std::string::npos);
}

TEST(OrganizedCloud, GivenACreatedCloudThenBuildAllocatesNothing) {
  const hal::PinholeIntrinsics K = intrinsics(640, 480);
  auto cloud = OrganizedCloud::create(OrganizedCloudConfig{}, K);
  ASSERT_TRUE(cloud.ok());
  const cv::Mat depth(K.height, K.width, CV_32FC1, cv::Scalar(1.5f));
  core::AllocationScope scope;
  ASSERT_TRUE(cloud->build(depth).ok());
  ASSERT_TRUE(cloud->build(depth).ok());
  EXPECT_EQ(scope.allocations(), 0u);
  EXPECT_EQ(cloud->valid_count(), 320 * 240);
}

}  // namespace
}  // namespace hwr::detect
