#pragma once
// The prior map (issue #6 item 1; paper sec. II-E): an earlier run's map store (map_store.hpp),
// opened lazily for relocalization. open() reads every segment's keyframes (poses, ORB features
// with depth, descriptors, GNSS / magnetometer metadata) but none of the clouds; the clouds are
// read on demand by points_near() and evicted least-recently-used beyond a point budget, so only
// the local maps near the current hypothesis are in memory.
//
// Frames (ARCHITECTURE.md "Frames and names"): `prior` is the earlier run's world frame (its
// store's "world"); every pose and point this class hands out is in it. A segment's cloud is stored
// in its segment frame and moved to the prior frame with the store's T_world_segment when loaded.
//
// Keyframes are estimation::FrameFeatures, so the estimation matchers and PoseRansac take them as
// they are: each Feature's p_cam_m is rebuilt from (u, v, depth) with the store's intrinsics
// (paper eq. 3, p_cam = ((u - cx) z / fx, (v - cy) z / fy, z), as GridOrbExtractor computes it).
//
// Memory held for the map's lifetime: every keyframe feature, ~88 bytes each (a 56-byte
// estimation::Feature with its eq. 3 point + its 32-byte ORB descriptor), and, once a Relocalizer
// has indexed the map (Relocalizer::prepare), its LSH vote index over those descriptors, ~100 bytes
// per feature more: ~190 bytes per prior feature in all (the sim lab's 80 s prior: 158k features,
// ~30 MB). PriorMapConfig::max_prior_features bounds it: open() refuses a larger prior (kOutOfRange).
// Clouds: 16 bytes per point, at most max_loaded_points of them, thinned when read to one point per
// cloud_voxel_m voxel (PriorMapConfig), plus the one segment being read: its stored cloud, the
// thinning's 16 bytes per stored point of scratch and its output at once.
// points_near() writes into the caller's vector, which keeps its capacity between calls. Loading a
// cloud allocates (it reads a file); this class runs off the control loop.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/estimation/frame_features.hpp"
#include "hwr/recon/keyframe_cloud.hpp"
#include "hwr/recon/map_store.hpp"

namespace hwr::recon {

struct PriorMapConfig {
  // Clouds kept in memory, points in all loaded segments together (16 bytes each), counted after
  // thinning.
  int64_t max_loaded_points = 4'000'000;
  // A cloud is thinned when read: one point per voxel of this size (the centroid of the stored
  // points in it, the colour of the first), in the segment frame. The relocalizer's NDT ends at
  // 0.25 m voxels; the stored map's voxels are 2 cm. Measured (hwr-bench reloc's preload): 0.05 m
  // keeps 18 % of the outdoor prior's points (19.8M -> 3.59M), 16 % of the lab's (8.1M -> 1.33M).
  // 0 keeps every stored point.
  double cloud_voxel_m = 0.05;
  // Keyframe features of the whole prior, held for the map's lifetime (~190 bytes each with the
  // relocalizer's vote index, see "Memory" above): 2M ~ 380 MB. open() fails beyond it.
  int64_t max_prior_features = 2'000'000;
  // Before a segment's cloud was ever read its extent is unknown: it is taken as the box of its
  // keyframe positions grown by this reach (the keyframe clouds' max_depth_m, keyframe_cloud.hpp).
  // Once read, the cloud's own box replaces it (kept after eviction).
  double cloud_reach_m = 8.0;
  // ORB pyramid of the stored features (FrameFeatures::scale_per_octave); the store does not hold it.
  int orb_levels = 8;
  float orb_scale_factor = 1.2f;
};

// One keyframe of the prior run.
struct PriorKeyframe {
  explicit PriorKeyframe(estimation::FrameFeatures f) : features(std::move(f)) {}
  uint32_t segment_id = 0;
  int32_t id = -1;  // the prior run's keyframe id
  int64_t t_ns = 0;
  Eigen::Isometry3d T_prior_cam = Eigen::Isometry3d::Identity();
  estimation::FrameFeatures features;  // p_cam_m rebuilt (eq. 3) where depth_m > 0; grid built
  bool gnss_valid = false;
  double lat_deg = 0, lon_deg = 0, alt_m = 0;
  bool mag_valid = false;
  Eigen::Vector3d mag_imu_uT = Eigen::Vector3d::Zero();
};

// The index entry of one segment.
struct PriorSegment {
  uint32_t segment_id = 0;
  Eigen::Isometry3d T_prior_segment = Eigen::Isometry3d::Identity();
  int first_keyframe = 0, keyframe_count = 0;  // range in PriorMap::keyframes()
  Eigen::AlignedBox3d keyframe_box_prior;      // keyframe camera positions
  bool cloud_box_known = false;                // the cloud was read at least once
  Eigen::AlignedBox3d cloud_box_prior;         // its points (valid when cloud_box_known)
  int64_t points = 0;       // cloud size: segment.yaml's until read, then thinned (cloud_voxel_m)
  bool loaded = false;      // cloud in memory now
  bool unreadable = false;  // its cloud failed to read once: skipped by points_near from then on
};

struct PriorMapCounters {
  uint64_t cloud_loads = 0;      // segment clouds read from disk
  int64_t points_read = 0;       // their stored points, before thinning
  uint64_t cloud_evictions = 0;  // dropped to stay within max_loaded_points
  uint64_t queries = 0;          // points_near calls
  int64_t loaded_points = 0;     // in memory now
  int loaded_segments = 0;       // in memory now
  int unreadable_segments = 0;   // clouds that failed to read (logged once each, then skipped)
};

// What one points_near() call used.
struct PointsNearStats {
  int segments_near = 0;         // segments whose (known or estimated) box is within the radius
  int segments_used = 0;         // ... whose cloud was searched
  int segments_over_budget = 0;  // near, but their cloud did not fit the budget: not searched
  int segments_unreadable = 0;   // near, but their cloud cannot be read (corrupt, missing): not searched
  int64_t points = 0;            // written to the output
};

// What preload_clouds() did.
struct PreloadStats {
  int segments_loaded = 0;       // read by this call
  int segments_in_memory = 0;    // afterwards
  int segments_over_budget = 0;  // left on disk: the next would pass max_loaded_points
  int segments_unreadable = 0;
  int64_t points_in_memory = 0;  // afterwards, thinned
  bool cancelled = false;        // keep_going said stop before every cloud that fits was read
};

class PriorMap {
 public:
  // Opens the store at `dir` (MapStore::open_existing) and reads every segment's keyframes.
  // Errors carry the store's status and path: kNotFound (no store at dir), kCorruptData /
  // kParseError (a damaged store.yaml, segment.yaml or keyframes.bin), kInvalidArgument (a store
  // without segments, descriptors that are not 32-byte ORB, invalid intrinsics or config),
  // kOutOfRange (more keyframe features than config.max_prior_features).
  static core::Expected<PriorMap> open(const std::string& dir, const PriorMapConfig& config = {});

