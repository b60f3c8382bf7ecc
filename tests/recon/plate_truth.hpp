#pragma once
// Test helper: a ground-truth plate (recon/plate_fit.hpp) from its size and pose, with its 8 corners
// in plate_fit's order (corner i at local (sx L/2, sy W/2, sz T/2), sx = bit 2 of i, sy = bit 1,
// sz = bit 0, bit set: +).
#include <string>

#include <Eigen/Geometry>

#include "hwr/recon/plate_fit.hpp"

namespace hwr::testing {

inline recon::PlateTruth make_plate(const std::string& name, const Eigen::Vector3d& size_m,
                                    const Eigen::Isometry3d& T_world_plate) {
  recon::PlateTruth p;
  p.name = name;
  p.size_m = size_m;
  p.T_world_plate = T_world_plate;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d local(((i >> 2) & 1 ? 0.5 : -0.5) * size_m.x(),
                                ((i >> 1) & 1 ? 0.5 : -0.5) * size_m.y(), (i & 1 ? 0.5 : -0.5) * size_m.z());
    p.corners_world[static_cast<size_t>(i)] = T_world_plate * local;
  }
  return p;
}

}  // namespace hwr::testing
