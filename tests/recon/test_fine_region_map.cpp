// The fine cloud of the welding regions (recon/fine_region_map.hpp). Oracles: a brute-force
// back-projection of every pixel of a synthetic depth image tested against the region boxes (which
// pixels enter the fine map, and that nothing outside a box or beyond the depth limit does); the
// segment-frame placement of points and boxes by the closed-form transform; region association by
// box containment; the allocation counter.

#include <cmath>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "hwr/core/alloc_counter.hpp"
#include "hwr/recon/fine_region_map.hpp"

namespace hwr::recon {
namespace {

hal::PinholeIntrinsics intrinsics() {
  hal::PinholeIntrinsics K;
  K.width = 320;
  K.height = 240;
  K.fx = K.fy = 300.0;
  K.cx = 159.5;
  K.cy = 119.5;
  return K;
}

// A fronto-parallel wall at depth z0 with a step: the right half of the image 1 cm nearer, the
// bottom quarter 20 cm nearer (a depth edge: its border rows are dropped).
cv::Mat wall_depth(const hal::PinholeIntrinsics& K, float z0) {
  cv::Mat d(K.height, K.width, CV_32FC1, cv::Scalar(z0));
  for (int v = 0; v < K.height; ++v)
    for (int u = K.width / 2; u < K.width; ++u) d.at<float>(v, u) = z0 - 0.01f;
  for (int v = 3 * K.height / 4; v < K.height; ++v)
    for (int u = 0; u < K.width; ++u) d.at<float>(v, u) -= 0.2f;
  return d;
}

Eigen::Isometry3d pose(double yaw, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
               Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()).toRotationMatrix();
  T.translation() = t;
  return T;
}

WeldRegion region_at(const Eigen::Vector3d& centre_cam, const Eigen::Vector3d& half, double yaw = 0.0) {
  WeldRegion r;
  r.source = WeldRegionSource::kOperator;
  r.T_cam_region = pose(yaw, centre_cam);
  r.half_size_m = half;
  set_weld_region_label(&r, "joint");
  return r;
}

bool inside(const Eigen::Isometry3d& T_box_p, const Eigen::Vector3d& p, const Eigen::Vector3d& half) {
  const Eigen::Vector3d q = T_box_p * p;
  return std::fabs(q.x()) <= half.x() && std::fabs(q.y()) <= half.y() && std::fabs(q.z()) <= half.z();
}

// Pixels whose back-projection lies in the box (camera frame), within depth limits and not on the
// far side of the depth edge (the row above the 20 cm step, which the fine cloud's keyframe cloud
// drops: it keeps the nearer side, edge_keeps_nearer).
int brute_force_pixels(const cv::Mat& depth, const hal::PinholeIntrinsics& K,
                       const Eigen::Isometry3d& T_cam_box, const Eigen::Vector3d& half, float max_depth) {
  const Eigen::Isometry3d T_box_cam = T_cam_box.inverse();
  int n = 0;
  for (int v = 0; v < K.height; ++v)
    for (int u = 0; u < K.width; ++u) {
      const float z = depth.at<float>(v, u);
      if (!(z > 0.2f) || z > max_depth) continue;
      if (v == 3 * K.height / 4 - 1) continue;  // far side of the depth edge
      const Eigen::Vector3d p((u - K.cx) * z / K.fx, (v - K.cy) * z / K.fy, z);
      n += inside(T_box_cam, p, half);
    }
  return n;
}

FineRegionConfig small_config() {
  FineRegionConfig c;
  c.voxels = {0.0005, 100'000};  // finer than the pixel spacing: one voxel per pixel
  c.max_regions = 3;
  return c;
}

TEST(FineRegionMap, GivenARegionInViewThenExactlyThePixelsInsideItEnterTheFineMapInTheSegmentFrame) {
  const hal::PinholeIntrinsics K = intrinsics();
  auto fine = FineRegionMap::create(small_config(), K);
  ASSERT_TRUE(fine.ok()) << fine.status().message();
  const cv::Mat depth = wall_depth(K, 1.5f);
  const Eigen::Isometry3d T_world_cam = pose(0.7, Eigen::Vector3d(2.0, -1.0, 1.2));
  const Eigen::Isometry3d T_world_segment = pose(-0.4, Eigen::Vector3d(1.0, 0.5, 0.0));
  // A tilted box across the 1 cm step and the depth edge, partly outside the image.
  const WeldRegion r = region_at(Eigen::Vector3d(0.45, 0.2, 1.5), Eigen::Vector3d(0.3, 0.25, 0.05), 0.4);
  ASSERT_EQ(fine->add(r, T_world_cam), 0);
  fine->insert_keyframe(cv::Mat(), depth, T_world_cam, T_world_segment);

  const int expected = brute_force_pixels(depth, K, r.T_cam_region, r.half_size_m, 3.5f);
  ASSERT_GT(expected, 500);
  EXPECT_EQ(fine->counters().points_inserted, static_cast<uint64_t>(expected));
  EXPECT_EQ(fine->fine_map().size(), expected);  // voxels finer than the pixel spacing
  EXPECT_EQ(fine->counters().keyframes_in_view, 1u);

  std::vector<CloudPoint> pts;
  std::vector<uint32_t> counts;
  std::vector<StoredWeldRegion> regions;
  fine->take_segment(T_world_segment, &pts, &counts, &regions);
  ASSERT_EQ(static_cast<int>(pts.size()), expected);
  ASSERT_EQ(counts.size(), pts.size());
  const Eigen::Isometry3d T_region_world = (T_world_cam * r.T_cam_region).inverse();
  for (size_t i = 0; i < pts.size(); ++i) {
    EXPECT_EQ(counts[i], 1u);
    const Eigen::Vector3d p_world = T_world_segment * Eigen::Vector3d(pts[i].x_m, pts[i].y_m, pts[i].z_m);
    EXPECT_TRUE(inside(T_region_world, p_world, r.half_size_m + Eigen::Vector3d::Constant(1e-5)));
  }
  ASSERT_EQ(regions.size(), 1u);
  EXPECT_EQ(regions[0].fine_points, expected);
  EXPECT_EQ(weld_region_label(regions[0].region), "joint");
  const Eigen::Isometry3d T_segment_region_expected =
      T_world_segment.inverse() * T_world_cam * r.T_cam_region;
  EXPECT_TRUE(regions[0].T_segment_region.isApprox(T_segment_region_expected, 1e-12));
  // Seen from one keyframe: the viewpoint is its camera centre in the segment frame.
  EXPECT_TRUE(
      regions[0].viewpoint_segment.isApprox((T_world_segment.inverse() * T_world_cam).translation(), 1e-9));
  // The map is cleared for the next segment; the region stays active.
  EXPECT_EQ(fine->fine_map().size(), 0);
  EXPECT_EQ(fine->active_regions(), 1);
}

TEST(FineRegionMap, GivenRepeatedViewsThenEachVoxelCountsItsPointsAndTheCountsSumToThePixels) {
  const hal::PinholeIntrinsics K = intrinsics();
  FineRegionConfig c = small_config();
  c.voxels.voxel_m = 0.004;  // coarser than the pixels: voxels merge points
  auto fine = FineRegionMap::create(c, K);
  ASSERT_TRUE(fine.ok());
  const cv::Mat depth = wall_depth(K, 1.2f);
  const Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  const WeldRegion r = region_at(Eigen::Vector3d(0, 0, 1.2), Eigen::Vector3d(0.15, 0.15, 0.1));
  ASSERT_EQ(fine->add(r, T_world_cam), 0);
  for (int k = 0; k < 3; ++k)
    fine->insert_keyframe(cv::Mat(), depth, T_world_cam, Eigen::Isometry3d::Identity());
  const int per_view = brute_force_pixels(depth, K, r.T_cam_region, r.half_size_m, 3.5f);
  std::vector<CloudPoint> pts;
  std::vector<uint32_t> counts;
  std::vector<StoredWeldRegion> regions;
  fine->take_segment(Eigen::Isometry3d::Identity(), &pts, &counts, &regions);
  // The same view three times: each voxel holds its pixels three times over.
  uint64_t sum = 0;
  for (uint32_t n : counts) {
    sum += n;
    EXPECT_EQ(n % 3, 0u);
  }
  EXPECT_EQ(sum, 3u * static_cast<uint64_t>(per_view));
  EXPECT_LE(pts.size(), static_cast<size_t>(per_view));
}

TEST(FineRegionMap, GivenARegionBeyondTheDepthLimitOrBehindTheCameraThenNothingIsInserted) {
  const hal::PinholeIntrinsics K = intrinsics();
  auto fine = FineRegionMap::create(small_config(), K);
  ASSERT_TRUE(fine.ok());
  const cv::Mat far = wall_depth(K, 4.0f);  // beyond max_depth_m 3.5
  ASSERT_EQ(fine->add(region_at(Eigen::Vector3d(0, 0, 4.0), Eigen::Vector3d(0.3, 0.3, 0.3)),
                      Eigen::Isometry3d::Identity()),
            0);
  fine->insert_keyframe(cv::Mat(), far, Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity());
  EXPECT_EQ(fine->counters().points_inserted, 0u);
  // The same wall near, but the camera turned around: the box is behind it.
  Eigen::Isometry3d turned = Eigen::Isometry3d::Identity();
  turned.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();
  fine->insert_keyframe(cv::Mat(), wall_depth(K, 1.0f), turned, Eigen::Isometry3d::Identity());
  EXPECT_EQ(fine->counters().points_inserted, 0u);
  EXPECT_EQ(fine->counters().keyframes_in_view, 0u);
}

TEST(FineRegionMap, GivenDetectionsThenOverlapsMergeNewPlacesAddAndAFullTableOrABadBoxIsRefused) {
  const hal::PinholeIntrinsics K = intrinsics();
  auto fine = FineRegionMap::create(small_config(), K);  // 3 regions at most
  ASSERT_TRUE(fine.ok());
  const Eigen::Isometry3d T_world_cam = pose(0.2, Eigen::Vector3d(1, 2, 1));
  EXPECT_EQ(fine->add(region_at(Eigen::Vector3d(0, 0, 1.5), Eigen::Vector3d(0.3, 0.2, 0.1)), T_world_cam), 0);
  // Its centre inside the first box: the same region, seen again.
  EXPECT_EQ(
      fine->add(region_at(Eigen::Vector3d(0.2, 0.1, 1.55), Eigen::Vector3d(0.3, 0.2, 0.1)), T_world_cam), 0);
  // A bigger box whose centre is outside the first but which holds the first one's centre: the same.
  EXPECT_EQ(fine->add(region_at(Eigen::Vector3d(0.5, 0, 1.5), Eigen::Vector3d(0.6, 0.3, 0.2)), T_world_cam),
            0);
  EXPECT_EQ(fine->add(region_at(Eigen::Vector3d(2, 0, 1.5), Eigen::Vector3d(0.3, 0.2, 0.1)), T_world_cam), 1);
  EXPECT_EQ(fine->add(region_at(Eigen::Vector3d(-2, 0, 1.5), Eigen::Vector3d(0.3, 0.2, 0.1)), T_world_cam),
            2);
  EXPECT_EQ(fine->add(region_at(Eigen::Vector3d(0, 3, 1.5), Eigen::Vector3d(0.3, 0.2, 0.1)), T_world_cam),
            -1);
  EXPECT_EQ(fine->counters().regions_added, 3u);
  EXPECT_EQ(fine->counters().detections_merged, 2u);
  EXPECT_EQ(fine->counters().regions_refused, 1u);
  EXPECT_EQ(fine->add(region_at(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0.3, 0, 0.1)), T_world_cam), -1);
  EXPECT_EQ(fine->add(region_at(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0.3, NAN, 0.1)), T_world_cam), -1);
  Eigen::Isometry3d sheared = T_world_cam;
  sheared.linear()(0, 1) += 0.1;
  EXPECT_EQ(fine->add(region_at(Eigen::Vector3d(5, 0, 1), Eigen::Vector3d(0.3, 0.2, 0.1)), sheared), -1);
  EXPECT_EQ(fine->counters().detections_invalid, 3u);
  // The world box of region 1 is the keyframe's pose times the detection.
  EXPECT_TRUE(
      fine->T_world_region(1).translation().isApprox(T_world_cam * Eigen::Vector3d(2, 0, 1.5), 1e-12));
}

