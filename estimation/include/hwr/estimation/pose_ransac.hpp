#pragma once
// Robust absolute pose of a frame from 3D (world) - 2D (pixel) correspondences, with depth where
// the frame has it: RANSAC (Fischler & Bolles 1981) over minimal samples, hand-written and
// allocation-free after construction.
//
// Minimal solver: with depth on at least min_depth_fraction of the correspondences, 3 depth-backed
// points (eq. 3) -> rigid 3D-3D fit (Umeyama 1991 / Horn 1987); otherwise P3P on bearings (Lambda
// Twist, Persson & Nordberg, ECCV 2018). Hypotheses are scored MSAC-style (Torr & Zisserman 2000):
// reprojection error <= inlier_px * scale(octave), and depth consistency when depth_m > 0. The
// iteration count adapts to the inlier ratio; the best hypothesis is refined on all its inliers
// (MotionOnlyRefiner, one round) and the inliers re-evaluated.

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hwr/estimation/motion_only_refiner.hpp"  // Correspondence
#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::estimation {

struct PoseRansacConfig {
  int max_iterations = 200;
  double inlier_px = 3.0;
  double confidence = 0.999;
  int min_inliers = 12;
  uint64_t seed = 1;
  // Added to the brief's fields:
  double inlier_depth_frac = 0.05;  // |z - depth| <= frac * depth for correspondences with depth
  double min_depth_fraction = 0.2;  // below: P3P on bearings; > 1 forces P3P
  double scale_factor = 1.2;        // pyramid scale: pixel tolerance of octave k = inlier_px * s^k
  bool refine = true;               // final Gauss-Newton fit on the inliers
};

struct PoseRansacResult {
  Eigen::Isometry3d T_cam_world = Eigen::Isometry3d::Identity();
  int inliers = 0;
  int iterations = 0;
  bool ok = false;
  bool used_p3p = false;  // the minimal solver was P3P (else 3D-3D)
};

// Lambda Twist P3P: camera poses T_cam_world with bearing_k ~ T_cam_world * x_world_k, k = 0..2
// (bearings need not be unit). Writes up to 4 solutions, returns their count.
int p3p_lambda_twist(const Eigen::Vector3d bearings[3], const Eigen::Vector3d x_world[3],
                     std::array<Eigen::Isometry3d, 4>* solutions);

// Weighted least-squares rigid transform T with dst_k ~ T * src_k (Umeyama 1991 without scale).
// weights may be null (all 1). Needs n >= 3 non-collinear points; returns false when degenerate.
bool rigid_fit_3d3d(const Eigen::Vector3d* src, const Eigen::Vector3d* dst, const double* weights, int n,
                    Eigen::Isometry3d* T_dst_src);

class PoseRansac {
 public:
  explicit PoseRansac(int max_correspondences);

  // inlier_mask (size n) is written. Correspondences beyond max_correspondences are ignored.
  PoseRansacResult solve(const Correspondence* c, int n, const hal::PinholeIntrinsics& K,
                         const PoseRansacConfig& cfg, uint8_t* inlier_mask);

 private:
  double score(const Eigen::Isometry3d& T, int n, const PoseRansacConfig& cfg, uint8_t* mask, int* inliers,
               int* pool_inliers) const;

  int max_n_;
  std::vector<Eigen::Vector3d> bearing_;  // K^-1 (u, v, 1), not normalised
  std::vector<Eigen::Vector3d> p_cam_;    // eq. 3 back-projection where depth_m > 0
  std::vector<double> thr2_px2_;          // squared pixel tolerance per correspondence
  std::vector<int> pool_;                 // indices the minimal samples are drawn from
  std::vector<uint8_t> in_pool_;
  std::vector<uint8_t> mask_scratch_, best_mask_;
  std::vector<Correspondence> inlier_c_;
  std::vector<uint8_t> refine_mask_;
  const Correspondence* c_ = nullptr;
  hal::PinholeIntrinsics K_;
  MotionOnlyRefiner refiner_;
};

}  // namespace hwr::estimation
