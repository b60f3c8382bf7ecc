#pragma once
// Voxel thinning of a point cloud: one point per occupied cube of side voxel_m, the centroid of the
// points in it (the colour of its first point in input order). The prior map thins its clouds
// when it reads them (prior_map.hpp, PriorMapConfig::cloud_voxel_m): the relocalizer's NDT voxels
// are 0.25-2 m, the stored map's 2 cm.
//
// Voxel keys are floor(p / voxel_m) per axis within ±2^20; a point outside that range (beyond
// ±52 km at 5 cm) is kept as it is. Non-finite points are dropped. The output follows the input
// order of each voxel's first point (a strided subsample keeps the map's spread rather than a
// regular grid); the positions do not depend on the input's order. Allocates scratch arrays of
// ~16 + 24 bytes per point (runs where clouds are read from disk, off the control loop).

#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/recon/keyframe_cloud.hpp"

namespace hwr::recon {

struct ThinningStats {
  int64_t points_in = 0;
  int64_t points_out = 0;
  int64_t nonfinite_dropped = 0;
  int64_t out_of_range_kept = 0;
};

// Thins `cloud` in place. Errors: voxel_m not positive and finite (kInvalidArgument; cloud untouched).
core::Expected<ThinningStats> thin_cloud(std::vector<CloudPoint>* cloud, double voxel_m);

}  // namespace hwr::recon
