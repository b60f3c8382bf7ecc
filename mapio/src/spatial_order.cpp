#include "hwr/mapio/spatial_order.hpp"

#include <algorithm>
#include <cmath>

namespace hwr::mapio {

namespace {

constexpr uint64_t kCellsPerAxis = uint64_t{1} << 21;

// The 21 low bits of v spread to every third bit (bit i -> bit 3i).
uint64_t spread_bits(uint64_t v) {
  v &= kCellsPerAxis - 1;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}

uint64_t cell_index(float v, float min, double cell_m) {
  const double c = std::floor((static_cast<double>(v) - static_cast<double>(min)) / cell_m);
  return c <= 0.0 ? 0 : std::min(static_cast<uint64_t>(c), kCellsPerAxis - 1);
}

}  // namespace

SpatialOrder::SpatialOrder(int max_points, double cell_m) : cell_m_(cell_m > 0.0 ? cell_m : 0.02) {
  const size_t n = static_cast<size_t>(std::max(max_points, 0));
  points_.resize(n);
  ids_.resize(n);
  order_.resize(n);
}

bool SpatialOrder::sort(ChunkPoint* points, uint32_t* ids, int n) {
  if (n <= 1) return true;
  if (points == nullptr || static_cast<size_t>(n) > order_.size()) return false;
  float min[3] = {points[0].x_m, points[0].y_m, points[0].z_m};
  for (int i = 1; i < n; ++i) {
    min[0] = std::min(min[0], points[i].x_m);
    min[1] = std::min(min[1], points[i].y_m);
    min[2] = std::min(min[2], points[i].z_m);
  }
  for (int i = 0; i < n; ++i) {
    const ChunkPoint& p = points[i];
    const uint64_t code = spread_bits(cell_index(p.x_m, min[0], cell_m_)) |
                          spread_bits(cell_index(p.y_m, min[1], cell_m_)) << 1 |
                          spread_bits(cell_index(p.z_m, min[2], cell_m_)) << 2;
    order_[static_cast<size_t>(i)] = {code, static_cast<uint32_t>(i)};
  }
  // (code, index) pairs are unique, so an unstable sort gives the stable order.
  std::sort(order_.begin(), order_.begin() + n);
  for (int k = 0; k < n; ++k) {
    const uint32_t i = order_[static_cast<size_t>(k)].second;
    points_[static_cast<size_t>(k)] = points[i];
    if (ids != nullptr) ids_[static_cast<size_t>(k)] = ids[i];
  }
  std::copy(points_.begin(), points_.begin() + n, points);
  if (ids != nullptr) std::copy(ids_.begin(), ids_.begin() + n, ids);
  return true;
}

}  // namespace hwr::mapio
