#include "hwr/recon/voxel_map.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace hwr::recon {
namespace {

constexpr int64_t kAxisHalfRange = int64_t{1} << 20;  // 21 bits per axis, offset binary

// splitmix64's finaliser: spreads neighbouring voxel keys over the table.
uint64_t mix(uint64_t x) {
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebULL;
  x ^= x >> 31;
  return x;
}

}  // namespace

core::Expected<VoxelMap> VoxelMap::create(const VoxelMapConfig& config) {
  if (!(config.voxel_m > 0) || !std::isfinite(config.voxel_m)) {
    return core::InvalidArgument("voxel map: voxel_m must be positive and finite, got " +
                                 std::to_string(config.voxel_m));
  }
  if (config.max_voxels < 1 || config.max_voxels > (1 << 30)) {
    return core::InvalidArgument("voxel map: max_voxels must be in [1, 2^30], got " +
                                 std::to_string(config.max_voxels));
  }
  return VoxelMap(config);
}

VoxelMap::VoxelMap(const VoxelMapConfig& config) : config_(config), inv_voxel_(1.0 / config.voxel_m) {
  size_t slots = 1;
  while (slots < 2 * static_cast<size_t>(config.max_voxels)) slots <<= 1;  // load factor <= 0.5
  keys_.assign(slots, kEmpty);
  voxels_.assign(slots, Voxel{});
  created_.assign(static_cast<size_t>(config.max_voxels), 0);
  mask_ = slots - 1;
}

bool VoxelMap::key_of(double x, double y, double z, uint64_t* key) const {
  const double c[3] = {std::floor(x * inv_voxel_), std::floor(y * inv_voxel_), std::floor(z * inv_voxel_)};
  uint64_t k = 0;
  for (double v : c) {
    if (!(v >= -static_cast<double>(kAxisHalfRange) && v < static_cast<double>(kAxisHalfRange))) return false;
    k = (k << 21) | static_cast<uint64_t>(static_cast<int64_t>(v) + kAxisHalfRange);
  }
  *key = k;  // 63 bits used: never equal to kEmpty
  return true;
}

size_t VoxelMap::slot_of(uint64_t key) const { return static_cast<size_t>(mix(key)) & mask_; }

void VoxelMap::insert(const CloudPoint* points, int n) {
  for (int i = 0; i < n; ++i) {
    const CloudPoint& p = points[i];
    uint64_t key = 0;
    if (!key_of(p.x_m, p.y_m, p.z_m, &key)) {
      ++counters_.refused_range;
      continue;
    }
    size_t s = slot_of(key);
    while (keys_[s] != kEmpty && keys_[s] != key) s = (s + 1) & mask_;
    Voxel& v = voxels_[s];
    if (keys_[s] == kEmpty) {
      if (size_ >= config_.max_voxels) {
        ++counters_.refused_full;
        continue;
      }
      keys_[s] = key;
      v = Voxel{};
      created_[static_cast<size_t>(size_)] = static_cast<uint32_t>(s);
      ++size_;
      ++counters_.voxels_created;
    } else {
      ++counters_.points_merged;
    }
    // Running mean: m += (x - m) / n.
    const float w = 1.0f / static_cast<float>(++v.count);
    v.x_m += (p.x_m - v.x_m) * w;
    v.y_m += (p.y_m - v.y_m) * w;
    v.z_m += (p.z_m - v.z_m) * w;
    v.r += (static_cast<float>(p.r) - v.r) * w;
    v.g += (static_cast<float>(p.g) - v.g) * w;
    v.b += (static_cast<float>(p.b) - v.b) * w;
  }
}

const Voxel* VoxelMap::find(const Eigen::Vector3d& p_world_m) const {
  uint64_t key = 0;
  if (!key_of(p_world_m.x(), p_world_m.y(), p_world_m.z(), &key)) return nullptr;
  for (size_t s = slot_of(key);; s = (s + 1) & mask_) {
    if (keys_[s] == kEmpty) return nullptr;
    if (keys_[s] == key) return &voxels_[s];
  }
}

void VoxelMap::clear() {
  std::fill(keys_.begin(), keys_.end(), kEmpty);
  size_ = 0;
}

}  // namespace hwr::recon
