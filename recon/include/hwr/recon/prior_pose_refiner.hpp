#pragma once
// Local refinement of a keyframe's T_prior_cam against the prior map before carving (issue #6
// item 3; docs/prior_map_update.md). The free-space carver needs the pose to ~2 mm / 0.1 deg along
// the normals of the surfaces it checks; the relocalization gives 1-6 cm / 0.3 deg.
//
// Method: projective point-to-plane Gauss-Newton on the carver's own geometry
// (free_space_carver.hpp, "point-to-plane normal equations"). The keyframe's local planes are
// measured once (least-squares planes of 1/z at every stride_px-th pixel, up to max_depth_m: farther
// than the carver reaches, since the fit averages the range noise); every iteration casts them into
// the Embree spheres of each prior segment in view from the current pose (re-pairing), where each
// ray's residual is the height r = n̂·(p̄ − q_m) of the robustly weighted mean p̄ of the prior points
// near it above its measured plane. The 6x6 normal equations of all views, for ξ = (ω, v) in the
// camera frame (T_prior_cam · exp(ξ)), are divided by the squared robust scale of the residuals
// (σ ≈ 1.4826 median |r| / σ_ray: information), the guess's own information (the correction carried
// from earlier keyframes, PriorMapUpdater) is added as a prior on the correction so far, and the
// step is solved in the well-constrained subspace only:
//   - the rotation is scaled by lever_m (ω · lever_m is a displacement) and the information matrix
//     is eigen-decomposed at the first iteration; a direction is moved when its eigenvalue is within
//     min_eigen_ratio of the largest or its σ = 1 / sqrt(λ) is at most max_sigma_m. The others (a
//     floor-only view leaves the two horizontal translations and the yaw free) keep the guess. The
//     subspace stays fixed over the iterations: re-estimated, it would leak the noise of each
//     re-pairing into the weak directions, which then random-walk (measured: 9.7 mm on an exact pose);
//   - robust: Tukey's biweight on each prior point's height; the first iteration takes every pair
//     within ±window_m, later ones c = 4.685 σ per ray (not below min_tukey_c_sigmas σ_ray).
// Converged: a step below converged_step_m and converged_step_rad, or one whose squared Mahalanobis
// length is below converged_mahalanobis2 (the re-paired residuals differ a little each time, so the
// steps stop shrinking at the estimate's own noise), after min_iterations.
// Fails closed: a refinement that does not converge within max_iterations, meets fewer than min_rays
// residuals, or ends more than max_correction_m / max_correction_rad from the anchor (the
// relocalized pose) returns the starting guess unchanged, and the carver's own pose check then
// decides about the frame.
//
// No allocation in refine(): the plane buffer is sized at create(), the views are the caller's
// array, the systems are fixed size, the eigen solver 6x6.

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "hwr/core/status.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/recon/free_space_carver.hpp"

