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
