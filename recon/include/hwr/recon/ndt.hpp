#pragma once
// Hand-written point-to-distribution NDT (Magnusson, "The Three-Dimensional Normal-Distributions
// Transform", PhD thesis, Örebro 2009, ch. 6; issue #4 item 3). The target cloud is cut into cubic
// voxels; each voxel with enough points holds a Gaussian (mean, unbiased covariance regularised so
// its smallest eigenvalues are at least `min_eigenvalue_ratio` of the largest, thesis sec. 6.2,
// eq. 6.11 as PCL numbers it). A source point q (already moved by the pose) scores against a
// Gaussian (mu, Sigma) with Magnusson's Gaussian approximation of the outlier mixture:
//   s(q) = -d1 exp(-d2/2 (q - mu)^T Sigma^-1 (q - mu))                       (eq. 6.9)
// with d1 < 0, d2 > 0 from the outlier ratio and the voxel side (eq. 6.8), so 0 < s <= -d1.
// The aligner minimises the cost f = -sum s over the source points and their neighbour Gaussians
// with the analytic gradient and Hessian (eqs. 6.10, 6.12, 6.13), Newton steps (where the Hessian is
// not positive definite its eigenvalues are replaced by their absolute values, floored at 1e-9 of the
// largest) and a strong-Wolfe line search on the step length (Nocedal & Wright alg. 3.5/3.6), coarse to fine
// over the configured voxel sides (a coarse level's convergence epsilons are the configured ones times its
// side over the finest side: it only seeds the next level).
//
// Pose parameterisation (replaces the thesis' Euler angles of eqs. 6.17-6.21): a 6-vector
// x = (t, phi), t in metres, phi a rotation vector in radians, acts about a pivot c (target frame)
//   T(x) p = Exp(phi) (p - c) + c + t.
// The Jacobian of a moved point q is then J = [I, -[q - c]x] and its only second derivatives are in
// the rotation block, d2q/dphi_i dphi_j = 1/2 (e_i (q - c)_j + e_j (q - c)_i) - delta_ij (q - c).
// A Newton step x is applied on the left, T <- T(x) * T. The aligner pivots about the centroid of
// the moved source cloud (better conditioned than the origin when clouds lie far from it); the
// Hessian it reports is converted to the pivot c = 0 (the target origin).
//
// Memory: NdtTarget and NdtAligner allocate in create() only (an aligner holds one target, or one
// per configured level with target_per_level, ~200 B x max_target_voxels each); building a target and
// aligning never allocate (the firmware rule of ARCHITECTURE.md), so the mapping task can run them every
// junction. Threads: with num_threads > 1 the aligner starts num_threads - 1 workers in create(); each pass
// over the source cuts it into a fixed number of chunks whose partial sums are added in chunk
// order, so the result does not depend on the thread count (bit for bit).

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hwr/core/status.hpp"

