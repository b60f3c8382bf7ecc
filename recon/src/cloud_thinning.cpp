#include "hwr/recon/cloud_thinning.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>

namespace hwr::recon {
namespace {

constexpr int64_t kKeyRange = int64_t{1} << 20;  // voxel index per axis in [-2^20, 2^20)

// 21 bits per axis, offset to be non-negative.
bool voxel_key(const CloudPoint& p, double inv_voxel, uint64_t* key) {
  const double c[3] = {std::floor(p.x_m * inv_voxel), std::floor(p.y_m * inv_voxel),
                       std::floor(p.z_m * inv_voxel)};
  uint64_t k = 0;
  for (double v : c) {
    if (!(v >= -static_cast<double>(kKeyRange) && v < static_cast<double>(kKeyRange))) return false;
    k = (k << 21) | static_cast<uint64_t>(static_cast<int64_t>(v) + kKeyRange);
  }
  *key = k;
  return true;
}

}  // namespace

core::Expected<ThinningStats> thin_cloud(std::vector<CloudPoint>* cloud, double voxel_m) {
  if (!(voxel_m > 0) || !std::isfinite(voxel_m)) {
    return core::InvalidArgument("cloud thinning: voxel_m must be positive and finite");
  }
  if (cloud->size() > std::numeric_limits<uint32_t>::max()) {
    return core::InvalidArgument("cloud thinning: more than 2^32 - 1 points");
  }
  ThinningStats stats;
  stats.points_in = static_cast<int64_t>(cloud->size());
  const double inv_voxel = 1.0 / voxel_m;
  std::vector<std::pair<uint64_t, uint32_t>> keyed;
  keyed.reserve(cloud->size());
  // (first input index, point): the output follows the input order of each voxel's first point,
  // so a strided subsample of it keeps the input's (map's) spread, not a regular grid.
  std::vector<std::pair<uint32_t, CloudPoint>> kept;
  for (size_t i = 0; i < cloud->size(); ++i) {
    const CloudPoint& p = (*cloud)[i];
    if (!std::isfinite(p.x_m) || !std::isfinite(p.y_m) || !std::isfinite(p.z_m)) {
      ++stats.nonfinite_dropped;
      continue;
    }
    uint64_t key = 0;
    if (voxel_key(p, inv_voxel, &key)) {
      keyed.emplace_back(key, static_cast<uint32_t>(i));
    } else {
      kept.emplace_back(static_cast<uint32_t>(i), p);
      ++stats.out_of_range_kept;
    }
  }
  // By key, then input index: a voxel's first point in input order comes first (its colour).
  std::sort(keyed.begin(), keyed.end());
  for (size_t b = 0; b < keyed.size();) {
    size_t e = b;
    double sx = 0, sy = 0, sz = 0;
    for (; e < keyed.size() && keyed[e].first == keyed[b].first; ++e) {
      const CloudPoint& p = (*cloud)[keyed[e].second];
      sx += p.x_m;
      sy += p.y_m;
      sz += p.z_m;
    }
    const double n = static_cast<double>(e - b);
    CloudPoint q = (*cloud)[keyed[b].second];
    q.x_m = static_cast<float>(sx / n);
    q.y_m = static_cast<float>(sy / n);
    q.z_m = static_cast<float>(sz / n);
    kept.emplace_back(keyed[b].second, q);
    b = e;
  }
  std::sort(kept.begin(), kept.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<CloudPoint> out;
  out.reserve(kept.size());
  for (const auto& k : kept) out.push_back(k.second);
  stats.points_out = static_cast<int64_t>(out.size());
  cloud->swap(out);
  return stats;
}

}  // namespace hwr::recon
