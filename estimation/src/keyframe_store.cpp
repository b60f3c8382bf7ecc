#include "hwr/estimation/keyframe_store.hpp"

#include <algorithm>

namespace hwr::estimation {

KeyframeStore::KeyframeStore(const KeyframeStoreConfig& config) : config_(config) {
  config_.capacity = std::max(config_.capacity, 2);
  config_.image_slots = std::max(config_.image_slots, 1);
  config_.max_total = std::max(config_.max_total, config_.capacity);
  ring_.reserve(static_cast<size_t>(config_.capacity));
  for (int i = 0; i < config_.capacity; ++i) {
    ring_.emplace_back(config_.feature_capacity, config_.width, config_.height, config_.levels,
                       config_.scale_factor);
  }
  archive_.resize(static_cast<size_t>(config_.max_total));
  images_.resize(static_cast<size_t>(config_.image_slots));
  for (ImageSlot& s : images_) {
    s.bgr.create(config_.height, config_.width, CV_8UC3);
    s.depth_m.create(config_.height, config_.width, CV_32FC1);
  }
}

Keyframe* KeyframeStore::insert(int64_t t_ns, const Eigen::Isometry3d& T_world_cam) {
  if (next_id_ >= config_.max_total) return nullptr;
  const int id = next_id_;
  Keyframe& kf = ring_[static_cast<size_t>(id % config_.capacity)];
  if (kf.id >= 0) sync_archive(kf.id);  // the evicted keyframe's final pose, while still in the ring
  ++next_id_;
  if (size_ < config_.capacity) ++size_;
  kf.id = id;
  kf.t_ns = t_ns;
  kf.T_world_cam = T_world_cam;
  kf.features.clear();
  std::fill(kf.points.begin(), kf.points.end(), MapPointHandle{});
  sync_archive(id);
  return &kf;
}

Keyframe* KeyframeStore::get(int id) {
  if (id < oldest_id() || id > newest_id()) return nullptr;
  return &ring_[static_cast<size_t>(id % config_.capacity)];
}

const Keyframe* KeyframeStore::get(int id) const { return const_cast<KeyframeStore*>(this)->get(id); }

Eigen::Isometry3d KeyframeStore::pose(int id) const {
  if (const Keyframe* kf = get(id)) return kf->T_world_cam;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (id < 0 || id >= next_id_) return T;
  const ArchivedPose& a = archive_[static_cast<size_t>(id)];
  T.linear() = a.q_world_cam.toRotationMatrix();
  T.translation() = a.p_world_cam_m;
  return T;
}

void KeyframeStore::sync_archive(int id) {
  const Keyframe* kf = get(id);
  if (kf == nullptr) return;
  ArchivedPose& a = archive_[static_cast<size_t>(id)];
  a.q_world_cam = Eigen::Quaterniond(kf->T_world_cam.linear()).normalized();
  a.p_world_cam_m = kf->T_world_cam.translation();
}

void KeyframeStore::store_images(int id, const cv::Mat& bgr, const cv::Mat& depth_m) {
  ImageSlot& s = images_[static_cast<size_t>(id % config_.image_slots)];
  s.id = (bgr.empty() || depth_m.empty()) ? -1 : id;  // a slot holds both images or none
  // copyTo reuses the preallocated buffers when the size and type match (no allocation).
  if (!bgr.empty()) bgr.copyTo(s.bgr);
  if (!depth_m.empty()) depth_m.copyTo(s.depth_m);
}

const cv::Mat* KeyframeStore::depth_m(int id) const {
  const ImageSlot& s = images_[static_cast<size_t>(id % config_.image_slots)];
  return s.id == id ? &s.depth_m : nullptr;
}

const cv::Mat* KeyframeStore::bgr(int id) const {
  const ImageSlot& s = images_[static_cast<size_t>(id % config_.image_slots)];
  return s.id == id ? &s.bgr : nullptr;
}

}  // namespace hwr::estimation
