#include "hwr/recon/structure_points.hpp"

#include <cmath>
#include <cstdint>
#include <unordered_map>

#include <Eigen/Eigenvalues>

namespace hwr::recon {
namespace {

struct VoxelSums {
  int n = 0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  bool horizontal = false;
};

// 21 bits per axis (offset binary), as the NDT voxel keys; false outside the range or for NaN.
bool voxel_key(const float* p, double inv_side, uint64_t* key) {
  constexpr int64_t kHalf = int64_t{1} << 20;
  uint64_t k = 0;
  for (int a = 0; a < 3; ++a) {
    const double c = std::floor(p[a] * inv_side);
    if (!(c >= -static_cast<double>(kHalf) && c < static_cast<double>(kHalf))) return false;
    k = (k << 21) | static_cast<uint64_t>(static_cast<int64_t>(c) + kHalf);
  }
  *key = k;
  return true;
}

}  // namespace

int split_structure_points(const float* xyz, int n, const StructurePointsConfig& config,
                           std::vector<float>* structure, std::vector<float>* rest) {
  structure->clear();
  rest->clear();
  if (xyz == nullptr || n <= 0 || !(config.voxel_m > 0)) return 0;
  const double inv_side = 1.0 / config.voxel_m;
  std::unordered_map<uint64_t, VoxelSums> voxels;
  voxels.reserve(static_cast<size_t>(n / 4 + 1));
  for (int i = 0; i < n; ++i) {
    const float* p = xyz + 3 * static_cast<size_t>(i);
    uint64_t key = 0;
    if (!voxel_key(p, inv_side, &key)) continue;
    VoxelSums& v = voxels[key];
    const Eigen::Vector3d q(p[0], p[1], p[2]);
    ++v.n;
    v.sum += q;
    v.outer += q * q.transpose();
  }
  for (auto& [key, v] : voxels) {
    (void)key;
    if (v.n < 5) continue;
    const Eigen::Vector3d mean = v.sum / v.n;
    const Eigen::Matrix3d cov = v.outer / v.n - mean * mean.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(cov);
    const Eigen::Vector3d lambda = es.eigenvalues();  // ascending
    const bool planar = lambda(0) < config.planarity * lambda(1);
    v.horizontal = planar && std::abs(es.eigenvectors().col(0).z()) >= config.min_normal_z;
  }
  for (int i = 0; i < n; ++i) {
    const float* p = xyz + 3 * static_cast<size_t>(i);
    uint64_t key = 0;
    if (!voxel_key(p, inv_side, &key)) continue;
    const VoxelSums& v = voxels[key];
    std::vector<float>* out = v.n < 5 || v.horizontal ? rest : structure;
    out->insert(out->end(), p, p + 3);
  }
  return static_cast<int>(structure->size() / 3);
}

}  // namespace hwr::recon
