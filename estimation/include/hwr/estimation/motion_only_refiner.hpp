#pragma once
// Pose-only optimisation of one frame against known 3D points (ORB-SLAM's PoseOptimization,
// Mur-Artal & Tardós, T-RO 2017 sec. IV-B): Levenberg-Marquardt on SE(3) with a Huber kernel,
// reprojection residuals whitened by the keypoint's octave scale plus, for RGB-D keypoints, a depth
// residual; after each round every correspondence is re-classified by a chi-square test, so
// outliers leave the next round and inliers that come back re-enter it. Allocation-free.

#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::estimation {

// A 3D point (world) observed at pixel uv_px of the frame at pyramid level `octave`, with the
// frame's depth at that pixel (0 = none).
struct Correspondence {
  Eigen::Vector3d p_world;
  Eigen::Vector2d uv_px;
  double depth_m = 0;
  int octave = 0;
};

struct RefineConfig {
  int rounds = 4;
  int iterations_per_round = 10;
  double huber_px = 2.45;   // sqrt(5.99): Huber threshold on the whitened 2-dof residual
  double chi2_px2 = 5.991;  // 95 % chi-square, 2 dof (pixel residual / sigma)
  bool use_depth = true;
  double depth_sigma_per_m2 = 0.0015;  // depth sigma = c * depth^2 (structured-light noise model)
  // Added to the brief's fields: the 3-dof (u, v, depth) test and the pyramid scale that sets the
  // pixel sigma of each octave, scale_factor^octave (as OrbConfig::scale_factor).
  double huber_3dof = 2.796;  // sqrt(7.815)
  double chi2_3dof = 7.815;   // 95 % chi-square, 3 dof
  double scale_factor = 1.2;
  int min_inliers = 10;  // fewer: ok = false
};

struct RefineResult {
  Eigen::Isometry3d T_cam_world = Eigen::Isometry3d::Identity();
  int inliers = 0;
  double rms_px = 0;  // pixel reprojection RMS over the inliers
  bool ok = false;
  // Of dxi = (rho, phi) with T_cam_world <- exp(dxi) * T_cam_world (left, core::se3_exp), in m^2,
  // rad^2: the inverse Gauss-Newton information of the inliers' whitened residuals.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  int iterations = 0;  // LM iterations over all rounds
};

class MotionOnlyRefiner {
 public:
  explicit MotionOnlyRefiner(int max_correspondences);
  int max_correspondences() const { return max_correspondences_; }

  // Levenberg-Marquardt with Huber from T_init_cam_world; inlier_mask (size n) is written
  // (1 = inlier, 0 = outlier or behind the camera). Correspondences beyond max_correspondences are
  // ignored (mask 0).
  RefineResult refine(const Correspondence* c, int n, const hal::PinholeIntrinsics& K,
                      const Eigen::Isometry3d& T_init_cam_world, const RefineConfig& cfg,
                      uint8_t* inlier_mask);

 private:
  int max_correspondences_;
};

}  // namespace hwr::estimation
