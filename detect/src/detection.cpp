#include "hwr/detect/detection.hpp"

#include <algorithm>

namespace hwr::detect {

const char* detection_source_name(DetectionSource source) {
  switch (source) {
    case DetectionSource::kModel:
      return "model";
    case DetectionSource::kGeometry:
      return "geometry";
    case DetectionSource::kOperator:
      return "operator";
  }
  return "unknown";
}

const char* seam_kind_name(SeamKind kind) {
  switch (kind) {
    case SeamKind::kFillet:
      return "fillet";
    case SeamKind::kButt:
      return "butt";
  }
  return "unknown";
}

void place_in_world(const Eigen::Isometry3d& T_world_cam, Detection* d) {
  for (int e = 0; e < 2; ++e) d->seam_world[e] = T_world_cam * d->seam_cam[e];
  d->T_world_box = T_world_cam * d->T_cam_box;
}

cv::Rect2f box_image_rect(const hal::PinholeIntrinsics& K, const Eigen::Isometry3d& T_cam_box,
                          const Eigen::Vector3d& half_size_m) {
  double u_min = 1e30, v_min = 1e30, u_max = -1e30, v_max = -1e30;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d corner_box((i & 4 ? 1 : -1) * half_size_m.x(), (i & 2 ? 1 : -1) * half_size_m.y(),
                                     (i & 1 ? 1 : -1) * half_size_m.z());
    const Eigen::Vector3d p = T_cam_box * corner_box;
    if (p.z() <= 1e-3) continue;
    const double u = K.fx * p.x() / p.z() + K.cx, v = K.fy * p.y() / p.z() + K.cy;
    u_min = std::min(u_min, u);
    v_min = std::min(v_min, v);
    u_max = std::max(u_max, u);
    v_max = std::max(v_max, v);
  }
  if (!(u_max >= u_min)) return cv::Rect2f();
  u_min = std::clamp(u_min, 0.0, K.width - 1.0);
  u_max = std::clamp(u_max, 0.0, K.width - 1.0);
  v_min = std::clamp(v_min, 0.0, K.height - 1.0);
  v_max = std::clamp(v_max, 0.0, K.height - 1.0);
  return cv::Rect2f(static_cast<float>(u_min), static_cast<float>(v_min), static_cast<float>(u_max - u_min),
                    static_cast<float>(v_max - v_min));
}

DetectionList::DetectionList(int capacity) : capacity_(std::max(capacity, 0)) {
  items_.reserve(static_cast<size_t>(capacity_));
}

bool DetectionList::push(const Detection& d) {
  if (size() >= capacity_) return false;
  items_.push_back(d);
  return true;
}

void DetectionList::keep_most_confident(int keep) {
  // Insertion sort by confidence, descending (stable; at most a few dozen items, no allocation).
  for (size_t i = 1; i < items_.size(); ++i) {
    for (size_t j = i; j > 0 && items_[j].confidence > items_[j - 1].confidence; --j) {
      std::swap(items_[j], items_[j - 1]);
    }
  }
  if (keep >= 0 && size() > keep) items_.resize(static_cast<size_t>(keep));
}

}  // namespace hwr::detect
