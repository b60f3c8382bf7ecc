#pragma once
// Private to recon: the storage behind NdtTarget (hash grid of voxels, their Gaussians and the
// neighbour lists the aligner reads), shared by ndt_target.cpp (build) and ndt.cpp (score).

#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "hwr/core/status.hpp"
#include "hwr/recon/ndt.hpp"

namespace hwr::recon {

// One voxel's Gaussian: mean and the upper triangle of the regularised inverse covariance
// (xx, xy, xz, yy, yz, zz), floats to halve the memory the score pass streams through.
struct NdtGaussian {
  float mean[3];
  float icov[6];
};

// Up to 7 Gaussians near a voxel: its own (if any) and those of its 6 face neighbours, packed.
struct NdtVoxelLinks {
  int32_t count = 0;
  int32_t gaussian[7] = {-1, -1, -1, -1, -1, -1, -1};
};

// Magnusson's constants of the Gaussian approximation of the outlier mixture (thesis eq. 6.8):
// -log(c1 exp(-x^2/2) + c2) ~ d1 exp(-d2 x^2/2) + d3, matched at x = 0, x = 1 and x -> inf, with
// c1 = 10 (1 - p_o) and c2 = p_o / V for a voxel of volume V = side^3.
struct NdtScoreConstants {
  double d1 = 0;  // < 0
  double d2 = 0;  // > 0
  double d3 = 0;
};
NdtScoreConstants ndt_score_constants(double outlier_ratio, double resolution_m);

// The shared config checks of NdtTarget::create and NdtAligner::create.
core::Status validate_ndt_config(const NdtConfig& config);

// Integer voxel coordinates packed 21 bits per axis (offset binary), as in VoxelMap: ±2^20 voxels
// per axis. A packed key is at most 63 bits, so ~0 never is one.
constexpr int64_t kNdtAxisHalfRange = int64_t{1} << 20;
constexpr uint64_t kNdtEmptyKey = ~uint64_t{0};

inline bool ndt_voxel_index(double v, double inv_side, int64_t* i) {
  const double c = std::floor(v * inv_side);
  if (!(c >= -static_cast<double>(kNdtAxisHalfRange) && c < static_cast<double>(kNdtAxisHalfRange))) {
    return false;  // also rejects NaN
  }
  *i = static_cast<int64_t>(c);
  return true;
}

inline bool ndt_pack_key(int64_t ix, int64_t iy, int64_t iz, uint64_t* key) {
  const int64_t h = kNdtAxisHalfRange;
  if (ix < -h || ix >= h || iy < -h || iy >= h || iz < -h || iz >= h) return false;
  *key = (static_cast<uint64_t>(ix + h) << 42) | (static_cast<uint64_t>(iy + h) << 21) |
         static_cast<uint64_t>(iz + h);
  return true;
}

struct NdtTarget::Impl {
  struct Slot {
    uint64_t key = kNdtEmptyKey;
    int32_t voxel = -1;
  };
  // Build-time sums of one voxel, about its first point (keeps the covariance exact far from the
  // origin).
  struct Accumulator {
    int32_t count = 0;
    float ref[3] = {0, 0, 0};
    double sum[3] = {0, 0, 0};
    double outer[6] = {0, 0, 0, 0, 0, 0};  // xx xy xz yy yz zz
  };

  explicit Impl(const NdtConfig& c);

  // Voxel index of `key`, or -1. Linear probing from the multiplicative (Fibonacci) hash.
  int32_t find(uint64_t key) const {
    for (size_t s = slot_of(key);; s = (s + 1) & mask) {
      const Slot& slot = slots[s];
      if (slot.key == key) return slot.voxel;
      if (slot.key == kNdtEmptyKey) return -1;
    }
  }
  size_t slot_of(uint64_t key) const { return static_cast<size_t>((key * 0x9E3779B97F4A7C15ULL) >> shift); }
  void clear();

  NdtConfig config;
  double resolution_m = 0;
  double inv_resolution = 0;
  NdtScoreConstants constants;

  std::vector<Slot> slots;  // 2^k >= 2 * max_target_voxels (load factor <= 0.5)
  size_t mask = 0;
  int shift = 64;
  int voxels = 0;
  std::vector<uint64_t> voxel_key;      // per occupied voxel
  std::vector<int32_t> voxel_slot;      // where it sits in `slots` (to clear only what was used)
  std::vector<int32_t> voxel_gaussian;  // its Gaussian, or -1 (too few points)
  std::vector<NdtVoxelLinks> voxel_links;
  std::vector<Accumulator> accumulators;
  std::vector<NdtGaussian> gaussians;
  int gaussian_count = 0;
  int skipped_points = 0;
};

}  // namespace hwr::recon
