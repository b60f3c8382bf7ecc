#pragma once
// The points of a gravity-aligned cloud that lie off horizontal planes
// ("structure": walls, plates, beams, clutter), for the relocalizer's score margin
// (relocalizer.hpp, step e). Outdoors most of a local map is ground, which fits any pose that puts
// the ground on the ground (a fit turned 180 deg, shifted along a row of containers): scores over
// all points then differ by less than the margin between the right place and a wrong one. Scores
// over the structure points alone tell them apart.
//
// Method: the cloud is cut into cubic voxels of side voxel_m; a voxel with at least 5 points is a
// horizontal plane when its covariance's smallest eigenvalue is below planarity times the middle
// one and the matching eigenvector (its normal) has |n_z| >= min_normal_z. Points of horizontal
// voxels and of voxels with fewer than 5 points (no reliable normal) are left out.

#include <vector>

namespace hwr::recon {

struct StructurePointsConfig {
  double voxel_m = 0.5;
  double min_normal_z = 0.8;  // |n_z| of a horizontal plane's normal (within ~37 deg of vertical)
  double planarity = 0.2;     // lambda_min / lambda_mid below this: a plane
};

// Splits xyz (n points, packed x y z, z up) into its structure points and the rest (horizontal planes,
// sparse voxels), both packed and resized. Returns the structure points' count.
int split_structure_points(const float* xyz, int n, const StructurePointsConfig& config,
                           std::vector<float>* structure, std::vector<float>* rest);

}  // namespace hwr::recon
