#pragma once
// Test helper: an analytic depth camera. A scene of oriented boxes and an optional horizontal floor
// is ray-cast at every pixel centre (OpenCV pinhole: x right, y down, z forward; no distortion),
// giving the depth (camera z, metres, 0 where nothing is hit) and the id of the object hit (-1:
// nothing). Optional depth noise sigma(z) along z and NaN dropouts, each from its own seed. On
// request also a grey colour image, shaded as the simulator's renderer (hal/sim render.cpp): the hit
// face's albedo times a procedural texture times (ambient + (1 - ambient) max(0, n . l)) for a
// directional light, two-sided, point-sampled at the pixel centre, plus Gaussian pixel noise.

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "hwr/detect/depth_noise.hpp"
#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::testing {

// A face's pattern, in the face's own coordinates (the box's two other axes, metres):
//  kPlain: none; kSpeckled: 6 mm cells, 12 % of them dark (x 0.35), 6 % bright (x 1.25), the rest
//  within +-8 %; kScratched: speckled, plus brushed streaks (rows 1.5 mm high along the face's first
//  axis, +-10 %) and 40 dark scratches (x 0.3, 1.5 mm wide, 2-8 cm long, any direction) - texture
//  lines as on rusty or ground steel.
enum class Texture { kPlain, kSpeckled, kScratched };

struct RenderBox {
  Eigen::Isometry3d T_world_box = Eigen::Isometry3d::Identity();  // box centre and axes
  Eigen::Vector3d half_size_m = Eigen::Vector3d::Constant(0.5);
  int id = 1;           // 0 is the floor's
  double albedo = 0.7;  // grey level / 255 under full light
  Texture texture = Texture::kPlain;
  uint32_t texture_seed = 1;
};

struct RenderScene {
  std::vector<RenderBox> boxes;
  bool has_floor = false;  // the plane z = floor_z_m (world z up), id 0, seen from either side
  double floor_z_m = 0.0;
  double floor_albedo = 0.6;
  Texture floor_texture = Texture::kSpeckled;
  // The light (the simulator's lab: towards (0.3, 0.2, -1), ambient 0.35).
  Eigen::Vector3d light_dir_world{0.3, 0.2, -1.0};
  double ambient = 0.35;
};

struct RenderOptions {
  bool add_noise = false;  // z += N(0, sigma(z)) on every hit pixel
  detect::DepthNoiseModel noise;
  uint32_t noise_seed = 1;
  double nan_fraction = 0.0;  // this fraction of all pixels (in expectation) becomes NaN
  uint32_t nan_seed = 2;
  bool colour = false;             // also render bgr
  double pixel_noise_sigma = 2.0;  // grey levels (the simulator's ExposureSpec)
  uint32_t pixel_noise_seed = 3;
};

struct RenderedDepth {
  cv::Mat depth_m;  // CV_32FC1, K's size
  cv::Mat id;       // CV_32SC1, the noise-free hit's id, -1 where nothing is hit
  cv::Mat bgr;      // CV_8UC3 (grey), when RenderOptions::colour; background (no hit) 200
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

// A butt joint in the simulator's convention (scene_truth.cpp append_joint_plates): joint frame origin =
// the seam start on the plates' top faces, x along the seam (yaw about world z), z up; "left" plate
// x in [0, L], y in [gap / 2, gap / 2 + w], z in [-t, 0]; "right" the same at -y. The seam is the gap's
// centre line on the top faces; the plates lie on a support whose top is at start_world.z() - t.
struct ButtJoint {
  Eigen::Isometry3d T_world_joint = Eigen::Isometry3d::Identity();
  RenderBox left, right;
  Eigen::Vector3d start_world = Eigen::Vector3d::Zero();  // = the joint origin
  Eigen::Vector3d end_world = Eigen::Vector3d::Zero();    // = origin + L x_joint
};

ButtJoint make_butt(const Eigen::Vector3d& start_world, double yaw_rad, double length_m, double plate_width_m,
                    double thickness_m, double gap_m, int left_id, int right_id);

}  // namespace hwr::testing
