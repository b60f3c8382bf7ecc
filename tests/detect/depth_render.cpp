#include "depth_render.hpp"

#include <cmath>
#include <limits>
#include <random>

namespace hwr::testing {
namespace {

// Slab test (Kay and Kajiya): the ray o + t d against the box |x_i| <= h_i in its own frame.
// Returns the entry parameter, or +inf for a miss or a ray starting inside.
double ray_box(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& h) {
  double t_near = -std::numeric_limits<double>::infinity();
  double t_far = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d(i)) < 1e-15) {
      if (std::abs(o(i)) > h(i)) return std::numeric_limits<double>::infinity();
      continue;
    }
    double t0 = (-h(i) - o(i)) / d(i), t1 = (h(i) - o(i)) / d(i);
    if (t0 > t1) std::swap(t0, t1);
    t_near = std::max(t_near, t0);
    t_far = std::min(t_far, t1);
  }
  if (t_near > t_far || t_near <= 0.0) return std::numeric_limits<double>::infinity();
  return t_near;
}

}  // namespace

hal::PinholeIntrinsics vga_intrinsics() {
  hal::PinholeIntrinsics K;
  K.width = 640;
  K.height = 480;
  K.fx = K.fy = 525.0;
  K.cx = 319.5;
  K.cy = 239.5;
  return K;
}

RenderedDepth render_depth(const RenderScene& scene, const hal::PinholeIntrinsics& K,
                           const Eigen::Isometry3d& T_world_cam, const RenderOptions& options) {
  RenderedDepth out;
  out.depth_m = cv::Mat(K.height, K.width, CV_32FC1, cv::Scalar(0.0f));
  out.id = cv::Mat(K.height, K.width, CV_32SC1, cv::Scalar(-1));
  const Eigen::Vector3d o_world = T_world_cam.translation();
  const Eigen::Matrix3d R_world_cam = T_world_cam.linear();
  // Each box's ray origin and rotation in its own frame, once.
  std::vector<Eigen::Isometry3d> T_box_world;
  for (const RenderBox& b : scene.boxes) T_box_world.push_back(b.T_world_box.inverse());
  std::mt19937 noise_rng(options.noise_seed), nan_rng(options.nan_seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  for (int v = 0; v < K.height; ++v) {
    float* depth = out.depth_m.ptr<float>(v);
    int* id = out.id.ptr<int>(v);
    for (int u = 0; u < K.width; ++u) {
      // The ray's camera z component is 1, so its parameter at a hit is the hit's camera depth.
      const Eigen::Vector3d d_cam((u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0);
      const Eigen::Vector3d d_world = R_world_cam * d_cam;
      double best = std::numeric_limits<double>::infinity();
      int best_id = -1;
      if (scene.has_floor && std::abs(d_world.z()) > 1e-15) {
        const double t = (scene.floor_z_m - o_world.z()) / d_world.z();
        if (t > 0.0) {
          best = t;
          best_id = 0;
        }
      }
      for (size_t i = 0; i < scene.boxes.size(); ++i) {
        const double t =
            ray_box(T_box_world[i] * o_world, T_box_world[i].linear() * d_world, scene.boxes[i].half_size_m);
        if (t < best) {
          best = t;
          best_id = scene.boxes[i].id;
        }
      }
      if (best_id < 0) continue;
      id[u] = best_id;
      double z = best;
      if (options.add_noise) z += options.noise.sigma_m(best) * normal(noise_rng);
      depth[u] = static_cast<float>(z);
    }
  }
  if (options.nan_fraction > 0.0) {
    for (int v = 0; v < K.height; ++v) {
      float* depth = out.depth_m.ptr<float>(v);
      for (int u = 0; u < K.width; ++u) {
        if (uniform(nan_rng) < options.nan_fraction) depth[u] = std::numeric_limits<float>::quiet_NaN();
      }
    }
  }
  return out;
}

Eigen::Isometry3d look_at(const Eigen::Vector3d& eye_world, const Eigen::Vector3d& target_world) {
  const Eigen::Vector3d z_cam = (target_world - eye_world).normalized();
  const Eigen::Vector3d x_cam = z_cam.cross(Eigen::Vector3d::UnitZ()).normalized();  // right
  const Eigen::Vector3d y_cam = z_cam.cross(x_cam);                                  // down
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  T_world_cam.linear().col(0) = x_cam;
  T_world_cam.linear().col(1) = y_cam;
  T_world_cam.linear().col(2) = z_cam;
  T_world_cam.translation() = eye_world;
  return T_world_cam;
}

FilletJoint make_fillet(const Eigen::Vector3d& start_world, double yaw_rad, double length_m,
                        double base_width_m, double web_height_m, double thickness_m, int base_id,
                        int web_id) {
  FilletJoint j;
  j.T_world_joint.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  j.T_world_joint.translation() = start_world;
  const double L = length_m, bw = base_width_m, ww = web_height_m, t = thickness_m;
  j.base.T_world_box = j.T_world_joint * Eigen::Translation3d(0.5 * L, -0.5 * bw, -0.5 * t);
  j.base.half_size_m = Eigen::Vector3d(0.5 * L, 0.5 * bw, 0.5 * t);
  j.base.id = base_id;
  j.web.T_world_box = j.T_world_joint * Eigen::Translation3d(0.5 * L, 0.5 * t, 0.5 * ww);
  j.web.half_size_m = Eigen::Vector3d(0.5 * L, 0.5 * t, 0.5 * ww);
  j.web.id = web_id;
  j.start_world = start_world;
  j.end_world = j.T_world_joint * Eigen::Vector3d(L, 0.0, 0.0);
  return j;
}

}  // namespace hwr::testing
