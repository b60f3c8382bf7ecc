#include "hwr/recon/keyframe_cloud.hpp"

#include <cmath>
#include <string>

namespace hwr::recon {
namespace {

int samples_along(int n, int stride) { return (n + stride - 1) / stride; }

bool valid_depth(float z) { return std::isfinite(z) && z > 0.0f; }

}  // namespace

size_t keyframe_cloud_capacity_bytes(int width, int height, const KeyframeCloudConfig& config) {
  const int stride = config.stride_px > 0 ? config.stride_px : 1;
  return static_cast<size_t>(samples_along(width, stride)) *
             static_cast<size_t>(samples_along(height, stride)) * sizeof(CloudPoint) +
         alignof(CloudPoint);
}

core::Expected<KeyframeCloud> build_keyframe_cloud(const cv::Mat& bgr, const cv::Mat& depth_m,
                                                   const hal::PinholeIntrinsics& K,
                                                   const Eigen::Isometry3d& T_world_cam,
                                                   const KeyframeCloudConfig& config, core::Arena* arena) {
  if (arena == nullptr) return core::InvalidArgument("keyframe cloud: arena is null");
  if (!K.valid()) return core::InvalidArgument("keyframe cloud: invalid intrinsics");
  if (config.stride_px < 1 || !(config.min_depth_m >= 0) || !(config.max_depth_m > config.min_depth_m) ||
      !(config.max_depth_step > 0)) {
    return core::InvalidArgument(
        "keyframe cloud: config needs stride_px >= 1, 0 <= min_depth_m < max_depth_m, max_depth_step > 0");
  }
  if (depth_m.type() != CV_32FC1 || depth_m.cols != K.width || depth_m.rows != K.height) {
    return core::InvalidArgument("keyframe cloud: depth must be CV_32FC1 of " + std::to_string(K.width) +
                                 "x" + std::to_string(K.height) + ", got type " +
                                 std::to_string(depth_m.type()) + " " + std::to_string(depth_m.cols) + "x" +
                                 std::to_string(depth_m.rows));
  }
  if (!bgr.empty() && (bgr.type() != CV_8UC3 || bgr.size() != depth_m.size())) {
    return core::InvalidArgument("keyframe cloud: colour image must be CV_8UC3 of the depth image's size");
  }
  const int w = depth_m.cols, h = depth_m.rows, stride = config.stride_px;
  const size_t worst =
      static_cast<size_t>(samples_along(w, stride)) * static_cast<size_t>(samples_along(h, stride));
  const size_t room = arena->capacity_bytes() - arena->used_bytes();
  if (room < worst * sizeof(CloudPoint) + alignof(CloudPoint)) {
    return core::OutOfRange("keyframe cloud: the arena has " + std::to_string(room) + " bytes left, a " +
                            std::to_string(w) + "x" + std::to_string(h) + " keyframe at stride " +
                            std::to_string(stride) + " needs up to " +
                            std::to_string(worst * sizeof(CloudPoint) + alignof(CloudPoint)));
  }
  CloudPoint* out = arena->allocate<CloudPoint>(worst);
  if (out == nullptr) return core::OutOfRange("keyframe cloud: arena allocation failed");

  KeyframeCloud cloud;
  KeyframeCloudStats& st = cloud.stats;
  const Eigen::Matrix3f R = T_world_cam.linear().cast<float>();
  const Eigen::Vector3f t = T_world_cam.translation().cast<float>();
  const float fx = static_cast<float>(K.fx), fy = static_cast<float>(K.fy);
  const float cx = static_cast<float>(K.cx), cy = static_cast<float>(K.cy);
  int n = 0;
  for (int v = 0; v < h; v += stride) {
    const float* row = depth_m.ptr<float>(v);
    const float* up = depth_m.ptr<float>(v > 0 ? v - 1 : v);
    const float* down = depth_m.ptr<float>(v + 1 < h ? v + 1 : v);
    const uint8_t* colour = bgr.empty() ? nullptr : bgr.ptr<uint8_t>(v);
    for (int u = 0; u < w; u += stride) {
      ++st.sampled;
      const float z = row[u];
      if (!valid_depth(z)) {
        ++st.invalid;
        continue;
      }
      if (z < config.min_depth_m || z > config.max_depth_m) {
        ++st.out_of_range;
        continue;
      }
      // Edge: any 4-neighbour invalid or further than max_depth_step * z away in depth.
      const float limit = config.max_depth_step * z;
      const float nb[4] = {row[u > 0 ? u - 1 : u], row[u + 1 < w ? u + 1 : u], up[u], down[u]};
      bool edge = false;
      if (config.edge_keeps_nearer) {
        for (float q : nb) edge = edge || (valid_depth(q) && z - q > limit);
      } else {
        for (float q : nb) edge = edge || !valid_depth(q) || std::fabs(q - z) > limit;
      }
      if (edge) {
        ++st.edges;
        continue;
      }
      // Eq. (3), then the keyframe pose.
      const Eigen::Vector3f p_cam((static_cast<float>(u) - cx) * z / fx,
                                  (static_cast<float>(v) - cy) * z / fy, z);
      const Eigen::Vector3f p_world = R * p_cam + t;
      CloudPoint& p = out[n++];
      p.x_m = p_world.x();
      p.y_m = p_world.y();
      p.z_m = p_world.z();
      if (colour != nullptr) {
        p.b = colour[3 * u];
        p.g = colour[3 * u + 1];
        p.r = colour[3 * u + 2];
      } else {
        p.r = p.g = p.b = 128;
      }
      p.flags = 0;
    }
  }
  st.kept = n;
  cloud.points = out;
  cloud.size = n;
  return cloud;
}

}  // namespace hwr::recon