TEST(FineRegionMap, GivenANearerDetectionOrASettledPoseThenTheRegionIsPlacedAgain) {
  const hal::PinholeIntrinsics K = intrinsics();
  auto fine = FineRegionMap::create(small_config(), K);
  ASSERT_TRUE(fine.ok());
  const Eigen::Isometry3d T_world_far = pose(0.1, Eigen::Vector3d(0, -3, 1));
  WeldRegion far = region_at(Eigen::Vector3d(0, 0, 3.0), Eigen::Vector3d(0.4, 0.3, 0.2));
  far.keyframe_id = 7;
  ASSERT_EQ(fine->add(far, T_world_far), 0);
  const Eigen::Vector3d centre_world = T_world_far * Eigen::Vector3d(0, 0, 3.0);
  // The same joint from 1.5 m on keyframe 9, 1 cm off (the estimate's drift): re-anchored on it.
  Eigen::Isometry3d T_world_near = T_world_far;
  T_world_near.translation() = centre_world - T_world_far.linear() * Eigen::Vector3d(0.01, 0, 1.5);
  WeldRegion near = region_at(Eigen::Vector3d(0, 0, 1.5), Eigen::Vector3d(0.4, 0.3, 0.2));
  near.keyframe_id = 9;
  EXPECT_EQ(fine->add(near, T_world_near), 0);
  EXPECT_EQ(fine->counters().anchors_moved, 1u);
  EXPECT_EQ(fine->region(0).keyframe_id, 9);
  EXPECT_TRUE(fine->T_world_region(0).isApprox(T_world_near * near.T_cam_region, 1e-12));
  // A farther one merges without moving the anchor.
  EXPECT_EQ(fine->add(far, T_world_far), 0);
  EXPECT_EQ(fine->counters().anchors_moved, 1u);
  EXPECT_EQ(fine->region(0).keyframe_id, 9);
  // Keyframe 9 settles 3 mm elsewhere: the region follows; another keyframe's pose does not move it.
  Eigen::Isometry3d T_world_settled = T_world_near;
  T_world_settled.translation().x() += 0.003;
  fine->settle(8, pose(1.0, Eigen::Vector3d(5, 5, 5)));
  EXPECT_TRUE(fine->T_world_region(0).isApprox(T_world_near * near.T_cam_region, 1e-12));
  fine->settle(9, T_world_settled);
  EXPECT_TRUE(fine->T_world_region(0).isApprox(T_world_settled * near.T_cam_region, 1e-12));
}