namespace hwr::recon {

struct PriorPoseRefinerConfig {
  bool enabled = true;
  int stride_px = 8;              // rays on every 8th pixel in u and v (4 800 at 640x480) ...
  int offset_px = 4;              // ... starting here: between the pose check's rays (stride 8 from 0)
  int plane_radius_px = 6;        // local plane: least squares over ±this ...
  int plane_step_px = 2;          // ... every this many pixels (7 x 7 samples)
  float max_depth_m = 4.0f;       // planes up to here (beyond the carver's range: the fit averages the noise)
  float depth_noise_m0 = 0.001f;  // sigma_z = m0 + k z² (k: the carver's); the simulator's ZED-like m0
  float max_dev_sigmas = 4.5f;    // a plane's fit residuals (1/z) within this many sigma ...
  float max_rms_sigmas = 1.5f;    // ... and their RMS within this many
  float window_m = 0.07f;         // prior points within ±this of the measured plane pair with a ray
  float min_tukey_c_sigmas = 3.0f;  // Tukey c after the first iteration, at least this many σ_ray
  int max_iterations = 20;
  int min_iterations = 3;                // the robust scale settles over the first ones
  double converged_step_m = 1e-4;        // last step's translation ...
  double converged_step_rad = 3e-5;      // ... and rotation (0.0017 deg), or
  double converged_mahalanobis2 = 0.02;  // ... its squared Mahalanobis length (the estimate's noise)
  double lever_m = 1.5;                  // rotation scale for the subspace: ω lever_m is a displacement
  double min_eigen_ratio = 0.02;         // directions with λ < this λ_max ...
  double max_sigma_m = 0.002;            // ... and σ = 1/sqrt(λ) above this are not moved
  int min_rays = 200;                    // residuals (rays meeting the prior within the window)
  double max_correction_m = 0.08;        // from the anchor: beyond, the refinement is not trusted
  double max_correction_rad = 0.02;      // 1.15 deg
};

enum class PoseRefinement : uint8_t {
  kOff,           // disabled or no views
  kConverged,     // T_prior_cam refined
  kNotConverged,  // max_iterations without a step below the limits: the guess is returned
  kTooFewRays,    // fewer than min_rays residuals: the guess is returned
  kTooLarge,      // the correction from the anchor exceeds the limits: the guess is returned
};

struct PriorPoseRefinement {
  Eigen::Isometry3d T_prior_cam = Eigen::Isometry3d::Identity();  // refined, or the guess
  PoseRefinement result = PoseRefinement::kOff;
  int iterations = 0;
  int residuals = 0;                            // of the last iteration
  int constrained_dims = 0;                     // of the subspace fixed at the first iteration (0-6)
  float median_abs_residual_sigmas = 0;         // last iteration
  double step_m = 0, step_rad = 0;              // last step
  double correction_m = 0, correction_rad = 0;  // anchor^-1 * result (camera frame): converged, too large
  // The last iteration's information about xi (camera frame of the result), from the data alone:
  // its normal matrix divided by the squared robust scale of the residuals (the scale is at least 1:
  // never above the noise model), the directions that kept the guess included.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
};

// Where the refinement starts, and what is known there.
struct PriorPoseGuess {
  Eigen::Isometry3d T_prior_cam = Eigen::Isometry3d::Identity();  // the starting guess
  // The correction from here is bounded (max_correction_*): the relocalized pose (the guess may
  // already carry an earlier keyframe's correction).
  Eigen::Isometry3d T_prior_cam_anchor = Eigen::Isometry3d::Identity();
  // Information (inverse covariance) of the guess about xi = (omega rad, v m), T_prior_cam * exp(xi)
  // in the camera frame: a prior on the correction that keeps it where earlier keyframes put it in
  // the directions this one hardly sees. Zero: none.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
};

// A prior segment in view: its carver (points in the segment frame) and where the segment lies.
struct PriorView {
  FreeSpaceCarver* carver = nullptr;
  Eigen::Isometry3d T_prior_segment = Eigen::Isometry3d::Identity();
};

class PriorPoseRefiner {
 public:
  // Sizes the measured-plane buffer for K's image. Errors (kInvalidArgument): invalid intrinsics or
  // config (stride_px, offset_px, plane_radius_px, plane_step_px, max_iterations, min_iterations < 1
  // where they must be >= 1, non-positive window_m, lever_m or correction limits, min_eigen_ratio
  // outside (0, 1), negative converged_mahalanobis2).
  static core::Expected<PriorPoseRefiner> create(const PriorPoseRefinerConfig& config,
                                                 const hal::PinholeIntrinsics& K);

  // Refines T_prior_cam from the guess against views[0, n_views) (header); the views' carvers give
  // the planes' depth range and noise model (those of views[0]). Allocates nothing. Errors
  // (kInvalidArgument): the carvers' (bad depth image, non-rigid poses), views null with n_views > 0,
  // a null carver, a non-finite guess.
  core::Expected<PriorPoseRefinement> refine(const PriorView* views, int n_views, const cv::Mat& depth_m,
                                             const PriorPoseGuess& guess);

  // The same from another guess, or against other views, with the planes the last refine() measured
  // (same image; kOff when it measured none). PriorMapUpdater refines each segment alone this way.
  // max_iterations > 0 caps the iterations below the configuration's (a guess that is already close).
  core::Expected<PriorPoseRefinement> refine_again(const PriorView* views, int n_views,
                                                   const PriorPoseGuess& guess, int max_iterations = 0);

  const PriorPoseRefinerConfig& config() const { return config_; }
  // The local planes the last refine() measured (none before one, or when it was off): the carver's
  // pose check casts them too (FreeSpaceCarver::observe with check planes).
  const MeasuredPlane* planes() const { return planes_.data(); }
  int plane_count() const { return n_planes_; }

 private:
  PriorPoseRefiner(const PriorPoseRefinerConfig& config, const hal::PinholeIntrinsics& K, int capacity);
  static core::Status check_inputs(const PriorView* views, int n_views, const PriorPoseGuess& guess);
  // Gauss-Newton from the guess on planes_[0, n_planes_) (header).
  core::Expected<PriorPoseRefinement> solve(const PriorView* views, int n_views, const PriorPoseGuess& guess,
                                            int max_iterations);
  PriorPoseRefinerConfig config_;
  hal::PinholeIntrinsics K_;
  std::vector<MeasuredPlane> planes_;  // capacity: the sampled pixels of one image
  int n_planes_ = 0;                   // measured by the last refine()
};

const char* to_string(PoseRefinement r);

}  // namespace hwr::recon
