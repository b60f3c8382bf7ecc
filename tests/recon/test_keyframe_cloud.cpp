// Keyframe clouds (issue #4 item 1). Oracles: a fronto-parallel plane at a known depth seen from a
// known pose must land exactly on the world plane; invalid, out-of-range and edge pixels are
// counted and never emitted; the arena bounds memory.

#include <cmath>
#include <limits>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "hwr/core/alloc_counter.hpp"
#include "hwr/core/arena.hpp"
#include "hwr/recon/keyframe_cloud.hpp"

namespace hwr::recon {
namespace {

hal::PinholeIntrinsics intrinsics() {
  hal::PinholeIntrinsics K;
  K.width = 64;
  K.height = 48;
  K.fx = K.fy = 50.0;
  K.cx = 31.5;
  K.cy = 23.5;
  return K;
}

TEST(KeyframeCloud, GivenAPlaneSeenFromAPoseThenEveryPointLiesOnTheWorldPlane) {
  const hal::PinholeIntrinsics K = intrinsics();
  cv::Mat depth(K.height, K.width, CV_32FC1, cv::Scalar(2.0f));
  cv::Mat bgr(K.height, K.width, CV_8UC3, cv::Scalar(10, 20, 30));
  // Camera 1.5 m above the world origin looking along world +x (z_cam = x_world, x_cam = -y_world,
  // y_cam = -z_world): the plane z_cam = 2 is the world plane x = 2.
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  T_world_cam.linear() << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  T_world_cam.translation() = Eigen::Vector3d(0, 0, 1.5);
  KeyframeCloudConfig cfg;
  cfg.stride_px = 1;
  core::Arena arena(keyframe_cloud_capacity_bytes(K.width, K.height, cfg));
  auto cloud = build_keyframe_cloud(bgr, depth, K, T_world_cam, cfg, &arena);
  ASSERT_TRUE(cloud.ok()) << cloud.status().message();
  // The border pixels' clamped neighbour is themselves: nothing is an edge on a flat plane.
  EXPECT_EQ(cloud->size, K.width * K.height);
  EXPECT_EQ(cloud->stats.kept, cloud->size);
  double max_err = 0;
  for (int i = 0; i < cloud->size; ++i) {
    const CloudPoint& p = cloud->points[i];
    max_err = std::max(max_err, std::abs(p.x_m - 2.0));
    EXPECT_EQ(p.r, 30);
    EXPECT_EQ(p.g, 20);
    EXPECT_EQ(p.b, 10);
  }
  EXPECT_LT(max_err, 1e-5);
  // Pixel (0, 0): p_cam = (-31.5 * 2 / 50, -23.5 * 2 / 50, 2) -> world (2, 1.26, 1.5 + 0.94).
  EXPECT_NEAR(cloud->points[0].y_m, 1.26, 1e-5);
  EXPECT_NEAR(cloud->points[0].z_m, 2.44, 1e-5);
}

TEST(KeyframeCloud, GivenInvalidFarAndEdgePixelsThenTheyAreCountedAndDropped) {
  const hal::PinholeIntrinsics K = intrinsics();
  cv::Mat depth(K.height, K.width, CV_32FC1, cv::Scalar(2.0f));
  depth(cv::Rect(0, 0, 8, 8)).setTo(std::numeric_limits<float>::quiet_NaN());
  depth(cv::Rect(20, 0, 4, 4)).setTo(0.0f);
  depth(cv::Rect(40, 30, 10, 10)).setTo(20.0f);  // beyond max_depth_m
  depth(cv::Rect(0, 40, 64, 8)).setTo(3.0f);     // a step: rows 39 and 40 are edge pixels
  KeyframeCloudConfig cfg;
  cfg.stride_px = 1;
  core::Arena arena(keyframe_cloud_capacity_bytes(K.width, K.height, cfg));
  auto cloud = build_keyframe_cloud(cv::Mat(), depth, K, Eigen::Isometry3d::Identity(), cfg, &arena);
  ASSERT_TRUE(cloud.ok()) << cloud.status().message();
  const KeyframeCloudStats& st = cloud->stats;
  EXPECT_EQ(st.sampled, K.width * K.height);
  EXPECT_EQ(st.invalid, 64 + 16);
  EXPECT_EQ(st.out_of_range, 100);
  EXPECT_GE(st.edges, 2 * 64 - 10);  // both sides of the step, except under the far block
  EXPECT_EQ(st.sampled, st.invalid + st.out_of_range + st.edges + st.kept);
  for (int i = 0; i < cloud->size; ++i) {
    const CloudPoint& p = cloud->points[i];
    EXPECT_TRUE(std::isfinite(p.x_m) && std::isfinite(p.y_m) && std::isfinite(p.z_m));
    EXPECT_TRUE(std::abs(p.z_m - 2.0f) < 1e-6f || std::abs(p.z_m - 3.0f) < 1e-6f) << p.z_m;
    EXPECT_EQ(p.r, 128);
  }
}

TEST(KeyframeCloud, GivenEdgeKeepsNearerThenOnlyTheFarSideOfADepthEdgeIsDropped) {
  // A nearer block (1 m) on a 2 m wall, and a hole: the block's outermost pixels stay, the wall's
  // pixels beside it go, and nothing is dropped for being next to the hole.
  const hal::PinholeIntrinsics K = intrinsics();
  cv::Mat depth(K.height, K.width, CV_32FC1, cv::Scalar(2.0f));
  depth(cv::Rect(20, 10, 10, 10)).setTo(1.0f);
  depth(cv::Rect(50, 30, 4, 4)).setTo(0.0f);
  KeyframeCloudConfig cfg;
  cfg.stride_px = 1;
  cfg.edge_keeps_nearer = true;
  core::Arena arena(keyframe_cloud_capacity_bytes(K.width, K.height, cfg));
  auto cloud = build_keyframe_cloud(cv::Mat(), depth, K, Eigen::Isometry3d::Identity(), cfg, &arena);
  ASSERT_TRUE(cloud.ok()) << cloud.status().message();
  // The block's 100 pixels all kept; its 4-neighbour ring on the wall (4 x 10) dropped.
  int block = 0;
  for (int i = 0; i < cloud->size; ++i) block += std::abs(cloud->points[i].z_m - 1.0f) < 1e-6f;
  EXPECT_EQ(block, 100);
  EXPECT_EQ(cloud->stats.edges, 40);
  EXPECT_EQ(cloud->stats.invalid, 16);
  EXPECT_EQ(cloud->stats.kept, K.width * K.height - 40 - 16);
  // The default drops both sides and the hole's ring: 36 block pixels (its border) too.
  cfg.edge_keeps_nearer = false;
  arena.reset();
  auto both = build_keyframe_cloud(cv::Mat(), depth, K, Eigen::Isometry3d::Identity(), cfg, &arena);
  ASSERT_TRUE(both.ok());
  EXPECT_EQ(both->stats.edges, 40 + 36 + 16);
}

TEST(KeyframeCloud, GivenAStrideThenEveryStrideThPixelIsSampled) {
  const hal::PinholeIntrinsics K = intrinsics();
  cv::Mat depth(K.height, K.width, CV_32FC1, cv::Scalar(1.0f));
  KeyframeCloudConfig cfg;
  cfg.stride_px = 3;
  core::Arena arena(keyframe_cloud_capacity_bytes(K.width, K.height, cfg));
  auto cloud = build_keyframe_cloud(cv::Mat(), depth, K, Eigen::Isometry3d::Identity(), cfg, &arena);
  ASSERT_TRUE(cloud.ok());
  EXPECT_EQ(cloud->stats.sampled, 22 * 16);
  EXPECT_EQ(cloud->size, 22 * 16);
}

TEST(KeyframeCloud, GivenAFullArenaOrBadInputsThenClearErrorsAndNothingWritten) {
  const hal::PinholeIntrinsics K = intrinsics();
  cv::Mat depth(K.height, K.width, CV_32FC1, cv::Scalar(1.0f));
  KeyframeCloudConfig cfg;
  core::Arena small(256);
  auto full = build_keyframe_cloud(cv::Mat(), depth, K, Eigen::Isometry3d::Identity(), cfg, &small);
  ASSERT_FALSE(full.ok());
  EXPECT_EQ(full.status().code(), core::ErrorCode::kOutOfRange);
  EXPECT_NE(full.status().message().find("arena"), std::string::npos) << full.status().message();
  EXPECT_EQ(small.used_bytes(), 0u);

  core::Arena arena(keyframe_cloud_capacity_bytes(K.width, K.height, cfg));
  cv::Mat depth16(K.height, K.width, CV_16UC1, cv::Scalar(1000));
  EXPECT_FALSE(build_keyframe_cloud(cv::Mat(), depth16, K, Eigen::Isometry3d::Identity(), cfg, &arena).ok());
  cv::Mat small_depth(10, 10, CV_32FC1, cv::Scalar(1.0f));
  EXPECT_FALSE(
      build_keyframe_cloud(cv::Mat(), small_depth, K, Eigen::Isometry3d::Identity(), cfg, &arena).ok());
  cv::Mat grey(K.height, K.width, CV_8UC1);
  EXPECT_FALSE(build_keyframe_cloud(grey, depth, K, Eigen::Isometry3d::Identity(), cfg, &arena).ok());
  hal::PinholeIntrinsics bad = K;
  bad.fx = 0;
  EXPECT_FALSE(build_keyframe_cloud(cv::Mat(), depth, bad, Eigen::Isometry3d::Identity(), cfg, &arena).ok());
  KeyframeCloudConfig bad_cfg;
  bad_cfg.max_depth_m = 0.1f;
  EXPECT_FALSE(
      build_keyframe_cloud(cv::Mat(), depth, K, Eigen::Isometry3d::Identity(), bad_cfg, &arena).ok());
  EXPECT_EQ(arena.used_bytes(), 0u);
}

TEST(KeyframeCloud, GivenAPreallocatedArenaThenBuildingAllocatesNothing) {
  const hal::PinholeIntrinsics K = intrinsics();
  cv::Mat depth(K.height, K.width, CV_32FC1, cv::Scalar(1.5f));
  KeyframeCloudConfig cfg;
  core::Arena arena(2 * keyframe_cloud_capacity_bytes(K.width, K.height, cfg));
  core::AllocationScope scope;
  for (int i = 0; i < 10; ++i) {
    arena.reset();
    auto cloud = build_keyframe_cloud(cv::Mat(), depth, K, Eigen::Isometry3d::Identity(), cfg, &arena);
    ASSERT_TRUE(cloud.ok());
  }
  EXPECT_EQ(scope.allocations(), 0u);
}

}  // namespace
}  // namespace hwr::recon