// grow_to_cover (the geometric detector's boxes hold what one view saw): a merged detection's box
// extends the region's, in the region's axes, re-anchored or not; far apart boxes do not.
TEST(FineRegionMap, GivenGrowToCoverThenAMergedDetectionExtendsTheRegionsBox) {
  const hal::PinholeIntrinsics K = intrinsics();
  FineRegionConfig c = small_config();
  c.grow_to_cover = true;
  c.max_cover_m = 1.0;
  auto fine = FineRegionMap::create(c, K);
  ASSERT_TRUE(fine.ok());
  const Eigen::Isometry3d T_world_cam = pose(0.2, Eigen::Vector3d(1, 2, 1));
  ASSERT_EQ(fine->add(region_at(Eigen::Vector3d(0, 0, 1.5), Eigen::Vector3d(0.15, 0.1, 0.1)), T_world_cam),
            0);
  // 10 cm further along x (its centre inside the first box): the box now spans x in [-0.15, 0.25].
  ASSERT_EQ(fine->add(region_at(Eigen::Vector3d(0.1, 0, 1.5), Eigen::Vector3d(0.15, 0.1, 0.1)), T_world_cam),
            0);
  EXPECT_NEAR(fine->region(0).half_size_m.x(), 0.2, 1e-12);
  EXPECT_NEAR(fine->region(0).half_size_m.y(), 0.1, 1e-12);
  EXPECT_TRUE(
      fine->T_world_region(0).translation().isApprox(T_world_cam * Eigen::Vector3d(0.05, 0, 1.5), 1e-12));
  EXPECT_TRUE(fine->region(0).T_cam_region.translation().isApprox(Eigen::Vector3d(0.05, 0, 1.5), 1e-12));
  // A nearer view re-anchors and keeps what the region held: x in [-0.15, 0.25] still inside.
  const Eigen::Isometry3d T_world_near = T_world_cam * Eigen::Translation3d(0, 0, 0.5);
  ASSERT_EQ(fine->add(region_at(Eigen::Vector3d(0.0, 0, 1.0), Eigen::Vector3d(0.1, 0.1, 0.1)), T_world_near),
            0);
  EXPECT_EQ(fine->counters().anchors_moved, 1u);
  const Eigen::Isometry3d T_region_world = fine->T_world_region(0).inverse();
  for (double x : {-0.15, 0.25}) {
    const Eigen::Vector3d p = T_region_world * (T_world_cam * Eigen::Vector3d(x, 0, 1.5));
    EXPECT_LE(std::fabs(p.x()), fine->region(0).half_size_m.x() + 1e-9) << x;
  }
  EXPECT_EQ(fine->counters().boxes_grown, 2u);
  // A box that holds the region's centre but would stretch it beyond max_cover_m: merged, not grown.
  const Eigen::Vector3d before = fine->region(0).half_size_m;
  ASSERT_EQ(fine->add(region_at(Eigen::Vector3d(0.05, 0, 1.5), Eigen::Vector3d(0.9, 0.1, 0.1)), T_world_cam),
            0);
  EXPECT_TRUE(fine->region(0).half_size_m.isApprox(before, 1e-12));
  // A box across the region's axis (another seam's direction): merged, not grown.
  ASSERT_EQ(
      fine->add(region_at(Eigen::Vector3d(0.05, 0, 1.5), Eigen::Vector3d(0.3, 0.1, 0.1), 1.2), T_world_cam),
      0);
  EXPECT_TRUE(fine->region(0).half_size_m.isApprox(before, 1e-12));
  EXPECT_EQ(fine->counters().boxes_grown, 2u);
}

