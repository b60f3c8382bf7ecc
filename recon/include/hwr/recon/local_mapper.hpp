#pragma once
// The mapping side of the robot (paper sec. II-B global map, II-D segmentation; issue #4 items 2, 4):
// keyframes, once the sliding-window bundle adjustment has settled them (`keyframe_lag` keyframes
// behind the newest), are back-projected (eq. 3) and merged into the active local map, a voxel map
// in the segment frame. The segment frame is the camera frame of the segment's first keyframe, at
// the pose the estimator had for it when the segment started.
//
// The active local map is closed when the keyframes fused into it have travelled
// `segment_max_travel_m` or it holds `segment_max_points` voxels, whichever comes first. The junction
// to the next segment is aligned by ORB + NDT between the last keyframe before the cut and the first
// after it (JunctionAligner), and the closed segment — its points, keyframes (poses, features,
// descriptors) and junction — is handed to a SegmentSink (the on-disk store writer, or a collector
// in tests and benches). The voxel map is then cleared and reused, so memory does not grow with the
// run: everything is sized in create().

#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/core/arena.hpp"
#include "hwr/core/status.hpp"
#include "hwr/estimation/keyframe_store.hpp"
#include "hwr/recon/junction.hpp"
#include "hwr/recon/keyframe_cloud.hpp"
#include "hwr/recon/keyframe_sensor_tags.hpp"
#include "hwr/recon/map_store.hpp"
#include "hwr/recon/fine_region_map.hpp"
#include "hwr/recon/voxel_map.hpp"

namespace hwr::recon {

// Receives closed segments. take() may move the record's contents out.
class SegmentSink {
 public:
  virtual ~SegmentSink() = default;
  virtual void take(SegmentRecord&& segment) = 0;
};

// Receives the active local map while it fills, for streaming to the ground station (mapio): voxels
// in creation order, each sent once, `stream_lag_keyframes` keyframes after it was made (by then
// the camera has moved on and the voxel's mean has settled), in batches of at least
// `stream_min_points`; the rest when the segment closes, with segment_complete set (n may be 0).
// Points are in the segment frame; ids are voxel slots, unique within a segment. Called on the
// mapping task: must not block; the arrays are valid only during the call.
class MapStreamSink {
 public:
  virtual ~MapStreamSink() = default;
  virtual void stream(uint32_t segment_id, const Eigen::Isometry3d& T_world_segment,
                      const CloudPoint* points_segment, const uint32_t* voxel_ids, int n,
                      bool segment_complete) = 0;
};

struct LocalMapperConfig {
  KeyframeCloudConfig cloud;                                 // map points (stride 2)
  VoxelMapConfig voxels{0.02, 1'000'000};                    // the active local map
  double segment_max_travel_m = 18.0;                        // paper: 15-20 m
  int segment_max_points = 500'000;                          // paper: 5x10^5
  int keyframe_lag = 2;                                      // fuse keyframes this many behind the newest
  KeyframeCloudConfig junction_cloud{0.2f, 8.0f, 2, 0.05f};  // the NDT clouds of a junction
  JunctionConfig junction;
  int max_keyframes_per_segment = 4096;
  int stream_lag_keyframes = 5;  // MapStreamSink: a voxel is streamed this many keyframes after its creation
  int stream_min_points = 20'000;  // ... in batches of at least this many (except at a segment close)
  // The fine cloud inside welding regions (fine_region_map.hpp); add_weld_region() feeds it.
  FineRegionConfig fine;
};

struct LocalMapperCounters {
  uint64_t keyframes_fused = 0;
  uint64_t keyframes_without_images = 0;  // their images were gone: pose kept, no points
  uint64_t segments_closed = 0;
  uint64_t points_closed = 0;       // voxels in closed segments
  uint64_t fine_points_closed = 0;  // fine voxels (welding regions) in closed segments
  uint64_t junctions_orb = 0;       // seeded by ORB
  uint64_t junctions_ndt = 0;       // refined by NDT
  uint64_t cloud_errors = 0;
};

class LocalMapper {
 public:
  // Errors: invalid config or intrinsics (kInvalidArgument).
  static core::Expected<LocalMapper> create(const LocalMapperConfig& config, const hal::PinholeIntrinsics& K,
                                            int max_features);

