#pragma once
// The world frame of a run (ARCHITECTURE.md: "world = first IMU frame of a run"), made
// gravity-aligned so that gravity is (0, 0, -g) in it as in the scene: origin at the IMU position
// at the first sample, z up, x = the IMU x axis projected onto the horizontal plane. The
// simulator's walks start standing still and level, so this is exactly the first IMU frame.
// Runs in the same scene (revisits) relate through their T_scene_world: T_prior_current =
// T_scene_world_prior^-1 * T_scene_world_current.

#include <cmath>

#include <Eigen/Geometry>

namespace hwr::sim {

inline Eigen::Isometry3d world_frame_from_first_imu_pose(const Eigen::Isometry3d& T_scene_imu0) {
  const Eigen::Vector3d x = T_scene_imu0.linear().col(0);
  // Heading of the IMU x axis; a (near-)vertical x axis falls back to the y axis's heading.
  double yaw = std::atan2(x.y(), x.x());
  if (std::hypot(x.x(), x.y()) < 1e-9) {
    const Eigen::Vector3d y = T_scene_imu0.linear().col(1);
    yaw = std::atan2(y.y(), y.x()) - M_PI / 2;
  }
  Eigen::Isometry3d T_scene_world = Eigen::Isometry3d::Identity();
  T_scene_world.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T_scene_world.translation() = T_scene_imu0.translation();
  return T_scene_world;
}

}  // namespace hwr::sim