  const StoreMetadata& metadata() const { return store_.metadata(); }
  const std::string& dir() const { return store_.dir(); }
  const PriorMapConfig& config() const { return config_; }
  const std::vector<PriorKeyframe>& keyframes() const { return keyframes_; }
  const std::vector<PriorSegment>& segments() const { return segments_; }
  const PriorMapCounters& counters() const { return counters_; }
  int max_keyframe_features() const { return max_features_; }
  // Unique per open() in this process (kept by moves): tells a cache which prior map it indexed.
  uint64_t instance_id() const { return instance_id_; }

  // Writes into `out` (cleared first) every prior point (thinned, cloud_voxel_m), in the prior frame, within
  // radius_m of p_prior_m, from the segments whose box comes within radius_m of it; loads those clouds
  // (nearest segment first) and evicts least-recently-used others beyond max_loaded_points. A near segment
  // that does not fit the budget even with every cloud this query does not need evicted is skipped
  // and counted in the stats (the answer is then partial, never wrong); a cloud never read is read
  // (and thinned) before that is judged. A near segment whose cloud fails to read
  // (corrupt or missing cloud.bin) is marked unreadable, logged once (a warning naming the file and
  // the store's error), counted (counters().unreadable_segments) and skipped by this and every later
  // query (stats.segments_unreadable): the answer is then partial, from the other segments. Errors:
  // radius not positive and finite or a non-finite position (kInvalidArgument).
  core::Expected<PointsNearStats> points_near(const Eigen::Vector3d& p_prior_m, double radius_m,
                                              std::vector<CloudPoint>* out);

  // Reads (and thins) every cloud not in memory yet, in segment order, until one does not fit within
  // max_loaded_points (that one and the rest stay on disk); evicts nothing. For a robot that has a moment
  // before its first relocalization attempt (RelocalizationWorker runs it at start, beside
  // Relocalizer::prepare): without GNSS the first attempt's candidates come from anywhere in the map, and
  // reading their clouds then is most of its time. A cloud that fails to read is marked unreadable (as in
  // points_near). Returns how many segments are in memory afterwards. keep_going (optional) is asked
  // before each read: false stops the preload there (a robot shutting down does not wait for it).
  PreloadStats preload_clouds(const std::function<bool()>& keep_going = {});
  // Every readable segment's cloud is in memory (none left on disk): the whole prior fits the point
  // budget, and a structure over all of it (Relocalizer::prepare_targets) needs no query to read more.
  bool all_clouds_in_memory() const;
  // Segment i's cloud in the prior frame (thinned), empty when it is not in memory.
  const std::vector<CloudPoint>& cloud(size_t segment_index) const { return clouds_prior_[segment_index]; }
  // Changes whenever a cloud is read, evicted or found unreadable: a structure built over the clouds in
  // memory is stale once it differs from the value it was built at.
  uint64_t cloud_generation() const { return cloud_generation_; }

  PriorMap(PriorMap&&) noexcept = default;
  PriorMap& operator=(PriorMap&&) noexcept = default;

 private:
  PriorMap(MapStore store, const PriorMapConfig& config) : store_(std::move(store)), config_(config) {}
  // Distance from p to the segment's box (known cloud box, else the keyframe box grown by the reach).
  double box_distance_m(const PriorSegment& s, const Eigen::Vector3d& p) const;
  core::Status load_cloud(size_t index);
  void evict(size_t index);
  // Evicts least-recently-used loaded clouds that the current query does not need (needed_) until
  // extra_points more fit within max_loaded_points, or none is left to evict.
  void make_room(int64_t extra_points);
  // A cloud that failed to read: skipped by every later query, logged once.
  void mark_unreadable(size_t index, const core::Status& why);
  // Drops a cloud just read that does not fit (not counted as a cache eviction).
  void drop_unbudgeted(size_t index);

  MapStore store_;
  PriorMapConfig config_;
  std::vector<PriorKeyframe> keyframes_;
  std::vector<PriorSegment> segments_;
  std::vector<std::vector<CloudPoint>> clouds_prior_;  // per segment, prior frame; empty when not loaded
  std::vector<uint64_t> last_used_;                    // per segment: query stamp of its last use
  uint64_t stamp_ = 0;
  uint64_t instance_id_ = 0;
  uint64_t cloud_generation_ = 0;
  int max_features_ = 0;
  PriorMapCounters counters_;
  std::vector<std::pair<double, size_t>> near_;  // scratch: (distance, segment index)
  std::vector<uint8_t> needed_;                  // scratch: per segment, needed by this query
};

}  // namespace hwr::recon
