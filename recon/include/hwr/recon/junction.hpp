#pragma once
// Junction alignment between consecutive local maps (paper sec. II-D; issue #4 item 4): ORB matches
// between the last keyframe before a cut (a) and the first after it (b) give an initial relative
// pose (FLANN LSH matching, RANSAC over 3D-2D / 3D-3D minimal sets with the keypoints' depth), which
// seeds NDT between the two keyframes' clouds (each in its own camera frame). When ORB finds too
// few inliers the estimator's odometry seeds NDT, and when NDT does not converge the junction keeps
// the best earlier estimate and says so.
//
// Beyond the paper: the measurement (ORB refined over its inliers, or NDT) is fused with the
// tracker's own relative pose between the same two keyframes, each weighted by its information
// (a maximum a posteriori estimate with the odometry as a Gaussian prior). A single keyframe pair
// measures rotation 2-4x worse than the tracker, and over tens of junctions that error chains into
// the segmented trajectory. With correct covariances the fused junction is, in expectation, no worse
// than the better of the two; the prior's sigmas and orb_covariance_scale are fixed settings, so on
// a given scene it can be slightly worse than the measurement alone (docs/reconstruction.md).
// Only NDT's pose (the depth geometry) is fused by default: an ORB pose alone re-measures what the
// tracker measured from the same keypoints, so when it agrees with the odometry the odometry stays,
// and when it does not (gated out: the tracker lost or jumped) the measurement replaces it.

#include <Eigen/Geometry>
#include <memory>

#include "hwr/core/status.hpp"
#include "hwr/estimation/keyframe_store.hpp"
#include "hwr/estimation/lsh_matcher.hpp"
#include "hwr/estimation/motion_only_refiner.hpp"
#include "hwr/estimation/pose_ransac.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/recon/ndt.hpp"

namespace hwr::recon {

struct JunctionConfig {
  estimation::LshConfig lsh;
  estimation::PoseRansacConfig ransac;
  int min_orb_inliers = 25;  // fewer: the ORB pose is not trusted and odometry seeds NDT
  NdtConfig ndt = [] {
    NdtConfig c;
    c.resolutions_m = {1.0, 0.5, 0.25, 0.125};
    return c;  // point capacities: LocalMapper::create sizes them for its junction clouds
  }();
  // NDT's answer is kept only when it stays this close to its seed: the ORB seed (hundreds of
  // inliers) and the odometry are good to a few millimetres, so a larger jump means NDT slid along a
  // nearly degenerate scene (a corridor, a wall and floor) rather than corrected the seed.
  double max_ndt_correction_m = 0.03;
  double max_ndt_correction_rad = 0.01;
  // ... and when it reprojects the ORB inliers with an RMS error at most this ratio (+ 0.1 px) of
  // the ORB pose's own.
  double max_ndt_reprojection_ratio = 1.2;
  // Motion-only refinement of the RANSAC pose over all matches (gives the ORB pose's covariance).
  estimation::RefineConfig refine;
  // The refiner's covariance treats a's keypoints as exact; their depth noise is not, so the
  // measurement's covariance is this factor times the refiner's.
  double orb_covariance_scale = 4.0;
  // The tracker's relative pose between two consecutive keyframes as a prior: 1-sigma per axis of
  // rotation (rad) and translation (m). fuse_odometry = false keeps the measurement alone (paper).
  bool fuse_odometry = true;
  double odometry_sigma_rad = 0.0005;
  double odometry_sigma_m = 0.002;
  // A measurement whose Mahalanobis distance to the odometry (6 dof) exceeds this is not fused:
  // one of the two is wrong, and the measurement (hundreds of inliers, checked by NDT) is kept.
  double fusion_gate_chi2 = 22.46;  // 99.9 %, 6 dof
  // An ORB pose that NDT did not refine (NDT degenerate, not converged, or not agreeing) and that
  // passes the gate: false keeps the odometry, true fuses it too. Its error is largely the
  // tracker's own (the same keypoints of the same two keyframes; outdoors, fusing the 0.046 deg
  // measurements with the 0.037 deg odometry gave 0.037 deg, where independent errors would give
  // ~0.029), so fusing it as independent information moves each junction by a fresh error that
  // chains over the cuts (docs/reconstruction.md).
  bool fuse_orb_alone = false;
};

enum class JunctionSeed : uint8_t { kOrb, kOdometry };

struct JunctionResult {
  Eigen::Isometry3d T_a_b = Eigen::Isometry3d::Identity();  // refined: camera b in camera a
  JunctionSeed seed = JunctionSeed::kOdometry;
  int orb_matches = 0, orb_inliers = 0;
  NdtResult ndt;
  bool ndt_used = false;                      // T_a_b is NDT's result (else the seed)
  double orb_rms_px = 0, ndt_orb_rms_px = 0;  // ORB inliers' reprojection RMS under each pose
  // The measurement before fusion (ORB or NDT; the odometry when neither is trusted) and whether
  // T_a_b fuses it with the odometry (false: gated out, disabled, no ORB covariance, or an ORB pose
  // alone that agreed with the odometry: odometry_kept).
  Eigen::Isometry3d T_a_b_measured = Eigen::Isometry3d::Identity();
  bool fused = false;
  bool odometry_kept = false;  // the ORB pose alone agreed with the odometry, which stays (fuse_orb_alone)
  double fusion_chi2 = 0;      // Mahalanobis distance^2 of measurement vs odometry
};

class JunctionAligner {
 public:
  static core::Expected<JunctionAligner> create(const JunctionConfig& config, int max_features);

  // cloud_*_cam: each keyframe's cloud in its own camera frame. T_a_b_odometry: the estimator's
  // relative pose (the prior, and the fallback seed).
  JunctionResult align(const estimation::Keyframe& a, const estimation::Keyframe& b,
                       const hal::PinholeIntrinsics& K, const PointsView& cloud_a_cam,
                       const PointsView& cloud_b_cam, const Eigen::Isometry3d& T_a_b_odometry);

  JunctionAligner(JunctionAligner&&) noexcept;
  JunctionAligner& operator=(JunctionAligner&&) noexcept;
  ~JunctionAligner();

 private:
  struct Impl;
  explicit JunctionAligner(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hwr::recon
