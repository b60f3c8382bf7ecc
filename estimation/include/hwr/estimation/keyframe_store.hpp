#pragma once
// Keyframes (paper item 3): a preallocated ring of the most recent keyframes with their pose,
// features, descriptors and the map point each feature observes, plus a smaller ring of colour
// and depth images for the reconstruction (recon/ back-projects them, eq. 3). When the ring is
// full the oldest keyframe is evicted: its pose stays available by id in a compact archive (for
// the trajectory), its observations leave the bundle adjustment.

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "hwr/estimation/frame_features.hpp"
#include "hwr/estimation/map_point_store.hpp"

namespace hwr::estimation {

struct Keyframe {
  Keyframe(int feature_capacity, int width, int height, int levels, float scale_factor)
      : features(feature_capacity, width, height, levels, scale_factor),
        points(static_cast<size_t>(feature_capacity)) {}
  int32_t id = -1;
  int64_t t_ns = 0;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  FrameFeatures features;
  std::vector<MapPointHandle> points;  // per feature; invalid: observes no map point
};

struct KeyframeStoreConfig {
  int capacity = 1024;      // keyframes in the ring (bundle adjustment, recovery, revisits)
  int image_slots = 8;      // keyframes whose images are kept for reconstruction
  int max_total = 100'000;  // keyframe ids whose pose is archived (the whole run)
  int feature_capacity = 1000;
  int width = 640, height = 480;
  int levels = 8;  // pyramid of the features (their per-octave scale table)
  float scale_factor = 1.2f;
};

class KeyframeStore {
 public:
  explicit KeyframeStore(const KeyframeStoreConfig& config);

  // The next keyframe slot (evicting the oldest when full), with a new id. Fails (nullptr) only
  // when max_total ids have been used. The caller fills it.
  Keyframe* insert(int64_t t_ns, const Eigen::Isometry3d& T_world_cam);
  int size() const { return size_; }
  bool ids_exhausted() const { return next_id_ >= config_.max_total; }
  bool empty() const { return size_ == 0; }
  int newest_id() const { return next_id_ - 1; }
  int oldest_id() const { return next_id_ - size_; }
  // Keyframe by id while it is in the ring, else nullptr.
  Keyframe* get(int id);
  const Keyframe* get(int id) const;
  Keyframe& newest() { return *get(newest_id()); }
  // Pose of any keyframe of the run (ring or archive).
  Eigen::Isometry3d pose(int id) const;
  // Keeps the archive in step after the ring's poses changed (bundle adjustment).
  void sync_archive(int id);

  // Images of the keyframe (copied at insert); empty Mats once its slot was reused.
  void store_images(int id, const cv::Mat& bgr, const cv::Mat& depth_m);
  const cv::Mat* depth_m(int id) const;
  const cv::Mat* bgr(int id) const;

  const KeyframeStoreConfig& config() const { return config_; }

 private:
  struct ArchivedPose {
    Eigen::Quaterniond q_world_cam;
    Eigen::Vector3d p_world_cam_m;
  };
  struct ImageSlot {
    int id = -1;
    cv::Mat bgr, depth_m;
  };
  KeyframeStoreConfig config_;
  std::vector<Keyframe> ring_;
  std::vector<ArchivedPose> archive_;
  std::vector<ImageSlot> images_;
  int size_ = 0;
  int next_id_ = 0;
};

}  // namespace hwr::estimation