  // Fuses every keyframe of `keyframes` at least keyframe_lag behind the newest that is not fused
  // yet (all of them when `flush`), closing segments into `sink` on the way.
  void update(const estimation::KeyframeStore& keyframes, SegmentSink* sink, bool flush = false);
  // Flushes and closes the active segment (end of run).
  void finish(const estimation::KeyframeStore& keyframes, SegmentSink* sink);

  const LocalMapperCounters& counters() const { return counters_; }
  const VoxelMap& active_map() const { return map_; }
  uint32_t active_segment_id() const { return segment_.segment_id; }
  // The active segment's frame in the world (its first keyframe's camera pose when it started).
  const Eigen::Isometry3d& active_T_world_segment() const { return segment_.T_world_segment; }
  double active_travel_m() const { return segment_.travelled_m; }
  const LocalMapperConfig& config() const { return config_; }
  // Optional; not owned. Set before the first update().
  void set_stream_sink(MapStreamSink* sink) { stream_sink_ = sink; }
  // Magnetometer samples and GNSS fixes as they arrive, in time order: each stored keyframe is tagged
  // with the ones nearest its time (keyframe_sensor_tags.hpp), for relocalization against this run.
  void add_mag(const hal::MagSample& sample) { sensor_tags_.add_mag(sample); }
  void add_gnss(const hal::GnssFix& fix) { sensor_tags_.add_gnss(fix); }
  // A welding region detected on a keyframe whose estimated pose is T_world_cam (a detector, the
  // operator, or the simulator's truth): from the next fused keyframe on, the pixels inside it also
  // go into the fine cloud. Returns the region's id, or -1 when refused (fine_region_map.hpp).
  // Never allocates.
  int64_t add_weld_region(const WeldRegion& detection, const Eigen::Isometry3d& T_world_cam) {
    return fine_.add(detection, T_world_cam);
  }
  const FineRegionMap& fine_map() const { return fine_; }
  // The operator's corrections of the welding regions (fine_region_map.hpp add_fixed, set_fixed_box,
  // remove).
  FineRegionMap& fine_map_for_operator() { return fine_; }

  LocalMapper(LocalMapper&&) noexcept;
  LocalMapper& operator=(LocalMapper&&) noexcept;
  ~LocalMapper();

 private:
  LocalMapper(const LocalMapperConfig& config, const hal::PinholeIntrinsics& K, VoxelMap map,
              JunctionAligner junction, FineRegionMap fine);
  void fuse(const estimation::KeyframeStore& keyframes, int id, SegmentSink* sink);
  void close_segment(SegmentSink* sink);
  // Streams created voxels [streamed_voxels_, upto) of the active map.
  void stream_voxels(int upto, bool segment_complete);

  LocalMapperConfig config_;
  hal::PinholeIntrinsics K_;
  VoxelMap map_;
  JunctionAligner junction_;
  FineRegionMap fine_;
  std::unique_ptr<core::Arena> cloud_arena_;
  std::unique_ptr<core::Arena> junction_arena_[2];  // the previous keyframe's junction cloud, the current one
  int junction_prev_ = 0;                           // which arena holds the previous keyframe's cloud
  KeyframeCloud junction_cloud_prev_;
  SegmentRecord segment_;  // the active segment (points filled when it closes)
  bool segment_open_ = false;
  int next_id_ = 0;   // next keyframe id to fuse
  int last_id_ = -1;  // last fused keyframe
  Eigen::Isometry3d T_world_last_ = Eigen::Isometry3d::Identity();
  uint32_t next_segment_id_ = 0;
  LocalMapperCounters counters_;
  MapStreamSink* stream_sink_ = nullptr;
  KeyframeSensorTags sensor_tags_;
  int tagged_upto_ = -1;                // newest keyframe id whose sensor tags are remembered
  int streamed_voxels_ = 0;             // of the active map, in creation order
  std::vector<int> map_size_after_kf_;  // ring: map size after each of the last lag+1 keyframes
  int keyframes_in_segment_ = 0;
  std::vector<CloudPoint> stream_points_;  // batch buffers, sized in the constructor
  std::vector<uint32_t> stream_ids_;
};

}  // namespace hwr::recon
