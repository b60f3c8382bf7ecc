#pragma once
// The visual front end (paper items 3, 5, 6; issue #3 item 2): ORB features with depth on every
// frame, tracked against the local map by projection from a predicted pose (the IMU's when there
// is one, else constant velocity), pose from RANSAC then a motion-only refinement, recovery by
// wide descriptor matching (FLANN LSH) against recent keyframes when tracking is lost, and
// keyframe creation with new map points from depth (eq. 3) or two-view triangulation (eq. 4).
//
// Everything is allocated in the constructor; after warm-up track() does no heap allocation
// except inside OpenCV's ORB and in the recovery/triangulation paths (FLANN), which the
// allocation test reports separately.

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "hwr/estimation/frame_features.hpp"
#include "hwr/estimation/keyframe_store.hpp"
#include "hwr/estimation/lsh_matcher.hpp"
#include "hwr/estimation/map_point_store.hpp"
#include "hwr/estimation/motion_only_refiner.hpp"
#include "hwr/estimation/orb_extractor.hpp"
#include "hwr/estimation/pose_ransac.hpp"
#include "hwr/estimation/projection_matcher.hpp"
#include "hwr/estimation/triangulation.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/hal/rgbd_frame.hpp"

namespace hwr::estimation {

struct TrackerConfig {
  OrbConfig orb;
  KeyframeStoreConfig keyframes;  // feature_capacity/width/height are taken from orb and the camera
  // The map point pool is the tracker's working set, not the map (recon/ keeps the keyframe
  // clouds): when fewer than two keyframes' worth of slots are free, the points of the oldest
  // keyframes outside the local map and the recovery set are retired (their keyframes keep pose,
  // features and descriptors), so a run of any length keeps tracking in a bounded pool.
  int map_point_capacity = 300'000;
  int local_map_keyframes = 12;   // the newest keyframes whose points form the local map
  int max_local_points = 12'000;  // projected per frame
  ProjectionMatchConfig match;
  float wide_radius_factor = 3.0f;  // second projection pass when the first finds too few
  float refine_radius_px = 4.0f;    // rematch pass around the refined pose ...
  int rematch_refine_rounds = 2;    // ... and its refinement's outlier-rejection rounds
  PoseRansacConfig ransac;
  RefineConfig refine;
  int min_matches = 20;
  int min_inliers = 15;
  // Refining straight from the prediction is kept when at least this share of the matches are
  // inliers; otherwise RANSAC finds the pose first.
  double min_inlier_ratio_without_ransac = 0.5;
  // A new keyframe is triangulated against the previous one (eq. 4) when at least this many of its
  // features got no point from depth.
  int min_features_to_triangulate = 100;
  // A keyframe when the camera moved more than this since the last keyframe (paper item 3) ...
  double keyframe_translation_m = 0.2;
  double keyframe_rotation_rad = 0.05;
  // ... or when tracking thins out: fewer inliers than this fraction of the last keyframe's.
  double keyframe_inlier_fraction = 0.5;
  int min_depth_features_to_start = 50;
  LshConfig lsh;
  int recovery_keyframes = 3;  // newest keyframes tried by wide matching when tracking is lost
  TriangulationConfig triangulation;
  int cull_after_keyframes = 4;  // a point never matched again within this many keyframes is dropped
};

enum class TrackState { kWaiting, kTracking, kRecovered, kLost };
const char* track_state_name(TrackState s);

struct TrackTimings {  // nanoseconds of the last track() call, per stage
  int64_t extract_ns = 0;
  int64_t match_ns = 0;
  int64_t pose_ns = 0;
  int64_t keyframe_ns = 0;
};

struct TrackResult {
  TrackState state = TrackState::kWaiting;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  // Covariance of δξ = (ρ, φ) with T_cam_world ← exp(δξ)·T_cam_world (m², rad²); valid when tracked.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Identity();
  int features = 0;
  int matches = 0;
  int inliers = 0;
  bool keyframe = false;
  int reference_keyframe = -1;  // the keyframe the pose is expressed against (trajectory output)
  TrackTimings timings;
};

struct TrackerCounters {
  uint64_t frames = 0;
  uint64_t tracked = 0;
  uint64_t recovered = 0;
  uint64_t lost = 0;
  uint64_t keyframes = 0;
  uint64_t points_from_depth = 0;
  uint64_t points_triangulated = 0;
  uint64_t points_culled = 0;
  uint64_t points_retired = 0;        // removed with the oldest keyframes when the pool ran low
  uint64_t keyframes_retired = 0;     // keyframes whose point observations were retired
  uint64_t bad_frames = 0;            // wrong image type/size
  uint64_t keyframes_refused = 0;     // keyframe ids exhausted (KeyframeStoreConfig::max_total)
  uint64_t point_pool_exhausted = 0;  // new points refused: the map point pool was full
  uint64_t ransac_runs = 0;           // frames whose pose needed RANSAC (prediction not good enough)
};

class VisualTracker {
 public:
  VisualTracker(const TrackerConfig& config, const hal::PinholeIntrinsics& K);