// The operator's corrections (issue #7 item 4): a fixed box is neither re-anchored, grown nor settled;
// a removed region takes no more points; an added fixed region does not merge into a neighbour.
TEST(FineRegionMap, GivenTheOperatorsBoxesThenDetectionsNoLongerChangeThemAndARemovedRegionIsGone) {
  const hal::PinholeIntrinsics K = intrinsics();
  FineRegionConfig c = small_config();
  c.grow_to_cover = true;
  auto fine = FineRegionMap::create(c, K);
  ASSERT_TRUE(fine.ok());
  const Eigen::Isometry3d T_world_cam = pose(0.2, Eigen::Vector3d(1, 2, 1));
  ASSERT_EQ(fine->add(region_at(Eigen::Vector3d(0, 0, 1.5), Eigen::Vector3d(0.15, 0.1, 0.1)), T_world_cam),
            0);
  const Eigen::Isometry3d T_world_box = T_world_cam * pose(0.0, Eigen::Vector3d(0.02, 0, 1.5));
  ASSERT_TRUE(fine->set_fixed_box(0, T_world_box, Eigen::Vector3d(0.3, 0.1, 0.1)));
  EXPECT_TRUE(fine->fixed(0));
  EXPECT_FALSE(fine->set_fixed_box(7, T_world_box, Eigen::Vector3d(0.3, 0.1, 0.1)));  // no such region
  EXPECT_FALSE(fine->set_fixed_box(0, T_world_box, Eigen::Vector3d(0.3, 0.0, 0.1)));  // no volume
  // A nearer, overlapping detection merges without moving or growing it; settling its keyframe neither.
  const Eigen::Isometry3d T_world_near = T_world_cam * Eigen::Translation3d(0, 0, 0.5);
  ASSERT_EQ(fine->add(region_at(Eigen::Vector3d(0.1, 0, 1.0), Eigen::Vector3d(0.2, 0.1, 0.1)), T_world_near),
            0);
  fine->settle(-1, pose(1.0, Eigen::Vector3d(5, 5, 5)));
  EXPECT_TRUE(fine->T_world_region(0).isApprox(T_world_box, 1e-12));
  EXPECT_NEAR(fine->region(0).half_size_m.x(), 0.3, 1e-12);
  EXPECT_EQ(fine->counters().anchors_moved, 0u);
  EXPECT_EQ(fine->counters().boxes_grown, 0u);
  // An operator's region drawn beside it (overlapping) is a region of its own.
  WeldRegion drawn = region_at(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.1, 0.1, 0.1));
  const int64_t added = fine->add_fixed(drawn, T_world_box);
  ASSERT_EQ(added, 1);
  EXPECT_EQ(fine->active_regions(), 2);
  drawn.half_size_m.x() = -1;
  EXPECT_EQ(fine->add_fixed(drawn, T_world_box), -1);
  // Removed: gone from the table and from what the keyframes feed.
  ASSERT_TRUE(fine->remove(0));
  EXPECT_FALSE(fine->remove(0));
  EXPECT_EQ(fine->active_regions(), 1);
  EXPECT_EQ(fine->find(1), 0);
  EXPECT_EQ(fine->find(0), -1);
  EXPECT_EQ(fine->counters().regions_removed, 1u);
  EXPECT_EQ(fine->counters().boxes_fixed, 2u);
}

