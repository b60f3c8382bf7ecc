#pragma once
// Two-view triangulation of a feature match between keyframes (paper item 6, eq. 4): linear DLT
// (Hartley & Zisserman 2004, sec. 12.2) on normalised image coordinates, then the checks ORB-SLAM
// applies to a new map point (Mur-Artal et al., T-RO 2015 sec. V-D): enough parallax, in front of
// both cameras within the depth range, small reprojection error in both views.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::estimation {

struct TriangulationConfig {
  double min_parallax_deg = 1.0;
  double max_reproj_px = 2.0;
  double min_depth_m = 0.05;
  double max_depth_m = 50;
};

// kBehindCamera: the depth in either view is not within [min_depth_m, max_depth_m] (behind the
// camera, too close or too far). kDegenerate: the DLT solution is at infinity or not finite.
enum class TriangulationStatus { kOk, kLowParallax, kBehindCamera, kLargeReprojection, kDegenerate };

const char* to_string(TriangulationStatus status);

// p_world is written whenever the DLT gives a finite point (also for the failed checks after it).
TriangulationStatus triangulate_two_view(const Eigen::Isometry3d& T_cam0_world,
                                         const Eigen::Isometry3d& T_cam1_world,
                                         const hal::PinholeIntrinsics& K0, const hal::PinholeIntrinsics& K1,
                                         const Eigen::Vector2d& uv0_px, const Eigen::Vector2d& uv1_px,
                                         const TriangulationConfig& cfg, Eigen::Vector3d* p_world);

}  // namespace hwr::estimation
