#pragma once
// Welding regions of the map (issue #4 item 2: "a finer resolution around welding regions"; the
// detections of issue #7 feed it). A region is an oriented box around a weld joint, found on one
// keyframe by a detector (or drawn by the operator). Inside the active regions the local mapper keeps
// a second, fine cloud (fine_region_map.hpp) beside the coarse local map: the welding area is where
// the map has to be accurate to millimetres (paper Table III, AE), and only there can it afford to.
//
// The detection is kept in the frame it was made in — the keyframe's camera, T_cam_region — so the
// region moves with that keyframe's pose: the mapper places it in the world with the keyframe's
// estimated pose, a segment stores it in the segment frame, and a map moved as a whole (segments
// re-placed by their junctions, relocalization into a prior frame) moves its regions with it.

#include <array>
#include <cstddef>
#include <cmath>
#include <cstdint>
#include <string>

#include <Eigen/Geometry>

#include "hwr/detect/detection.hpp"

namespace hwr::recon {

// Who found the region. kSimTruth: the simulator's ground-truth joints seen from the keyframe's true
// pose (a perfect detector, for measuring the map until the detectors of issue #7 exist).
enum class WeldRegionSource : uint8_t { kModel = 0, kGeometry = 1, kOperator = 2, kSimTruth = 3 };

// "model", "geometry", "operator", "sim-truth"; "unknown" for any other value.
const char* weld_region_source_name(WeldRegionSource source);

inline constexpr size_t kWeldRegionLabelBytes = 32;

struct WeldRegion {
  uint32_t id = 0;  // unique within the run (the local mapper assigns it)
  WeldRegionSource source = WeldRegionSource::kGeometry;
  float confidence = 1.0f;                          // [0, 1]
  std::array<char, kWeldRegionLabelBytes> label{};  // NUL-terminated, e.g. the sim joint's name
  int32_t keyframe_id = -1;                         // the keyframe it was detected on
  int64_t t_ns = 0;                                 // that keyframe's time
  // Box centre and axes in the detection keyframe's camera frame, and its half sizes along them.
  Eigen::Isometry3d T_cam_region = Eigen::Isometry3d::Identity();
  Eigen::Vector3d half_size_m = Eigen::Vector3d::Zero();
};

// Whether a point in a region's box frame lies inside (or on) its box of half sizes half_size_m.
inline bool inside_region_box(const Eigen::Vector3d& p_region, const Eigen::Vector3d& half_size_m) {
  return std::fabs(p_region.x()) <= half_size_m.x() && std::fabs(p_region.y()) <= half_size_m.y() &&
         std::fabs(p_region.z()) <= half_size_m.z();
}

// Copies at most kWeldRegionLabelBytes - 1 bytes of `text` (the rest is cut) and NUL-terminates.
void set_weld_region_label(WeldRegion* region, const std::string& text);
std::string weld_region_label(const WeldRegion& region);

// A detector's detection (detect/detection.hpp) as a welding region: its box in the keyframe's camera
// frame, labelled with the seam's kind ("fillet", "butt"). The source numbers are shared.
WeldRegion weld_region_from_detection(const detect::Detection& detection);

// A region as a closed segment keeps it.
struct StoredWeldRegion {
  WeldRegion region;
  // The box in the segment frame: T_segment_world * T_world_cam(keyframe) * T_cam_region, with the
  // keyframe's pose as the mapper had it.
  Eigen::Isometry3d T_segment_region = Eigen::Isometry3d::Identity();
  int64_t fine_points = 0;  // fine voxels of this segment inside the box
  // Where the region was seen from: the mean camera centre (segment frame) over the points this
  // segment's keyframes put in the box. Depth noise lies along the viewing rays; recon::fit_plate
  // slides face points back along rays from here (PlateFitConfig::viewpoint_world). Zero when the
  // segment put no point in it.
  Eigen::Vector3d viewpoint_segment = Eigen::Vector3d::Zero();
};

}  // namespace hwr::recon
