// Voxel thinning (cloud_thinning.hpp). Oracles: each output point is the mean, computed here in
// double, of the input points whose floor(p / voxel) key it shares, with the colour of the first of
// them; one output per occupied voxel; non-finite points dropped; points beyond the key range kept
// as they are; the positions do not depend on the input's order, and the output follows the order of
// each voxel's first point; a bad voxel size changes nothing.

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "hwr/recon/cloud_thinning.hpp"

namespace hwr::recon {
namespace {

CloudPoint point(double x, double y, double z, uint8_t tag = 0) {
  CloudPoint p;
  p.x_m = static_cast<float>(x);
  p.y_m = static_cast<float>(y);
  p.z_m = static_cast<float>(z);
  p.r = tag;
  return p;
}

using Key = std::array<long long, 3>;
Key key_of(const CloudPoint& p, double voxel_m) {
  return {static_cast<long long>(std::floor(p.x_m / voxel_m)),
          static_cast<long long>(std::floor(p.y_m / voxel_m)),
          static_cast<long long>(std::floor(p.z_m / voxel_m))};
}

struct VoxelMean {
  double sum[3] = {0, 0, 0};
  int n = 0;
  uint8_t first_tag = 0;
};

// Brute force: the mean of each occupied voxel, by key.
std::map<Key, VoxelMean> voxel_means(const std::vector<CloudPoint>& in, double voxel_m) {
  std::map<Key, VoxelMean> m;
  for (const CloudPoint& p : in) {
    VoxelMean& v = m[key_of(p, voxel_m)];
    if (v.n == 0) v.first_tag = p.r;
    v.sum[0] += p.x_m;
    v.sum[1] += p.y_m;
    v.sum[2] += p.z_m;
    ++v.n;
  }
  return m;
}

TEST(CloudThinning, GivenADenseNoisySurfaceThenOnePointPerVoxelAtTheMeanOfItsPoints) {
  // A tilted plane sampled every 2 cm (the map's voxels) with 3 mm noise, 1.2 m x 0.8 m, thinned at 5 cm.
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.003);
  std::vector<CloudPoint> cloud;
  for (int i = 0; i < 60; ++i) {
    for (int j = 0; j < 40; ++j) {
      const double x = 0.02 * i - 0.3, y = 0.02 * j + 0.013;
      cloud.push_back(point(x + noise(rng), y + noise(rng), 0.3 * x - 0.1 * y + 1.0 + noise(rng),
                            static_cast<uint8_t>((i * 40 + j) & 0xff)));
    }
  }
  const double voxel = 0.05;
  const std::map<Key, VoxelMean> expected = voxel_means(cloud, voxel);
  const size_t n_in = cloud.size();
  auto stats = thin_cloud(&cloud, voxel);
  ASSERT_TRUE(stats.ok()) << stats.status().message();
  EXPECT_EQ(stats->points_in, static_cast<int64_t>(n_in));
  EXPECT_EQ(stats->points_out, static_cast<int64_t>(cloud.size()));
  ASSERT_EQ(cloud.size(), expected.size());
  EXPECT_LT(cloud.size(), n_in / 3);  // a surface at 2 cm spacing loses most points at 5 cm
  std::map<Key, int> seen;
  for (const CloudPoint& p : cloud) {
    // The mean lies in its voxel's convex hull, so in the same voxel (a mean exactly on a face is
    // not possible with this noise).
    const Key k = key_of(p, voxel);
    ASSERT_EQ(expected.count(k), 1u);
    EXPECT_EQ(++seen[k], 1) << "two points in one voxel";
    const VoxelMean& v = expected.at(k);
    EXPECT_NEAR(p.x_m, v.sum[0] / v.n, 1e-6);
    EXPECT_NEAR(p.y_m, v.sum[1] / v.n, 1e-6);
    EXPECT_NEAR(p.z_m, v.sum[2] / v.n, 1e-6);
    EXPECT_EQ(p.r, v.first_tag) << "the colour of the voxel's first point";
  }
}

TEST(CloudThinning, GivenAShuffledInputThenTheSamePositionsInTheInputsOrder) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  std::vector<CloudPoint> a;
  for (int i = 0; i < 5000; ++i)
    a.push_back(point(u(rng), u(rng), 0.1 * u(rng), static_cast<uint8_t>(i & 0xff)));
  std::vector<CloudPoint> b = a;
  std::shuffle(b.begin(), b.end(), rng);
  const std::vector<CloudPoint> b_in = b;
  ASSERT_TRUE(thin_cloud(&a, 0.2).ok());
  ASSERT_TRUE(thin_cloud(&b, 0.2).ok());
  ASSERT_EQ(a.size(), b.size());
  // The same voxel means, whatever the order (float sums in another order differ in the last bits).
  auto by_position = [](const CloudPoint& p, const CloudPoint& q) {
    return std::make_tuple(p.x_m, p.y_m, p.z_m) < std::make_tuple(q.x_m, q.y_m, q.z_m);
  };
  std::vector<CloudPoint> sa = a, sb = b;
  std::sort(sa.begin(), sa.end(), by_position);
  std::sort(sb.begin(), sb.end(), by_position);
  for (size_t i = 0; i < sa.size(); ++i) {
    EXPECT_NEAR(sa[i].x_m, sb[i].x_m, 1e-5);
    EXPECT_NEAR(sa[i].y_m, sb[i].y_m, 1e-5);
    EXPECT_NEAR(sa[i].z_m, sb[i].z_m, 1e-5);
  }
  // In b, the voxels come in the order of their first point in b's input.
  std::map<Key, size_t> first_seen;
  for (size_t i = 0; i < b_in.size(); ++i) first_seen.emplace(key_of(b_in[i], 0.2), i);
  for (size_t i = 1; i < b.size(); ++i) {
    EXPECT_LT(first_seen.at(key_of(b[i - 1], 0.2)), first_seen.at(key_of(b[i], 0.2)));
  }
}

