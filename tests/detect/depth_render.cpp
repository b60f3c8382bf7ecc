#include "depth_render.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace hwr::testing {
namespace {

// Slab test (Kay and Kajiya): the ray o + t d against the box |x_i| <= h_i in its own frame.
// Returns the entry parameter, or +inf for a miss or a ray starting inside; *axis: the entry face's
// axis.
double ray_box(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& h, int* axis) {
  double t_near = -std::numeric_limits<double>::infinity();
  double t_far = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d(i)) < 1e-15) {
      if (std::abs(o(i)) > h(i)) return std::numeric_limits<double>::infinity();
      continue;
    }
    double t0 = (-h(i) - o(i)) / d(i), t1 = (h(i) - o(i)) / d(i);
    if (t0 > t1) std::swap(t0, t1);
    if (t0 > t_near) {
      t_near = t0;
      *axis = i;
    }
    t_far = std::min(t_far, t1);
  }
  if (t_near > t_far || t_near <= 0.0) return std::numeric_limits<double>::infinity();
  return t_near;
}

uint32_t hash3(int64_t a, int64_t b, uint32_t seed) {
  uint64_t h = static_cast<uint64_t>(a) * 0x9E3779B97F4A7C15ull ^
               static_cast<uint64_t>(b) * 0xC2B2AE3D27D4EB4Full ^
               (static_cast<uint64_t>(seed) + 0x165667B19E3779F9ull);
  h ^= h >> 31;
  h *= 0xBF58476D1CE4E5B9ull;
  h ^= h >> 29;
  return static_cast<uint32_t>(h);
}

// A scratch on a face: a segment in face coordinates.
struct Scratch {
  Eigen::Vector2d a, b;
};

