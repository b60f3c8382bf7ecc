#pragma once
// Test helper: an analytic depth camera. A scene of oriented boxes and an optional horizontal floor
// is ray-cast at every pixel centre (OpenCV pinhole: x right, y down, z forward; no distortion),
// giving the depth (camera z, metres, 0 where nothing is hit) and the id of the object hit (-1:
// nothing). Optional depth noise sigma(z) along z and NaN dropouts, each from its own seed.

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "hwr/detect/depth_noise.hpp"
#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::testing {

struct RenderBox {
  Eigen::Isometry3d T_world_box = Eigen::Isometry3d::Identity();  // box centre and axes
  Eigen::Vector3d half_size_m = Eigen::Vector3d::Constant(0.5);
  int id = 1;  // 0 is the floor's
};

struct RenderScene {
  std::vector<RenderBox> boxes;
  bool has_floor = false;  // the plane z = floor_z_m (world z up), id 0, seen from either side
  double floor_z_m = 0.0;
};

struct RenderOptions {
  bool add_noise = false;  // z += N(0, sigma(z)) on every hit pixel
  detect::DepthNoiseModel noise;
  uint32_t noise_seed = 1;
  double nan_fraction = 0.0;  // this fraction of all pixels (in expectation) becomes NaN
  uint32_t nan_seed = 2;
};

struct RenderedDepth {
  cv::Mat depth_m;  // CV_32FC1, K's size
  cv::Mat id;       // CV_32SC1, the noise-free hit's id, -1 where nothing is hit
};

// 640 x 480, f 525 px, centred: the simulator's camera.
hal::PinholeIntrinsics vga_intrinsics();

RenderedDepth render_depth(const RenderScene& scene, const hal::PinholeIntrinsics& K,
                           const Eigen::Isometry3d& T_world_cam, const RenderOptions& options = {});

// The camera at eye_world looking at target_world, image "up" towards world +z (camera y ~ -z).
// The view direction must not be vertical.
Eigen::Isometry3d look_at(const Eigen::Vector3d& eye_world, const Eigen::Vector3d& target_world);

// A fillet joint in the simulator's convention (hal/sim scenario.cpp add_fillet, scene_truth.cpp):
// joint frame origin = the seam start on the base's top face, x along the seam (yaw about world z),
// z up; base x in [0, L], y in [-bw, 0], z in [-t, 0]; web x in [0, L], y in [0, t], z in [0, ww]
// (its y = 0 face is the seam side). The base lies on a support whose top is at start_world.z() - t.
struct FilletJoint {
  Eigen::Isometry3d T_world_joint = Eigen::Isometry3d::Identity();
  RenderBox base, web;
  Eigen::Vector3d start_world = Eigen::Vector3d::Zero();  // = the joint origin
  Eigen::Vector3d end_world = Eigen::Vector3d::Zero();    // = origin + L x_joint
};

FilletJoint make_fillet(const Eigen::Vector3d& start_world, double yaw_rad, double length_m,
                        double base_width_m, double web_height_m, double thickness_m, int base_id,
                        int web_id);

}  // namespace hwr::testing
