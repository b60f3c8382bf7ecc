#pragma once
// Keyframe clouds (paper eq. 3; issue #4 item 1): every `stride_px`-th pixel of a keyframe's depth
// image back-projected through the pinhole intrinsics, p_cam = ((u - cx) z / fx, (v - cy) z / fy, z),
// moved to the world frame with the keyframe pose, p_world = T_world_cam p_cam, and coloured from
// the keyframe image. Rejected and counted: invalid depth (0, NaN, inf), depth outside
// [min_depth_m, max_depth_m], and depth-discontinuity edges (a 4-neighbour whose depth differs by
// more than max_depth_step of the pixel's depth: the flying pixels between a foreground edge and
// the background; KeyframeCloudConfig::edge_keeps_nearer keeps the foreground's own edge pixels). Points are
// written into a caller's core::Arena, so the mapping task's memory is fixed at start-up; an arena without
// room is an error, nothing is written past it.

#include <cstdint>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "hwr/core/arena.hpp"
#include "hwr/core/status.hpp"
#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::recon {

// One coloured point in the world frame (metres); 16 bytes.
struct CloudPoint {
  float x_m = 0, y_m = 0, z_m = 0;
  uint8_t r = 0, g = 0, b = 0;
  uint8_t flags = 0;  // reserved (0)
};

struct KeyframeCloudConfig {
  float min_depth_m = 0.2f;
  float max_depth_m = 8.0f;      // the ZED 2i's depth noise grows with z²; beyond this it is not map quality
  int stride_px = 2;             // every stride-th pixel in u and v
  float max_depth_step = 0.05f;  // relative depth jump to a 4-neighbour that marks an edge
  // false: both sides of a depth edge are dropped, and so is a pixel next to an invalid one (the map:
  // a flying pixel is never kept). true: only the far side is dropped (a pixel with a valid
  // 4-neighbour nearer by more than the step), so a foreground silhouette keeps its outermost
  // pixel: dropping it moves every silhouette edge inwards by a pixel (~2.5 mm at 1.5 m), which the
  // welding regions' fine cloud cannot afford. A flying pixel between the two surfaces still has
  // the nearer surface beside it and is dropped.
  bool edge_keeps_nearer = false;
};

struct KeyframeCloudStats {
  int sampled = 0;       // pixels visited
  int invalid = 0;       // depth 0 / NaN / inf
  int out_of_range = 0;  // outside [min_depth_m, max_depth_m]
  int edges = 0;         // depth discontinuity
  int kept = 0;
};

struct KeyframeCloud {
  const CloudPoint* points = nullptr;  // in the arena; valid until its reset()
  int size = 0;
  KeyframeCloudStats stats;
};

// bgr: CV_8UC3 (or empty: points stay grey 128); depth_m: CV_32FC1 of K's size. Errors
// (kInvalidArgument): wrong types or sizes, invalid intrinsics or config; (kOutOfRange): the arena
// cannot hold the worst case (every sampled pixel) — checked before anything is written.
core::Expected<KeyframeCloud> build_keyframe_cloud(const cv::Mat& bgr, const cv::Mat& depth_m,
                                                   const hal::PinholeIntrinsics& K,
                                                   const Eigen::Isometry3d& T_world_cam,
                                                   const KeyframeCloudConfig& config, core::Arena* arena);

// Bytes an arena needs for one keyframe cloud of this image size (the worst case).
size_t keyframe_cloud_capacity_bytes(int width, int height, const KeyframeCloudConfig& config);

}  // namespace hwr::recon