namespace hwr::recon {

// A read-only view of points: `n` points, the i-th at (xyz + i * stride_floats)[0..2], metres.
// CloudPoint arrays (stride 4 floats) and packed xyz arrays (stride 3) both fit.
struct PointsView {
  const float* xyz = nullptr;
  int n = 0;
  int stride_floats = 3;
  Eigen::Vector3f at(int i) const {
    const float* p = xyz + static_cast<ptrdiff_t>(i) * stride_floats;
    return {p[0], p[1], p[2]};
  }
};

enum class NdtNeighbours : uint8_t {
  kDirect1,  // the voxel the point falls in
  kDirect7,  // that voxel and its 6 face neighbours (wider basin, ~3x the work)
};

struct NdtConfig {
  // Voxel sides, coarse to fine; 0 ends the list. Each level starts from the previous result.
  std::array<double, 4> resolutions_m{2.0, 1.0, 0.5, 0.0};
  double outlier_ratio = 0.55;          // Magnusson's p_o in eq. 6.7 (d1, d2 of eq. 6.8 derive from it)
  int min_points_per_voxel = 6;         // fewer: the voxel holds no Gaussian
  double min_eigenvalue_ratio = 0.01;   // covariance regularisation (eq. 6.11)
  int max_iterations = 35;              // Newton iterations per level
  double translation_epsilon_m = 1e-4;  // converged when a Newton step moves less than this ...
  double rotation_epsilon_rad = 1e-4;   // ... and rotates less than this (or the step taken does)
  double max_step = 0.5;                // line search's largest step |x| (metres and radians together)
  NdtNeighbours neighbours = NdtNeighbours::kDirect7;
  int num_threads = 1;                // >1: score/gradient/Hessian accumulated over threads
  int min_source_points = 20;         // fewer finite source points: not converged, reason set
  int max_target_points = 2'000'000;  // largest target cloud accepted (points given, finite or not)
  int max_source_points = 500'000;    // largest source cloud accepted
  int max_target_voxels = 262'144;    // occupied voxels one target level may hold (~200 B each)
  // The aligner keeps one target per level (true) or one for all (false: rebuilt at every level).
  // Per level, align()'s target_version can skip every rebuild for a caller that aligns many
  // sources or guesses against one cloud, at levels x the memory.
  bool target_per_level = false;
  // Degeneracy test at the end of the finest level: the Hessian, its rotation block scaled by the
  // source cloud's RMS radius about the pivot (so both blocks are in m^-2), is degenerate when its
  // smallest eigenvalue is below this fraction of its largest. Measured: a single plane 0.001 (only
  // the regularised in-plane spread holds it), the synthetic room of the tests 0.23, the outdoor
  // LiDAR pair of ../shared/data 0.018-0.06.
  double degenerate_eigenvalue_ratio = 0.005;
};

enum class NdtFailure : uint8_t {
  kNone,
  kTooFewSourcePoints,
  kTooFewTargetVoxels,  // fewer than 2 voxels with a Gaussian at some level
  kNoCorrespondences,   // no transformed source point fell near a Gaussian
  kDegenerate,          // Hessian rank-deficient along some direction (e.g. a single plane)
  kMaxIterations,       // the finest level did not converge in max_iterations
  kNonFinite,           // a NaN/inf appeared (never returned as a pose)
  kInvalidInput,        // null view, stride < 3, more points or voxels than the configured capacity
  kLineSearchFailed,    // the line search found no lower cost along a Newton step longer than 10x
                        // the epsilons: the cost jumps where points cross voxel faces (their
                        // neighbourhoods change) and the pose sits on such a jump. Shorter steps
                        // count as converged.
};
const char* ndt_failure_name(NdtFailure f);

struct NdtResult {
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  bool converged = false;
  NdtFailure failure = NdtFailure::kNone;
  int iterations = 0;       // Newton iterations, all levels
  double score = 0;         // sum s(p) at the result, eq. 6.9 (higher is better)
  double fitness = 0;       // score per source point with a correspondence, in [0, -d1]
  double inlier_ratio = 0;  // source points with a correspondence at the result / finite ones
  // Hessian of the cost -score at the result, finest level, over x = (t, phi) about the target
  // origin (T(x) p = Exp(phi) p + t applied on the left of T_target_source).
  Eigen::Matrix<double, 6, 6> hessian = Eigen::Matrix<double, 6, 6>::Zero();
  int levels = 0;            // levels run
  int nonfinite_points = 0;  // source points skipped because a coordinate was NaN or inf
  int correspondences = 0;   // source points with a correspondence at the result
  // The degeneracy test's measure at a converged result: the scaled Hessian's smallest eigenvalue over
  // its largest (NdtConfig::degenerate_eigenvalue_ratio); 0 when not judged.
  double eigenvalue_ratio = 0;
};

// The target's voxel Gaussians at one resolution. Fixed capacity; rebuilt with build().
class NdtTarget {
 public:
  // Errors (kInvalidArgument): bad config (see NdtAligner::create).
  static core::Expected<NdtTarget> create(const NdtConfig& config);
  // Voxelises `target` at `resolution_m`. Non-finite points are skipped and counted. Errors:
  // resolution not positive and finite or null view (kInvalidArgument); more points than
  // max_target_points or more occupied voxels than max_target_voxels (kOutOfRange; the target is
  // then empty). Never allocates.
  core::Status build(const PointsView& target, double resolution_m);
  // The same over several views at once (their points together: a map held in pieces, such as the
  // relocalizer's prior segments); max_target_points bounds their sum.
  core::Status build(const PointsView* targets, int n_targets, double resolution_m);
  int gaussian_voxels() const;
  int occupied_voxels() const;  // with or without a Gaussian, last build
  double resolution_m() const;
  int skipped_points() const;  // non-finite or beyond the ±2^20-voxel key range, last build
  NdtTarget(NdtTarget&&) noexcept;
  NdtTarget& operator=(NdtTarget&&) noexcept;
  ~NdtTarget();

