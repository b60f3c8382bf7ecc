// split_structure_points (recon/structure_points.hpp): ground vs structure of a gravity-aligned cloud.
#include "hwr/recon/structure_points.hpp"

#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

namespace hwr::recon {
namespace {

void add(std::vector<float>* xyz, double x, double y, double z) {
  xyz->push_back(static_cast<float>(x));
  xyz->push_back(static_cast<float>(y));
  xyz->push_back(static_cast<float>(z));
}

// A 4 m x 4 m floor at z = 0.02 (5 cm grid, a gentle 5 deg slope along x) and a 4 m x 2 m wall at x = 3.1.
std::vector<float> floor_and_wall(int* n_floor, int* n_wall) {
  std::vector<float> xyz;
  *n_floor = *n_wall = 0;
  const double slope = std::tan(5.0 * M_PI / 180.0);
  for (double x = 0.01; x < 4.0; x += 0.05) {
    for (double y = 0.01; y < 4.0; y += 0.05, ++*n_floor) add(&xyz, x, y, 0.02 + slope * x);
  }
  for (double y = 0.01; y < 4.0; y += 0.05) {
    for (double z = 0.52; z < 2.5; z += 0.05, ++*n_wall) add(&xyz, 3.1, y, z);
  }
  return xyz;
}

TEST(StructurePoints, GivenAFloorAndAWallThenTheWallIsStructureAndTheFloorIsNot) {
  int n_floor = 0, n_wall = 0;
  const std::vector<float> xyz = floor_and_wall(&n_floor, &n_wall);
  std::vector<float> structure, rest;
  const int n =
      split_structure_points(xyz.data(), n_floor + n_wall, StructurePointsConfig{}, &structure, &rest);
  EXPECT_EQ(n, n_wall);
  ASSERT_EQ(structure.size(), static_cast<size_t>(3 * n));
  EXPECT_EQ(rest.size(), static_cast<size_t>(3 * n_floor));
  for (int i = 0; i < n; ++i) EXPECT_FLOAT_EQ(structure[3 * static_cast<size_t>(i)], 3.1f);
}

TEST(StructurePoints, GivenSparseOrNonFinitePointsThenTheyAreNotStructure) {
  // A scattered cloud: fewer than 5 points per 0.5 m voxel has no reliable normal.
  std::vector<float> xyz;
  for (int i = 0; i < 40; ++i) add(&xyz, 0.75 * i, 0.3 * (i % 3), 1.0 + 0.1 * (i % 2));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  add(&xyz, nan, 0, 0);
  add(&xyz, 0, std::numeric_limits<float>::infinity(), 0);
  std::vector<float> structure, rest;
  EXPECT_EQ(split_structure_points(xyz.data(), 42, StructurePointsConfig{}, &structure, &rest), 0);
  EXPECT_EQ(rest.size(), 3u * 40u);  // the non-finite points are in neither
  EXPECT_EQ(split_structure_points(nullptr, 5, StructurePointsConfig{}, &structure, &rest), 0);
  EXPECT_TRUE(rest.empty());
}

TEST(StructurePoints, GivenATiltedPlaneBeyondTheNormalLimitThenItIsStructure) {
  // A 45 deg ramp: its normal's z is 0.71 < 0.8, so it constrains x as much as z: structure.
  std::vector<float> xyz;
  int count = 0;
  for (double x = 0.01; x < 2.0; x += 0.05) {
    for (double y = 0.01; y < 2.0; y += 0.05, ++count) add(&xyz, x, y, x);
  }
  std::vector<float> structure, rest;
  EXPECT_EQ(split_structure_points(xyz.data(), count, StructurePointsConfig{}, &structure, &rest), count);
}

}  // namespace
}  // namespace hwr::recon
