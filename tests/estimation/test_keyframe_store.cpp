// Keyframe ring and map point pool: ids, eviction with the pose archive, image slots, stale
// handles after removal, exhaustion.

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "hwr/estimation/keyframe_store.hpp"
#include "hwr/estimation/map_point_store.hpp"

namespace hwr::estimation {
namespace {

Eigen::Isometry3d pose_x(double x) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation().x() = x;
  return T;
}

KeyframeStoreConfig small_config() {
  KeyframeStoreConfig c;
  c.capacity = 4;
  c.image_slots = 2;
  c.max_total = 10;
  c.feature_capacity = 16;
  c.width = 64;
  c.height = 48;
  return c;
}

TEST(KeyframeStore, GivenMoreKeyframesThanCapacityWhenInsertedThenTheOldestAreEvictedAndTheirPosesArchived) {
  KeyframeStore store(small_config());
  for (int i = 0; i < 6; ++i) ASSERT_NE(store.insert(i * 100, pose_x(i)), nullptr);
  EXPECT_EQ(store.size(), 4);
  EXPECT_EQ(store.oldest_id(), 2);
  EXPECT_EQ(store.newest_id(), 5);
  EXPECT_EQ(store.get(1), nullptr);
  ASSERT_NE(store.get(2), nullptr);
  EXPECT_EQ(store.get(2)->t_ns, 200);
  // Evicted keyframes keep the pose they had when they left the ring.
  EXPECT_NEAR(store.pose(0).translation().x(), 0.0, 1e-12);
  EXPECT_NEAR(store.pose(1).translation().x(), 1.0, 1e-12);
  // A pose changed in the ring (bundle adjustment) is what pose() returns, and what the archive keeps.
  store.get(2)->T_world_cam = pose_x(2.5);
  EXPECT_NEAR(store.pose(2).translation().x(), 2.5, 1e-12);
  for (int i = 6; i < 8; ++i) ASSERT_NE(store.insert(i * 100, pose_x(i)), nullptr);
  EXPECT_EQ(store.get(2), nullptr);
  EXPECT_NEAR(store.pose(2).translation().x(), 2.5, 1e-12);
}

TEST(KeyframeStore, GivenMaxTotalIdsUsedWhenInsertingThenNullptr) {
  KeyframeStore store(small_config());
  for (int i = 0; i < 10; ++i) ASSERT_NE(store.insert(i, pose_x(i)), nullptr);
  EXPECT_EQ(store.insert(10, pose_x(10)), nullptr);
}

TEST(KeyframeStore, GivenImagesWhenStoredThenOnlyTheNewestSlotsKeepThem) {
  KeyframeStore store(small_config());
  for (int i = 0; i < 3; ++i) {
    store.insert(i, pose_x(i));
    cv::Mat bgr(48, 64, CV_8UC3, cv::Scalar(i, i, i));
    cv::Mat depth(48, 64, CV_32FC1, cv::Scalar(1.0 + i));
    store.store_images(i, bgr, depth);
  }
  EXPECT_EQ(store.depth_m(0), nullptr);
  ASSERT_NE(store.depth_m(2), nullptr);
  EXPECT_FLOAT_EQ(store.depth_m(2)->at<float>(5, 5), 3.0f);
  EXPECT_EQ(store.bgr(1)->at<cv::Vec3b>(0, 0)[0], 1);
}

TEST(MapPointStore, GivenARemovedPointWhenItsOldHandleIsUsedThenItIsStaleEvenAfterTheSlotIsReused) {
  MapPointStore store(2);
  uint8_t desc[kOrbDescriptorBytes] = {1, 2, 3};
  const MapPointHandle a = store.create(Eigen::Vector3d(1, 2, 3), desc, 0, 0);
  ASSERT_TRUE(a.valid());
  ASSERT_NE(store.get(a), nullptr);
  EXPECT_EQ(store.get(a)->descriptor[2], 3);
  store.remove(a);
  EXPECT_EQ(store.get(a), nullptr);
  EXPECT_EQ(store.alive(), 0);
  const MapPointHandle b = store.create(Eigen::Vector3d(4, 5, 6), desc, 1, 0);
  const MapPointHandle c = store.create(Eigen::Vector3d(7, 8, 9), desc, 1, 0);
  ASSERT_TRUE(b.valid());
  ASSERT_TRUE(c.valid());
  EXPECT_EQ(store.get(a), nullptr);  // its slot is reused by b or c, with a new generation
  EXPECT_EQ(store.alive(), 2);
  // Full: a clear failure, counted.
  EXPECT_FALSE(store.create(Eigen::Vector3d::Zero(), desc, 2, 0).valid());
  EXPECT_EQ(store.exhausted(), 1u);
  store.remove(a);  // a stale handle removes nothing
  EXPECT_EQ(store.alive(), 2);
}

}  // namespace
}  // namespace hwr::estimation