  // Tracks one frame. T_world_cam_predicted: the IMU's prediction, or nullptr (constant velocity).
  // T_world_cam_start: pose of the first keyframe (the world frame's relation to the camera; the
  // IMU's static initialisation gives it), used until the map exists.
  TrackResult track(const hal::RgbdFrame& frame, const Eigen::Isometry3d* T_world_cam_predicted,
                    const Eigen::Isometry3d& T_world_cam_start = Eigen::Isometry3d::Identity());

  // The mapping side of a new keyframe (the mapping task runs it before the local bundle
  // adjustment, off the per-frame path): two-view triangulation of its features without depth
  // against the previous keyframe (eq. 4), and culling of recent points never seen again.
  void map_new_keyframes();

  KeyframeStore& keyframes() { return keyframes_; }
  const KeyframeStore& keyframes() const { return keyframes_; }
  MapPointStore& points() { return points_; }
  const MapPointStore& points() const { return points_; }
  const hal::PinholeIntrinsics& intrinsics() const { return K_; }
  const TrackerConfig& config() const { return config_; }
  TrackerCounters counters() const {
    TrackerCounters c = counters_;
    c.point_pool_exhausted = points_.exhausted();
    return c;
  }
  // Instrumentation for tests and benches: called right before (begin = true) and after the ORB
  // extraction, so a caller can attribute heap allocations to it (OpenCV's ORB allocates inside).
  using StageHook = void (*)(void* user, bool begin);
  void set_extract_hook(StageHook hook, void* user) {
    extract_hook_ = hook;
    extract_hook_user_ = user;
  }
  // Bundle adjustment moved the newest keyframe: the last tracked pose moves with it, so the next
  // prediction starts from the refined map.
  void on_keyframe_moved(const Eigen::Isometry3d& T_world_kf_before,
                         const Eigen::Isometry3d& T_world_kf_after);

 private:
  int collect_local_map();
  int build_correspondences(int n_matches);
  bool estimate_pose(int n_matches, const Eigen::Isometry3d& T_cam_world_guess, bool have_guess,
                     RefineResult* out);
  bool recover(RefineResult* out, int* n_correspondences);
  void insert_keyframe(const hal::RgbdFrame& frame, const Eigen::Isometry3d& T_world_cam);
  void triangulate_with_previous(Keyframe* kf);
  void evict_oldest_if_full();
  void release_keyframe_points(Keyframe* kf);
  void retire_points_if_low();
  void cull_points(int newest_keyframe_id);

  TrackerConfig config_;
  hal::PinholeIntrinsics K_;
  GridOrbExtractor extractor_;
  FrameFeatures current_;
  KeyframeStore keyframes_;
  MapPointStore points_;
  ProjectionMatcher projection_;
  LshMatcher lsh_;
  PoseRansac ransac_;
  MotionOnlyRefiner refiner_;
  cv::Mat gray_;

  // Per-frame scratch, sized at construction.
  std::vector<MapPointRef> local_refs_;
  std::vector<int32_t> local_index_;  // local_refs_[i] is map point slot local_index_[i]
  std::vector<FeatureMatch> matches_;
  std::vector<Correspondence> correspondences_;
  std::vector<int32_t> correspondence_point_;    // map point slot of each correspondence
  std::vector<int32_t> correspondence_feature_;  // feature index of each correspondence
  std::vector<uint8_t> inlier_mask_;
  int n_correspondences_ = 0;  // correspondences of the final pose of the current frame
  struct RecentPoint {
    MapPointHandle handle;
    int32_t keyframe_id = -1;
  };
  std::vector<RecentPoint> recent_points_;  // created within the last cull_after_keyframes keyframes
  uint32_t stamp_ = 0;
  StageHook extract_hook_ = nullptr;
  void* extract_hook_user_ = nullptr;

  bool initialized_ = false;
  int last_mapped_keyframe_ = -1;
  int oldest_with_points_ = 0;  // keyframes older than this id have had their points retired
  Eigen::Isometry3d T_world_cam_last_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_prev_last_ = Eigen::Isometry3d::Identity();  // motion model: last relative motion
  int64_t t_last_ns_ = 0;
  int64_t dt_last_ns_ = 0;
  int last_keyframe_inliers_ = 0;
  TrackerCounters counters_;
};

}  // namespace hwr::estimation