TEST(FineRegionMap, GivenACreatedMapThenAddingAndInsertingAllocateNothing) {
  const hal::PinholeIntrinsics K = intrinsics();
  auto fine = FineRegionMap::create(small_config(), K);
  ASSERT_TRUE(fine.ok());
  const cv::Mat depth = wall_depth(K, 1.5f);
  cv::Mat bgr(K.height, K.width, CV_8UC3, cv::Scalar(10, 20, 30));
  const Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  core::AllocationScope scope;
  fine->add(region_at(Eigen::Vector3d(0, 0, 1.5), Eigen::Vector3d(0.2, 0.1, 0.05)), T_world_cam);
  fine->add(region_at(Eigen::Vector3d(0.1, 0, 1.5), Eigen::Vector3d(0.2, 0.1, 0.05)), T_world_cam);
  for (int k = 0; k < 3; ++k) fine->insert_keyframe(bgr, depth, T_world_cam, Eigen::Isometry3d::Identity());
  EXPECT_EQ(scope.allocations(), 0u);
  EXPECT_GT(fine->counters().points_inserted, 1000u);
}

TEST(FineRegionMap, GivenBadSettingsThenCreateSaysWhat) {
  const hal::PinholeIntrinsics K = intrinsics();
  FineRegionConfig c = small_config();
  c.max_regions = 0;
  EXPECT_EQ(FineRegionMap::create(c, K).status().code(), core::ErrorCode::kInvalidArgument);
  c = small_config();
  c.voxels.voxel_m = 0;
  EXPECT_EQ(FineRegionMap::create(c, K).status().code(), core::ErrorCode::kInvalidArgument);
  c = small_config();
  c.cloud.max_depth_m = 0.1f;
  EXPECT_EQ(FineRegionMap::create(c, K).status().code(), core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(FineRegionMap::create(small_config(), hal::PinholeIntrinsics{}).status().code(),
            core::ErrorCode::kInvalidArgument);
}

}  // namespace
}  // namespace hwr::recon
