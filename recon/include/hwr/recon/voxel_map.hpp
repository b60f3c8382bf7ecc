#pragma once
// The global point map (paper sec. II-B; issue #4 item 2): keyframe clouds merged into voxels of a
// configurable side. Each voxel keeps the running mean of the points that fell in it (position and
// colour) and their count, so re-observing a surface refines it instead of duplicating it.
//
// Memory is fixed at construction (ARCHITECTURE.md firmware rules): an open-addressing hash table
// (linear probing, power-of-two slots, load factor <= 0.5) of `max_voxels` voxels. A point whose
// voxel is new when the map is full is refused and counted; nothing is ever reallocated. Integer
// voxel coordinates are packed 21 bits per axis, so the map spans ±2^20 voxels per axis (±10 km at
// 1 cm) and a point beyond that is refused and counted too.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "hwr/core/status.hpp"
#include "hwr/recon/keyframe_cloud.hpp"

namespace hwr::recon {

struct VoxelMapConfig {
  double voxel_m = 0.02;
  int max_voxels = 2'000'000;
};

struct Voxel {
  float x_m = 0, y_m = 0, z_m = 0;  // mean of the points merged here (world frame)
  float r = 0, g = 0, b = 0;        // mean colour
  uint32_t count = 0;
};

struct VoxelMapCounters {
  uint64_t points_merged = 0;  // into an existing voxel
  uint64_t voxels_created = 0;
  uint64_t refused_full = 0;   // a new voxel was needed and the map was full
  uint64_t refused_range = 0;  // outside the packable coordinate range or non-finite
};

class VoxelMap {
 public:
  // Errors (kInvalidArgument): voxel_m not positive and finite, max_voxels < 1.
  static core::Expected<VoxelMap> create(const VoxelMapConfig& config);

  // Merges every point of the cloud; never allocates.
  void insert(const CloudPoint* points, int n);
  void insert(const KeyframeCloud& cloud) { insert(cloud.points, cloud.size); }

  int size() const { return size_; }
  int capacity() const { return config_.max_voxels; }
  const VoxelMapConfig& config() const { return config_; }
  const VoxelMapCounters& counters() const { return counters_; }
  // The voxel holding p_world, or nullptr.
  const Voxel* find(const Eigen::Vector3d& p_world_m) const;
  // Voxels in creation order: created(i), i in [0, size()), is the slot of the i-th voxel made
  // since the last clear(). Slots never move while the map is not cleared (no deletion, no
  // rehash), so a slot is a stable id of its voxel: the map streamer sends voxels in this order
  // and names them by slot.
  uint32_t created(int i) const { return created_[static_cast<size_t>(i)]; }
  const Voxel& at_slot(uint32_t slot) const { return voxels_[slot]; }
  // Visits every occupied voxel (table order).
  template <class F>
  void for_each(F&& f) const {
    for (size_t i = 0; i < keys_.size(); ++i)
      if (keys_[i] != kEmpty) f(voxels_[i]);
  }
  void clear();

 private:
  static constexpr uint64_t kEmpty = ~uint64_t{0};
  explicit VoxelMap(const VoxelMapConfig& config);
  bool key_of(double x, double y, double z, uint64_t* key) const;
  size_t slot_of(uint64_t key) const;

  VoxelMapConfig config_;
  double inv_voxel_ = 0;
  std::vector<uint64_t> keys_;
  std::vector<Voxel> voxels_;
  std::vector<uint32_t> created_;  // capacity max_voxels, fixed at construction
  size_t mask_ = 0;
  int size_ = 0;
  VoxelMapCounters counters_;
};

}  // namespace hwr::recon
