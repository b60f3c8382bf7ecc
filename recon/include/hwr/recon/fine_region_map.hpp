#pragma once
// The fine cloud of the welding regions (issue #4 item 2: "a finer resolution around welding
// regions once detections exist"). Beside the coarse local map (2 cm voxels), the local mapper keeps
// every keyframe pixel (stride 1) that falls inside an active welding region and lies within
// `cloud.max_depth_m`, merged into a second voxel map of `voxels.voxel_m` (2 mm) in the segment
// frame. The fine voxels are smaller than the depth noise, so each is close to one raw point; each
// keeps the number of points merged into it, and fitting the fine cloud with those counts as
// weights (recon::fit_plate) reproduces a fit of the raw points while the memory is bounded by the
// regions' surface, not by how long the robot looks at them.
//
// Regions come from detections (weld_region.hpp): add() places a detection in the world with its
// keyframe's estimated pose. A detection whose box centre lies inside an active region's box, or
// whose box contains an active region's centre, is that region seen again and is merged into it;
// the region is re-anchored on it when it was seen from nearer (5 cm or more): a region keeps its
// closest view, where a detector sees it best. When the anchor keyframe is fused, settle() places
// the region again with that keyframe's settled pose (the sliding-window bundle adjustment moves
// a new keyframe by millimetres). Regions stay active across segment cuts; each closed segment
// stores the regions that got fine points in it, in its own frame.
//
// Memory: the voxel map, the active-region table, the pixel arena and the per-region counters are
// sized in create(); add() and insert_keyframe() never allocate. take_segment() fills the caller's
// vectors (the segment close, like the coarse map's points).

#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "hwr/core/arena.hpp"
#include "hwr/core/status.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/recon/keyframe_cloud.hpp"
#include "hwr/recon/voxel_map.hpp"
#include "hwr/recon/weld_region.hpp"

namespace hwr::recon {

struct FineRegionConfig {
  bool enabled = true;
  // Pixels taken: every pixel (stride 1) up to 3.5 m: the floor joints of the sim lab are seen from
  // 2.2-3 m. At a depth edge only the far side is dropped: a plate's silhouette keeps its outermost
  // pixels (KeyframeCloudConfig::edge_keeps_nearer).
  KeyframeCloudConfig cloud{0.2f, 3.5f, 1, 0.05f, true};
  VoxelMapConfig voxels{0.002, 2'000'000};
  int max_regions = 64;  // active at once; a new region when the table is full is refused and counted
  // A region's box grows, in its own axes, to hold every detection merged into it whose box x axis
  // (a seam's direction) is within cover_max_angle_rad of the region's, at most max_cover_m along
  // each axis. For detectors whose boxes hold only what one view saw (the geometric seam detector: a
  // seam cut by the image border); the simulator's truth boxes are whole.
  bool grow_to_cover = false;
  double max_cover_m = 2.0;  // the sim's longest joint is 1.5 m
  double cover_max_angle_rad = 0.175;
};

struct FineRegionCounters {
  uint64_t regions_added = 0;
  uint64_t detections_merged = 0;   // a detection of a region already active
  uint64_t anchors_moved = 0;       // ... seen from nearer: the region re-anchored on it
  uint64_t boxes_grown = 0;         // ... and its box grown to hold the detection (grow_to_cover)
  uint64_t regions_refused = 0;     // the table was full
  uint64_t regions_removed = 0;     // remove(): the operator rejected them
  uint64_t boxes_fixed = 0;         // set_fixed_box() and add_fixed(): the operator's boxes
  uint64_t detections_invalid = 0;  // non-positive or non-finite half sizes, a non-rigid pose
  uint64_t keyframes_in_view = 0;   // keyframes that saw at least one active region
  uint64_t points_inserted = 0;     // handed to the fine map (merged, new, or refused by its voxel map)
  uint64_t cloud_errors = 0;
};

class FineRegionMap {
 public:
  // Errors (kInvalidArgument): invalid intrinsics, cloud config (keyframe_cloud.hpp), voxel config
  // (voxel_map.hpp), max_regions < 1.
  static core::Expected<FineRegionMap> create(const FineRegionConfig& config,
                                              const hal::PinholeIntrinsics& K);