std::vector<Scratch> scratches(const RenderBox& box) {
  std::vector<Scratch> out;
  if (box.texture != Texture::kScratched) return out;
  std::mt19937 rng(box.texture_seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  // On the largest faces (the two largest half sizes), where the scratches matter.
  double ex = box.half_size_m.x(), ey = box.half_size_m.y();
  for (int i = 0; i < 40; ++i) {
    const Eigen::Vector2d a((2 * unit(rng) - 1) * ex, (2 * unit(rng) - 1) * ey);
    const double angle = 2 * M_PI * unit(rng), length = 0.02 + 0.06 * unit(rng);
    out.push_back({a, a + length * Eigen::Vector2d(std::cos(angle), std::sin(angle))});
  }
  return out;
}

double segment_distance(const Eigen::Vector2d& p, const Scratch& s) {
  const Eigen::Vector2d ab = s.b - s.a;
  const double t = std::clamp((p - s.a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (p - (s.a + t * ab)).norm();
}

// The texture's factor at face coordinates q (metres).
double texture_factor(Texture texture, uint32_t seed, const Eigen::Vector2d& q,
                      const std::vector<Scratch>& cuts) {
  if (texture == Texture::kPlain) return 1.0;
  const int64_t cx = static_cast<int64_t>(std::floor(q.x() / 0.006)),
                cy = static_cast<int64_t>(std::floor(q.y() / 0.006));
  const uint32_t h = hash3(cx, cy, seed);
  double f = h % 100 < 12 ? 0.35 : h % 100 < 18 ? 1.25 : 1.0 + 0.16 * ((h >> 8) % 1000 / 1000.0 - 0.5);
  if (texture == Texture::kScratched) {
    const int64_t row = static_cast<int64_t>(std::floor(q.y() / 0.0015));
    f *= 1.0 + 0.2 * (hash3(row, 7, seed) % 1000 / 1000.0 - 0.5);
    for (const Scratch& s : cuts) {
      if (segment_distance(q, s) < 0.00075) {
        f *= 0.3;
        break;
      }
    }
  }
  return f;
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
  if (options.colour) out.bgr = cv::Mat(K.height, K.width, CV_8UC3, cv::Scalar(200, 200, 200));
  const Eigen::Vector3d to_light = -scene.light_dir_world.normalized();
  std::vector<std::vector<Scratch>> cuts;
  for (const RenderBox& b : scene.boxes) cuts.push_back(scratches(b));
  std::mt19937 pixel_rng(options.pixel_noise_seed);
  std::normal_distribution<double> pixel_normal(0.0, 1.0);  // its own: a distribution caches a draw
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
      int best_id = -1, best_box = -1, best_axis = 2;
      if (scene.has_floor && std::abs(d_world.z()) > 1e-15) {
        const double t = (scene.floor_z_m - o_world.z()) / d_world.z();
        if (t > 0.0) {
          best = t;
          best_id = 0;
        }
      }
      for (size_t i = 0; i < scene.boxes.size(); ++i) {
        int axis = 2;
        const double t = ray_box(T_box_world[i] * o_world, T_box_world[i].linear() * d_world,
                                 scene.boxes[i].half_size_m, &axis);
        if (t < best) {
          best = t;
          best_id = scene.boxes[i].id;
          best_box = static_cast<int>(i);
          best_axis = axis;
        }
      }
      if (best_id < 0) continue;
      id[u] = best_id;
      if (options.colour) {
        // The face's normal (world) and texture coordinates; two-sided Lambert shading.
        const Eigen::Vector3d hit = o_world + best * d_world;
        Eigen::Vector3d n_world = Eigen::Vector3d::UnitZ();
        double albedo = scene.floor_albedo, factor = 1.0;
        if (best_box < 0) {
          factor = texture_factor(scene.floor_texture, 99, hit.head<2>(), {});
        } else {
          const RenderBox& b = scene.boxes[static_cast<size_t>(best_box)];
          n_world = b.T_world_box.linear().col(best_axis);
          const Eigen::Vector3d local = T_box_world[static_cast<size_t>(best_box)] * hit;
          const int i0 = best_axis == 0 ? 1 : 0, i1 = best_axis == 2 ? 1 : 2;
          albedo = b.albedo;
          factor =
              texture_factor(b.texture, b.texture_seed, Eigen::Vector2d(local(i0), local(i1)),
                             best_axis == 2 ? cuts[static_cast<size_t>(best_box)] : std::vector<Scratch>{});
        }
        if (n_world.dot(d_world) > 0.0) n_world = -n_world;
        const double shade = scene.ambient + (1.0 - scene.ambient) * std::max(0.0, n_world.dot(to_light));
        const double grey =
            255.0 * albedo * factor * shade + options.pixel_noise_sigma * pixel_normal(pixel_rng);
        const uint8_t g = static_cast<uint8_t>(std::clamp(std::lround(grey), 0L, 255L));
        out.bgr.at<cv::Vec3b>(v, u) = cv::Vec3b(g, g, g);
      }
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

ButtJoint make_butt(const Eigen::Vector3d& start_world, double yaw_rad, double length_m, double plate_width_m,
                    double thickness_m, double gap_m, int left_id, int right_id) {
  ButtJoint j;
  j.T_world_joint.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  j.T_world_joint.translation() = start_world;
  const double L = length_m, w = plate_width_m, t = thickness_m, y_c = 0.5 * gap_m + 0.5 * w;
  for (RenderBox* plate : {&j.left, &j.right}) {
    const double side = plate == &j.left ? 1.0 : -1.0;
    plate->T_world_box = j.T_world_joint * Eigen::Translation3d(0.5 * L, side * y_c, -0.5 * t);
    plate->half_size_m = Eigen::Vector3d(0.5 * L, 0.5 * w, 0.5 * t);
    plate->id = plate == &j.left ? left_id : right_id;
    plate->albedo = 0.7;
    plate->texture = Texture::kSpeckled;
    plate->texture_seed = static_cast<uint32_t>(plate->id);
  }
  j.start_world = start_world;
  j.end_world = j.T_world_joint * Eigen::Vector3d(L, 0.0, 0.0);
  return j;
}

}  // namespace hwr::testing