TEST(CloudThinning, GivenNonFiniteFarOrNegativeCoordinatesThenDroppedKeptOrBinnedByFloor) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<CloudPoint> cloud = {
      point(-0.01, -0.01, -0.01, 1),  // voxel (-1, -1, -1) at 0.1 m: floor, not truncation
      point(0.01, 0.01, 0.01, 2),     // voxel (0, 0, 0)
      point(-0.09, -0.02, -0.05, 3),  // voxel (-1, -1, -1) again
      point(2.0e5, 0.0, 0.0, 4),      // beyond 2^20 voxels of 0.1 m: kept as it is
      point(0.0, 0.0, 0.0, 5),        // voxel (0, 0, 0) again
  };
  CloudPoint bad = point(0, 0, 0, 6);
  bad.y_m = nan;
  cloud.push_back(bad);
  bad.y_m = inf;
  cloud.push_back(bad);
  auto stats = thin_cloud(&cloud, 0.1);
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->nonfinite_dropped, 2);
  EXPECT_EQ(stats->out_of_range_kept, 1);
  ASSERT_EQ(cloud.size(), 3u);
  // In the order of each voxel's first point: (-1, -1, -1) (input 0), (0, 0, 0) (input 1), the far
  // point (input 3).
  EXPECT_EQ(cloud[0].r, 1);
  EXPECT_NEAR(cloud[0].x_m, -0.05, 1e-6);
  EXPECT_NEAR(cloud[0].y_m, -0.015, 1e-6);
  EXPECT_NEAR(cloud[0].z_m, -0.03, 1e-6);
  EXPECT_EQ(cloud[1].r, 2);
  EXPECT_NEAR(cloud[1].x_m, 0.005, 1e-6);
  EXPECT_EQ(cloud[2].r, 4);
  EXPECT_EQ(cloud[2].x_m, 2.0e5f);
}

TEST(CloudThinning, GivenABadVoxelSizeThenAnErrorAndTheCloudUntouched) {
  std::vector<CloudPoint> cloud = {point(0, 0, 0, 1), point(0.001, 0, 0, 2)};
  for (double voxel :
       {0.0, -0.05, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    auto stats = thin_cloud(&cloud, voxel);
    ASSERT_FALSE(stats.ok());
    EXPECT_EQ(stats.status().code(), core::ErrorCode::kInvalidArgument);
    EXPECT_EQ(cloud.size(), 2u);
  }
  std::vector<CloudPoint> empty;
  auto stats = thin_cloud(&empty, 0.05);
  ASSERT_TRUE(stats.ok());
  EXPECT_TRUE(empty.empty());
}

}  // namespace
}  // namespace hwr::recon