  // A detection on a keyframe whose estimated pose is T_world_cam. Returns the id of the region it
  // became or merged into, or -1 when refused (invalid detection, table full; counted). The region's
  // id is assigned here (detection.id is ignored).
  int64_t add(const WeldRegion& detection, const Eigen::Isometry3d& T_world_cam);
  // The operator's corrections (issue #7 item 4; detect/detection_ledger.hpp). A fixed region keeps
  // the box it was given in the world: detections merged into it no longer re-anchor or grow it, and
  // settle() leaves it where it is.
  //  - add_fixed: a new region (no merging) with box T_world_region and region.half_size_m; region's
  //    other fields are kept, its id assigned. -1 when refused (invalid box, table full; counted).
  //  - set_fixed_box: region `id` gets this box and becomes fixed. false when no region has that id or
  //    the box is invalid.
  //  - remove: region `id` leaves the active table (its fine points already merged stay in the
  //    segment's cloud). false when no region has that id.
  // None of them allocates.
  int64_t add_fixed(const WeldRegion& region, const Eigen::Isometry3d& T_world_region);
  bool set_fixed_box(uint32_t id, const Eigen::Isometry3d& T_world_region,
                     const Eigen::Vector3d& half_size_m);
  bool remove(uint32_t id);
  // Index of region `id` in the active table, or -1.
  int find(uint32_t id) const;
  bool fixed(int i) const { return active_[static_cast<size_t>(i)].fixed; }

  // The keyframe's settled pose: regions anchored on it are placed again with it.
  void settle(int32_t keyframe_id, const Eigen::Isometry3d& T_world_cam);

  // Merges the keyframe's pixels inside the active regions into the fine map, in the segment frame
  // (T_world_segment). bgr may be empty (points grey). Only the image rectangle that the regions'
  // boxes project to is visited.
  void insert_keyframe(const cv::Mat& bgr, const cv::Mat& depth_m, const Eigen::Isometry3d& T_world_cam,
                       const Eigen::Isometry3d& T_world_segment);

  // The segment's fine cloud and the regions that got points in it (boxes in that segment's frame),
  // then clears the fine map for the next segment (the regions stay active). Vectors are replaced.
  void take_segment(const Eigen::Isometry3d& T_world_segment, std::vector<CloudPoint>* points_segment,
                    std::vector<uint32_t>* counts, std::vector<StoredWeldRegion>* regions);

  int active_regions() const { return static_cast<int>(active_.size()); }
  // Region i of the active table (i < active_regions()) and its box in the world frame.
  const WeldRegion& region(int i) const { return active_[static_cast<size_t>(i)].region; }
  const Eigen::Isometry3d& T_world_region(int i) const {
    return active_[static_cast<size_t>(i)].T_world_region;
  }
  const VoxelMap& fine_map() const { return map_; }
  const FineRegionCounters& counters() const { return counters_; }
  const FineRegionConfig& config() const { return config_; }

  FineRegionMap(FineRegionMap&&) noexcept;
  FineRegionMap& operator=(FineRegionMap&&) noexcept;
  ~FineRegionMap();

 private:
  struct Active {
    WeldRegion region;
    Eigen::Isometry3d T_world_region = Eigen::Isometry3d::Identity();
    Eigen::Isometry3d T_region_world = Eigen::Isometry3d::Identity();
    bool fixed = false;          // the operator's box (add_fixed, set_fixed_box)
    int64_t segment_points = 0;  // fine points of the current segment inside it
    // Camera centres (segment frame) of the current segment's points inserted for this region,
    // summed with the number of points each keyframe inserted: the region's viewpoint.
    Eigen::Vector3d viewpoint_sum = Eigen::Vector3d::Zero();
    int64_t viewpoint_points = 0;
    int keyframe_points = 0;  // scratch of insert_keyframe
    // Scratch of insert_keyframe: the box in the current segment frame, and whether it is in view.
    Eigen::Isometry3d T_region_segment = Eigen::Isometry3d::Identity();
    bool in_view = false;
  };
  FineRegionMap(const FineRegionConfig& config, const hal::PinholeIntrinsics& K, VoxelMap map);
  // grow_to_cover: a's box grows to hold the other box (T_world_other, half sizes h_other).
  void cover(Active* a, const Eigen::Isometry3d& T_world_other, const Eigen::Vector3d& h_other);

  FineRegionConfig config_;
  hal::PinholeIntrinsics K_;
  VoxelMap map_;
  std::unique_ptr<core::Arena> arena_;  // one keyframe's worst-case cloud
  std::vector<Active> active_;          // capacity max_regions, reserved in the constructor
  uint32_t next_id_ = 0;
  FineRegionCounters counters_;
};

}  // namespace hwr::recon
