// NDT target: voxel Gaussians over the target cloud (Magnusson 2009, sec. 6.1-6.2).
#include "ndt_target.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Eigenvalues>

namespace hwr::recon {

NdtScoreConstants ndt_score_constants(double outlier_ratio, double resolution_m) {
  // Eq. 6.8: c1, c2 are the inlier and outlier weights of the mixture of eq. 6.7 (the Gaussian's
  // normalisation folded into c1, the uniform outlier density over one voxel into c2).
  const double c1 = 10.0 * (1.0 - outlier_ratio);
  const double c2 = outlier_ratio / (resolution_m * resolution_m * resolution_m);
  NdtScoreConstants k;
  k.d3 = -std::log(c2);
  k.d1 = -std::log(c1 + c2) - k.d3;
  k.d2 = -2.0 * std::log((-std::log(c1 * std::exp(-0.5) + c2) - k.d3) / k.d1);
  return k;
}

core::Status validate_ndt_config(const NdtConfig& c) {
  int levels = 0;
  bool ended = false;
  for (double r : c.resolutions_m) {
    if (r == 0.0) {
      ended = true;
      continue;
    }
    if (ended) continue;  // entries after the terminating 0 are ignored
    if (!(r > 0.0) || !std::isfinite(r)) {
      return core::InvalidArgument(
          "ndt: resolutions_m must be positive and finite before the 0 that ends "
          "the list, got " +
          std::to_string(r));
    }
    ++levels;
  }
  if (levels == 0) return core::InvalidArgument("ndt: resolutions_m needs at least one positive voxel side");
  if (!(c.outlier_ratio > 0.0 && c.outlier_ratio < 1.0)) {
    return core::InvalidArgument("ndt: outlier_ratio must be in (0, 1), got " +
                                 std::to_string(c.outlier_ratio));
  }
  if (c.min_points_per_voxel < 3) {
    return core::InvalidArgument("ndt: min_points_per_voxel must be >= 3 (a covariance needs them), got " +
                                 std::to_string(c.min_points_per_voxel));
  }
  if (!(c.min_eigenvalue_ratio > 0.0 && c.min_eigenvalue_ratio <= 1.0)) {
    return core::InvalidArgument("ndt: min_eigenvalue_ratio must be in (0, 1], got " +
                                 std::to_string(c.min_eigenvalue_ratio));
  }
  if (c.max_iterations < 1 || !(c.translation_epsilon_m > 0) || !(c.rotation_epsilon_rad > 0) ||
      !(c.max_step > 0) || !std::isfinite(c.max_step)) {
    return core::InvalidArgument(
        "ndt: max_iterations >= 1 and positive translation/rotation epsilons and max_step are required");
  }
  if (c.num_threads < 1 || c.num_threads > 64) {
    return core::InvalidArgument("ndt: num_threads must be in [1, 64], got " + std::to_string(c.num_threads));
  }
  if (c.min_source_points < 1 || c.max_source_points < 1 || c.max_target_points < 1 ||
      c.max_target_voxels < 1 || c.max_target_voxels > (1 << 28)) {
    return core::InvalidArgument(
        "ndt: min_source_points, max_source_points, max_target_points must be >= 1 and max_target_voxels in "
        "[1, 2^28]");
  }
  if (!(c.degenerate_eigenvalue_ratio >= 0.0 && c.degenerate_eigenvalue_ratio < 1.0)) {
    return core::InvalidArgument("ndt: degenerate_eigenvalue_ratio must be in [0, 1), got " +
                                 std::to_string(c.degenerate_eigenvalue_ratio));
  }
  return core::Status::Ok();
}

NdtTarget::Impl::Impl(const NdtConfig& c) : config(c) {
  size_t n_slots = 1;
  int bits = 0;
  while (n_slots < 2 * static_cast<size_t>(c.max_target_voxels)) {
    n_slots <<= 1;
    ++bits;
  }
  slots.assign(n_slots, Slot{});
  mask = n_slots - 1;
  shift = 64 - bits;
  const size_t cap = static_cast<size_t>(c.max_target_voxels);
  voxel_key.assign(cap, kNdtEmptyKey);
  voxel_slot.assign(cap, -1);
  voxel_gaussian.assign(cap, -1);
  voxel_links.assign(cap, NdtVoxelLinks{});
  accumulators.assign(cap, Accumulator{});
  gaussians.assign(cap, NdtGaussian{});
}

void NdtTarget::Impl::clear() {
  for (int v = 0; v < voxels; ++v) slots[static_cast<size_t>(voxel_slot[v])] = Slot{};
  voxels = 0;
  gaussian_count = 0;
  skipped_points = 0;
  resolution_m = 0;  // unbuilt until a build succeeds (NdtAligner::align_prebuilt refuses it)
}

namespace {

// Mean and regularised inverse covariance of one voxel's points. False: no Gaussian (all points
// equal, or a non-finite sum).
bool voxel_gaussian(const NdtTarget::Impl::Accumulator& a, double min_eigenvalue_ratio, NdtGaussian* g) {
  const double n = a.count;
  const Eigen::Vector3d mean_d(a.sum[0] / n, a.sum[1] / n, a.sum[2] / n);
  Eigen::Matrix3d S;
  S << a.outer[0], a.outer[1], a.outer[2], a.outer[1], a.outer[3], a.outer[4], a.outer[2], a.outer[4],
      a.outer[5];
  // Unbiased covariance of the cell (thesis sec. 6.1): (sum d d^T - n m m^T) / (n - 1), d about the
  // voxel's first point.
  const Eigen::Matrix3d cov = (S - n * mean_d * mean_d.transpose()) / (n - 1.0);
  if (!cov.allFinite()) return false;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(cov);
  Eigen::Vector3d lambda = es.eigenvalues();  // ascending
  const double lambda_max = lambda(2);
  if (!(lambda_max > 0.0) || !std::isfinite(lambda_max)) return false;
  // Eq. 6.11: eigenvalues below min_eigenvalue_ratio * lambda_max are raised to it, so a planar or
  // linear patch keeps an invertible covariance whose thin direction is still the sharpest.
  const double floor_value = min_eigenvalue_ratio * lambda_max;
  for (int k = 0; k < 3; ++k) lambda(k) = std::max(lambda(k), floor_value);
  const Eigen::Matrix3d& V = es.eigenvectors();
  const Eigen::Matrix3d icov = V * lambda.cwiseInverse().asDiagonal() * V.transpose();
  if (!icov.allFinite()) return false;
  for (int k = 0; k < 3; ++k) g->mean[k] = static_cast<float>(static_cast<double>(a.ref[k]) + mean_d(k));
  g->icov[0] = static_cast<float>(icov(0, 0));
  g->icov[1] = static_cast<float>(icov(0, 1));
  g->icov[2] = static_cast<float>(icov(0, 2));
  g->icov[3] = static_cast<float>(icov(1, 1));
  g->icov[4] = static_cast<float>(icov(1, 2));
  g->icov[5] = static_cast<float>(icov(2, 2));
  return true;
}

void unpack_key(uint64_t key, int64_t* ix, int64_t* iy, int64_t* iz) {
  const uint64_t m = (uint64_t{1} << 21) - 1;
  *ix = static_cast<int64_t>((key >> 42) & m) - kNdtAxisHalfRange;
  *iy = static_cast<int64_t>((key >> 21) & m) - kNdtAxisHalfRange;
  *iz = static_cast<int64_t>(key & m) - kNdtAxisHalfRange;
}

}  // namespace

core::Expected<NdtTarget> NdtTarget::create(const NdtConfig& config) {
  HWR_RETURN_IF_ERROR(validate_ndt_config(config));
  return NdtTarget(std::make_unique<Impl>(config));
}

NdtTarget::NdtTarget(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
NdtTarget::NdtTarget(NdtTarget&&) noexcept = default;
NdtTarget& NdtTarget::operator=(NdtTarget&&) noexcept = default;
NdtTarget::~NdtTarget() = default;

int NdtTarget::gaussian_voxels() const { return impl_->gaussian_count; }
int NdtTarget::occupied_voxels() const { return impl_->voxels; }
double NdtTarget::resolution_m() const { return impl_->resolution_m; }
int NdtTarget::skipped_points() const { return impl_->skipped_points; }

core::Status NdtTarget::build(const PointsView& target, double resolution_m) {
  return build(&target, 1, resolution_m);
}

core::Status NdtTarget::build(const PointsView* targets, int n_targets, double resolution_m) {
  Impl& m = *impl_;
  m.clear();
  if (!(resolution_m > 0.0) || !std::isfinite(resolution_m)) {
    return core::InvalidArgument("ndt target: resolution must be positive and finite, got " +
                                 std::to_string(resolution_m));
  }
  if (n_targets < 0 || (n_targets > 0 && targets == nullptr)) {
    return core::InvalidArgument("ndt target: n_targets >= 0 views and a pointer to them required");
  }
  int64_t total = 0;
  for (int t = 0; t < n_targets; ++t) {
    const PointsView& target = targets[t];
    if (target.n < 0 || (target.n > 0 && target.xyz == nullptr) || target.stride_floats < 3) {
      return core::InvalidArgument(
          "ndt target: the points view needs n >= 0, a pointer when n > 0 and stride >= 3");
    }
    total += target.n;
  }
  if (total > m.config.max_target_points) {
    return core::OutOfRange("ndt target: " + std::to_string(total) + " points exceed max_target_points = " +
                            std::to_string(m.config.max_target_points) +
                            "; raise it or downsample the target");
  }
  m.resolution_m = resolution_m;
  m.inv_resolution = 1.0 / resolution_m;
  m.constants = ndt_score_constants(m.config.outlier_ratio, resolution_m);

  // Pass 1: points into voxels (count, sums about the voxel's first point).
  for (int t = 0; t < n_targets; ++t) {
    const PointsView& target = targets[t];
    for (int i = 0; i < target.n; ++i) {
      const Eigen::Vector3f p = target.at(i);
      int64_t ix = 0, iy = 0, iz = 0;
      uint64_t key = 0;
      if (!p.allFinite() || !ndt_voxel_index(p.x(), m.inv_resolution, &ix) ||
          !ndt_voxel_index(p.y(), m.inv_resolution, &iy) || !ndt_voxel_index(p.z(), m.inv_resolution, &iz) ||
          !ndt_pack_key(ix, iy, iz, &key)) {
        ++m.skipped_points;
        continue;
      }
      size_t s = m.slot_of(key);
      while (m.slots[s].key != kNdtEmptyKey && m.slots[s].key != key) s = (s + 1) & m.mask;
      int32_t v = m.slots[s].voxel;
      if (m.slots[s].key == kNdtEmptyKey) {
        if (m.voxels >= m.config.max_target_voxels) {
          m.clear();
          return core::OutOfRange("ndt target: more than max_target_voxels = " +
                                  std::to_string(m.config.max_target_voxels) + " occupied voxels at " +
                                  std::to_string(resolution_m) + " m; raise it or use a coarser resolution");
        }
        v = m.voxels++;
        m.slots[s].key = key;
        m.slots[s].voxel = v;
        m.voxel_key[v] = key;
        m.voxel_slot[v] = static_cast<int32_t>(s);
        Impl::Accumulator& a = m.accumulators[v];
        a = Impl::Accumulator{};
        a.ref[0] = p.x();
        a.ref[1] = p.y();
        a.ref[2] = p.z();
      }
      Impl::Accumulator& a = m.accumulators[v];
      const double dx = static_cast<double>(p.x()) - a.ref[0];
      const double dy = static_cast<double>(p.y()) - a.ref[1];
      const double dz = static_cast<double>(p.z()) - a.ref[2];
      ++a.count;
      a.sum[0] += dx;
      a.sum[1] += dy;
      a.sum[2] += dz;
      a.outer[0] += dx * dx;
      a.outer[1] += dx * dy;
      a.outer[2] += dx * dz;
      a.outer[3] += dy * dy;
      a.outer[4] += dy * dz;
      a.outer[5] += dz * dz;
    }
  }

  // Pass 2: a Gaussian per voxel with enough points.
  for (int v = 0; v < m.voxels; ++v) {
    m.voxel_gaussian[v] = -1;
    const Impl::Accumulator& a = m.accumulators[v];
    if (a.count < m.config.min_points_per_voxel) continue;
    if (voxel_gaussian(a, m.config.min_eigenvalue_ratio, &m.gaussians[m.gaussian_count])) {
      m.voxel_gaussian[v] = m.gaussian_count++;
    }
  }

  // Pass 3: each voxel's own Gaussian and its 6 face neighbours' (kDirect7 reads them with one lookup).
  static constexpr int kFace[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
  for (int v = 0; v < m.voxels; ++v) {
    NdtVoxelLinks& links = m.voxel_links[v];
    links = NdtVoxelLinks{};
    if (m.voxel_gaussian[v] >= 0) links.gaussian[links.count++] = m.voxel_gaussian[v];
    int64_t ix = 0, iy = 0, iz = 0;
    unpack_key(m.voxel_key[v], &ix, &iy, &iz);
    for (const auto& f : kFace) {
      uint64_t key = 0;
      if (!ndt_pack_key(ix + f[0], iy + f[1], iz + f[2], &key)) continue;
      const int32_t u = m.find(key);
      if (u >= 0 && m.voxel_gaussian[u] >= 0) links.gaussian[links.count++] = m.voxel_gaussian[u];
    }
  }
  return core::Status::Ok();
}

}  // namespace hwr::recon
