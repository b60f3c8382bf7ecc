// The voxel map (issue #4 item 2). Oracles: points in one voxel merge into their exact mean;
// voxel boundaries at negative coordinates follow floor(); a full map refuses new voxels and
// counts them; creation order names slots that never move; inserting allocates nothing.

#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "hwr/core/alloc_counter.hpp"
#include "hwr/recon/voxel_map.hpp"

namespace hwr::recon {
namespace {

CloudPoint pt(float x, float y, float z, uint8_t grey = 100) {
  CloudPoint p;
  p.x_m = x;
  p.y_m = y;
  p.z_m = z;
  p.r = p.g = p.b = grey;
  return p;
}

TEST(VoxelMap, GivenPointsInOneVoxelThenTheyMergeIntoTheirMean) {
  auto map = VoxelMap::create({0.1, 100});
  ASSERT_TRUE(map.ok());
  const std::vector<CloudPoint> pts = {pt(0.01f, 0.02f, 0.03f, 0), pt(0.05f, 0.06f, 0.07f, 200),
                                       pt(0.09f, 0.01f, 0.02f, 100)};
  map->insert(pts.data(), static_cast<int>(pts.size()));
  ASSERT_EQ(map->size(), 1);
  const Voxel* v = map->find(Eigen::Vector3d(0.05, 0.05, 0.05));
  ASSERT_NE(v, nullptr);
  EXPECT_EQ(v->count, 3u);
  EXPECT_NEAR(v->x_m, 0.05, 1e-6);
  EXPECT_NEAR(v->y_m, 0.03, 1e-6);
  EXPECT_NEAR(v->z_m, 0.04, 1e-6);
  EXPECT_NEAR(v->r, 100.0, 1e-4);
  EXPECT_EQ(map->counters().voxels_created, 1u);
  EXPECT_EQ(map->counters().points_merged, 2u);
}

TEST(VoxelMap, GivenInsertionsThenCreationOrderNamesStableSlots) {
  auto map = VoxelMap::create({0.1, 100});
  ASSERT_TRUE(map.ok());
  const std::vector<CloudPoint> first = {pt(0.35f, 0.05f, 0.05f), pt(-0.25f, 0.05f, 0.05f)};
  map->insert(first.data(), 2);
  const uint32_t s0 = map->created(0), s1 = map->created(1);
  // Merging into old voxels and making new ones leaves the first slots where they were.
  const std::vector<CloudPoint> more = {pt(0.36f, 0.06f, 0.06f), pt(5.05f, 0.05f, 0.05f),
                                        pt(-0.26f, 0.0f, 0.0f)};
  map->insert(more.data(), 3);
  ASSERT_EQ(map->size(), 3);
  EXPECT_EQ(map->created(0), s0);
  EXPECT_EQ(map->created(1), s1);
  EXPECT_EQ(&map->at_slot(s0), map->find(Eigen::Vector3d(0.35, 0.05, 0.05)));
  EXPECT_EQ(&map->at_slot(s1), map->find(Eigen::Vector3d(-0.25, 0.05, 0.05)));
  EXPECT_EQ(&map->at_slot(map->created(2)), map->find(Eigen::Vector3d(5.05, 0.05, 0.05)));
  EXPECT_EQ(map->at_slot(s0).count, 2u);
  map->clear();
  map->insert(more.data() + 1, 1);
  ASSERT_EQ(map->size(), 1);
  EXPECT_EQ(&map->at_slot(map->created(0)), map->find(Eigen::Vector3d(5.05, 0.05, 0.05)));
}

TEST(VoxelMap, GivenPointsAcrossZeroThenVoxelsFollowFloor) {
  auto map = VoxelMap::create({0.1, 100});
  ASSERT_TRUE(map.ok());
  const std::vector<CloudPoint> pts = {pt(-0.01f, 0.05f, 0.05f), pt(0.01f, 0.05f, 0.05f),
                                       pt(-0.09f, 0.05f, 0.05f), pt(-0.11f, 0.05f, 0.05f)};
  map->insert(pts.data(), static_cast<int>(pts.size()));
  EXPECT_EQ(map->size(), 3);  // [-0.2,-0.1), [-0.1,0) twice, [0,0.1)
  EXPECT_EQ(map->find(Eigen::Vector3d(-0.05, 0.05, 0.05))->count, 2u);
  EXPECT_EQ(map->find(Eigen::Vector3d(0.05, 0.05, 0.05))->count, 1u);
  EXPECT_EQ(map->find(Eigen::Vector3d(0.5, 0.5, 0.5)), nullptr);
}

TEST(VoxelMap, GivenAFullMapThenNewVoxelsAreRefusedAndCountedButOldOnesStillMerge) {
  auto map = VoxelMap::create({1.0, 10});
  ASSERT_TRUE(map.ok());
  std::vector<CloudPoint> pts;
  for (int i = 0; i < 25; ++i) pts.push_back(pt(static_cast<float>(i) + 0.5f, 0.5f, 0.5f));
  map->insert(pts.data(), static_cast<int>(pts.size()));
  EXPECT_EQ(map->size(), 10);
  EXPECT_EQ(map->counters().refused_full, 15u);
  const CloudPoint again = pt(0.25f, 0.5f, 0.5f);
  map->insert(&again, 1);
  EXPECT_EQ(map->find(Eigen::Vector3d(0.5, 0.5, 0.5))->count, 2u);
  int visited = 0;
  map->for_each([&](const Voxel&) { ++visited; });
  EXPECT_EQ(visited, 10);
  map->clear();
  EXPECT_EQ(map->size(), 0);
  EXPECT_EQ(map->find(Eigen::Vector3d(0.5, 0.5, 0.5)), nullptr);
}

TEST(VoxelMap, GivenNonFiniteOrFarPointsThenTheyAreRefused) {
  auto map = VoxelMap::create({0.01, 10});
  ASSERT_TRUE(map.ok());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<CloudPoint> pts = {pt(nan, 0, 0), pt(0, std::numeric_limits<float>::infinity(), 0),
                                       pt(1e5f, 0, 0), pt(0.005f, 0.005f, 0.005f)};
  map->insert(pts.data(), static_cast<int>(pts.size()));
  EXPECT_EQ(map->size(), 1);
  EXPECT_EQ(map->counters().refused_range, 3u);
}

TEST(VoxelMap, GivenBadConfigThenCreateFails) {
  EXPECT_FALSE(VoxelMap::create({0.0, 10}).ok());
  EXPECT_FALSE(VoxelMap::create({std::nan(""), 10}).ok());
  EXPECT_FALSE(VoxelMap::create({0.01, 0}).ok());
}

TEST(VoxelMap, GivenACreatedMapThenInsertingAllocatesNothing) {
  auto map = VoxelMap::create({0.05, 50'000});
  ASSERT_TRUE(map.ok());
  std::vector<CloudPoint> pts;
  for (int i = 0; i < 20'000; ++i)
    pts.push_back(pt(0.013f * static_cast<float>(i % 200), 0.017f * static_cast<float>(i / 200), 1.0f));
  core::AllocationScope scope;
  map->insert(pts.data(), static_cast<int>(pts.size()));
  map->insert(pts.data(), static_cast<int>(pts.size()));
  EXPECT_EQ(scope.allocations(), 0u);
  EXPECT_GT(map->size(), 1000);
  EXPECT_EQ(map->counters().refused_full, 0u);
}

}  // namespace
}  // namespace hwr::recon