  struct Impl;  // hash grid, per-voxel mean / inverse covariance (src/ndt_target.hpp)

 private:
  explicit NdtTarget(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
  friend class NdtAligner;
};

class NdtAligner {
 public:
  // Errors (kInvalidArgument): no positive, finite resolution before the 0 that ends the list, a
  // non-positive or non-finite resolution in it, outlier_ratio outside (0, 1), min_points_per_voxel
  // < 3, min_eigenvalue_ratio outside (0, 1], non-positive epsilons / max_step / iterations,
  // num_threads outside [1, 64], capacities < 1.
  static core::Expected<NdtAligner> create(const NdtConfig& config);
  // Aligns source to target from the initial guess, coarse to fine over config.resolutions_m
  // (building the target at each level). Never throws, never returns a non-finite pose; on failure
  // converged = false, failure says why and T_target_source is the last finite estimate.
  // target_version: 0, the target is built at every level of every call. Otherwise the caller
  // promises that a view with the same pointer, size, stride and version holds the same points:
  // a level whose target was last built from it at that resolution is not built again (with
  // target_per_level every level keeps its own; with one shared target only a single-level config
  // gains). Callers that align many sources or guesses against one cloud (the relocalizer's
  // hypotheses) number each new cloud.
  NdtResult align(const PointsView& target, const PointsView& source,
                  const Eigen::Isometry3d& T_target_source_guess, uint64_t target_version = 0);
  // One level against a prebuilt target (for callers that reuse a target over many sources).
  NdtResult align_level(const NdtTarget& target, const PointsView& source,
                        const Eigen::Isometry3d& T_target_source_guess);
  // Coarse to fine over prebuilt targets, levels[0 .. n_levels), coarse first, each at the resolution
  // it was built with (a caller that holds the targets of a static map: the relocalizer's whole
  // prior). Iterations and epsilons are this aligner's config; a coarse level's epsilons grow with its
  // side over the finest level's, as in align(). No level, or a null or unbuilt one, is an invalid
  // input.
  NdtResult align_prebuilt(const NdtTarget* const* levels, int n_levels, const PointsView& source,
                           const Eigen::Isometry3d& T_target_source_guess);

  // For the derivative tests: the cost f = -sum s(p) at the pose T(x) (see the parameterisation at
  // the top, pivot `pivot_m`), and its gradient and Hessian with respect to a left perturbation
  // dx, T(dx) * T(x), at dx = 0 (at x = 0 these are the derivatives with respect to x itself).
  // Non-finite source points are skipped.
  double evaluate(const NdtTarget& target, const PointsView& source, const Eigen::Matrix<double, 6, 1>& x,
                  Eigen::Matrix<double, 6, 1>* gradient, Eigen::Matrix<double, 6, 6>* hessian,
                  const Eigen::Vector3d& pivot_m = Eigen::Vector3d::Zero());

  const NdtConfig& config() const;
  NdtAligner(NdtAligner&&) noexcept;
  NdtAligner& operator=(NdtAligner&&) noexcept;
  ~NdtAligner();

 private:
  struct Impl;
  explicit NdtAligner(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hwr::recon
