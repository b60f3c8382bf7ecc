// Helpers shared by the simulator tests: VGA intrinsics, look-at camera poses, rigid poses from a
// rotation vector and the slab-method ray/box oracle.

#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::sim::testing {

// 640x480 pinhole camera with cx = 319.5 and the given focal lengths and cy.
inline hal::PinholeIntrinsics vga(double fx, double fy, double cy) {
  hal::PinholeIntrinsics K;
  K.width = 640;
  K.height = 480;
  K.fx = fx;
  K.fy = fy;
  K.cx = 319.5;
  K.cy = cy;
  return K;
}

// The usual 640x480 camera: fx = fy = 525, principal point at the image centre.
inline hal::PinholeIntrinsics vga() { return vga(525.0, 525.0, 239.5); }

// Camera at `eye` looking at `target`, OpenCV axes (x right, y down, z forward), world z up.
inline Eigen::Isometry3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = x;
  T.linear().col(1) = z.cross(x);
  T.linear().col(2) = z;
  T.translation() = eye;
  return T;
}

// Rigid pose from a translation and a rotation vector (axis times angle).
inline Eigen::Isometry3d pose(const Eigen::Vector3d& t, const Eigen::Vector3d& rotation_vector) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (rotation_vector.norm() > 0)
    T.linear() = Eigen::AngleAxisd(rotation_vector.norm(), rotation_vector.normalized()).toRotationMatrix();
  T.translation() = t;
  return T;
}

// Distance along the ray from o_scene in direction d_scene (any length) to a centred box of edge
// lengths `size` placed at T_scene_box (slab method in the box frame); +inf on a miss. That is the
// entry point; when the ray starts inside the box it is the exit with exit_if_inside (a mesh of
// surfaces, not solids) and +inf without.
inline double ray_box_slab(const Eigen::Vector3d& size, const Eigen::Isometry3d& T_scene_box,
                           const Eigen::Vector3d& o_scene, const Eigen::Vector3d& d_scene,
                           bool exit_if_inside) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const Eigen::Isometry3d T_box_scene = T_scene_box.inverse();
  const Eigen::Vector3d o = T_box_scene * o_scene;
  const Eigen::Vector3d d = T_box_scene.linear() * d_scene.normalized();
  double t0 = -kInf, t1 = kInf;
  for (int k = 0; k < 3; ++k) {
    const double h = 0.5 * size[k];
    if (std::abs(d[k]) < 1e-15) {
      if (std::abs(o[k]) > h) return kInf;
      continue;
    }
    double a = (-h - o[k]) / d[k], b = (h - o[k]) / d[k];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  if (t0 > t1) return kInf;
  if (t0 > 0) return t0;
  return (exit_if_inside && t1 > 0) ? t1 : kInf;
}

}  // namespace hwr::sim::testing
