#pragma once
// Junction alignment between consecutive local maps (paper sec. II-D; issue #4 item 4): ORB matches
// between the last keyframe before a cut (a) and the first after it (b) give an initial relative
// pose (FLANN LSH matching, RANSAC over 3D-2D / 3D-3D minimal sets with the keypoints' depth), which
// seeds NDT between the two keyframes' clouds (each in its own camera frame). The refined T_a_b
// joins the two segments; when ORB finds too few inliers the estimator's odometry seeds NDT, and
// when NDT does not converge the junction keeps the best earlier estimate and says so.

#include <Eigen/Geometry>
#include <memory>

#include "hwr/core/status.hpp"
#include "hwr/estimation/keyframe_store.hpp"
#include "hwr/estimation/lsh_matcher.hpp"
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
};

enum class JunctionSeed : uint8_t { kOrb, kOdometry };

struct JunctionResult {
  Eigen::Isometry3d T_a_b = Eigen::Isometry3d::Identity();  // refined: camera b in camera a
  JunctionSeed seed = JunctionSeed::kOdometry;
  int orb_matches = 0, orb_inliers = 0;
  NdtResult ndt;
  bool ndt_used = false;                      // T_a_b is NDT's result (else the seed)
  double orb_rms_px = 0, ndt_orb_rms_px = 0;  // ORB inliers' reprojection RMS under each pose
};

class JunctionAligner {
 public:
  static core::Expected<JunctionAligner> create(const JunctionConfig& config, int max_features);

  // cloud_*_cam: each keyframe's cloud in its own camera frame. T_a_b_odometry: the estimator's
  // relative pose (the fallback seed).
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
