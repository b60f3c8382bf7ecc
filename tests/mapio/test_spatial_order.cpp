// SpatialOrder (mapio/spatial_order.hpp): a permutation of the batch (every point once, its id with
// it) along a Z-order curve, so that consecutive runs of points are compact.

#include <algorithm>
#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "hwr/core/alloc_counter.hpp"
#include "hwr/mapio/spatial_order.hpp"

namespace hwr::mapio {
namespace {

// Points on a 40 m x 30 m floor in a random (creation-like) order, id = position in a raster order.
std::vector<ChunkPoint> floor_points(int n, std::vector<uint32_t>* ids) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> x(-20.0f, 20.0f), y(-15.0f, 15.0f), z(-0.01f, 0.01f);
  std::vector<ChunkPoint> p(static_cast<size_t>(n));
  ids->resize(p.size());
  for (size_t i = 0; i < p.size(); ++i) {
    p[i] = {x(rng),
            y(rng),
            z(rng),
            static_cast<uint8_t>(i),
            static_cast<uint8_t>(i >> 8),
            static_cast<uint8_t>(i >> 16),
            static_cast<uint8_t>(i % 3)};
    (*ids)[i] = static_cast<uint32_t>(i) * 2654435761u;
  }
  return p;
}

// Mean over runs of `block` consecutive points of the bounding box's largest side.
double mean_block_extent_m(const std::vector<ChunkPoint>& p, size_t block) {
  double sum = 0;
  int blocks = 0;
  for (size_t first = 0; first + block <= p.size(); first += block, ++blocks) {
    float lo[3] = {1e9f, 1e9f, 1e9f}, hi[3] = {-1e9f, -1e9f, -1e9f};
    for (size_t i = first; i < first + block; ++i) {
      const float v[3] = {p[i].x_m, p[i].y_m, p[i].z_m};
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], v[a]);
        hi[a] = std::max(hi[a], v[a]);
      }
    }
    sum += std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  }
  return sum / blocks;
}

TEST(SpatialOrder, GivenAScatteredBatchThenAPermutationWithIdsAttachedAndCompactRuns) {
  std::vector<uint32_t> ids;
  const std::vector<ChunkPoint> before = floor_points(60000, &ids);
  std::vector<ChunkPoint> after = before;
  std::vector<uint32_t> after_ids = ids;
  SpatialOrder order(65536);
  {
    core::AllocationScope scope;
    ASSERT_TRUE(order.sort(after.data(), after_ids.data(), static_cast<int>(after.size())));
    EXPECT_EQ(scope.allocations(), 0u) << "sort() allocates nothing within its capacity";
  }
  // A permutation: the id (a bijection of the original index) finds each point's original.
  std::vector<int> seen(before.size(), 0);
  for (size_t k = 0; k < after.size(); ++k) {
    const uint32_t i = after_ids[k] * 244002641u;  // inverse of 2654435761 mod 2^32
    ASSERT_LT(i, before.size());
    ++seen[i];
    EXPECT_EQ(std::memcmp(&after[k], &before[i], sizeof(ChunkPoint)), 0) << "point " << i;
  }
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), static_cast<std::ptrdiff_t>(seen.size()));
  // Runs of 1024 points (1/60 of the floor, ~5 m across when compact) span far less than the floor.
  const double unsorted_m = mean_block_extent_m(before, 1024);
  const double sorted_m = mean_block_extent_m(after, 1024);
  std::printf("[ spatial order ] mean extent of a 1024-point run: %.1f m unsorted, %.1f m sorted\n",
              unsorted_m, sorted_m);
  EXPECT_LT(sorted_m, 0.3 * unsorted_m);
}

TEST(SpatialOrder, GivenTooManyPointsOrNoIdsThenTheDocumentedBehaviour) {
  std::vector<uint32_t> ids;
  std::vector<ChunkPoint> p = floor_points(1000, &ids);
  const std::vector<ChunkPoint> copy = p;
  SpatialOrder small(999);
  EXPECT_FALSE(small.sort(p.data(), ids.data(), 1000));
  EXPECT_EQ(std::memcmp(p.data(), copy.data(), p.size() * sizeof(ChunkPoint)), 0) << "left as it was";
  SpatialOrder fits(1000);
  EXPECT_TRUE(fits.sort(p.data(), nullptr, 1000));  // ids optional
  EXPECT_TRUE(fits.sort(nullptr, nullptr, 0));
  EXPECT_TRUE(fits.sort(p.data(), nullptr, 1));
}

}  // namespace
}  // namespace hwr::mapio
