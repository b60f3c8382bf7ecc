#include "hwr/detect/geometric_seam_detector.hpp"

#include <cmath>
#include <string>

#include "hwr/detect/seam_metrics.hpp"

namespace hwr::detect {

namespace {

// Whether detection b repeats a's seam: nearly parallel lines, b's midpoint near a's line, and
// overlapping extents along it.
bool same_seam(const Detection& a, const Detection& b, double max_angle_rad, double max_distance_m) {
  const Eigen::Vector3d da = a.seam_cam[1] - a.seam_cam[0];
  const Eigen::Vector3d db = b.seam_cam[1] - b.seam_cam[0];
  const double la = da.norm(), lb = db.norm();
  if (la < 1e-9 || lb < 1e-9) return false;
  const Eigen::Vector3d ua = da / la;
  if (std::acos(std::min(1.0, std::fabs(ua.dot(db / lb)))) > max_angle_rad) return false;
  const Eigen::Vector3d mid_b = 0.5 * (b.seam_cam[0] + b.seam_cam[1]);
  if (distance_to_line_m(mid_b, a.seam_cam[0], ua) > max_distance_m) return false;
  const double t0 = ua.dot(b.seam_cam[0] - a.seam_cam[0]), t1 = ua.dot(b.seam_cam[1] - a.seam_cam[0]);
  return std::max(t0, t1) > 0 && std::min(t0, t1) < la;
}

}  // namespace

GeometricSeamDetector::GeometricSeamDetector(const GeometricSeamConfig& config,
                                             const hal::PinholeIntrinsics& K, OrganizedCloud cloud,
                                             PlaneSegmenter planes, FilletFinder fillets,
                                             RaisedRegionFinder raised, ButtFinder butts)
    : config_(config),
      K_(K),
      cloud_(std::move(cloud)),
      planes_(std::move(planes)),
      fillets_(std::move(fillets)),
      raised_(std::move(raised)),
      butts_(std::move(butts)),
      candidates_(config.max_detections * 4) {}

core::Expected<std::unique_ptr<GeometricSeamDetector>> GeometricSeamDetector::create(
    const GeometricSeamConfig& config, const hal::PinholeIntrinsics& K) {
  if (config.max_detections < 1)
    return core::InvalidArgument("geometric seam detector: max_detections must be >= 1");
  if (!(config.duplicate_angle_rad >= 0) || !(config.duplicate_distance_m >= 0)) {
    return core::InvalidArgument(
        "geometric seam detector: duplicate_angle_rad and duplicate_distance_m must be >= 0");
  }
  auto cloud = OrganizedCloud::create(config.cloud, K);
  if (!cloud.ok()) return cloud.status();
  auto planes = PlaneSegmenter::create(config.planes, config.noise, cloud->width(), cloud->height());
  if (!planes.ok()) return planes.status();
  auto fillets = FilletFinder::create(config.fillet, config.noise, cloud->width() * cloud->height());
  if (!fillets.ok()) return fillets.status();
  auto raised = RaisedRegionFinder::create(config.raised, config.noise, cloud->width(), cloud->height());
  if (!raised.ok()) return raised.status();
  auto butts = ButtFinder::create(config.butt, config.noise, K);
  if (!butts.ok()) return butts.status();
  return std::unique_ptr<GeometricSeamDetector>(new GeometricSeamDetector(
      config, K, std::move(cloud.value()), std::move(planes.value()), std::move(fillets.value()),
      std::move(raised.value()), std::move(butts.value())));
}

core::Status GeometricSeamDetector::detect(const KeyframeView& view, DetectionList* out) {
  if (out == nullptr) return core::InvalidArgument("geometric seam detector: no output list");
  out->clear();
  stats_ = GeometricSeamStats{};
  if (view.depth_m == nullptr || view.depth_m->empty()) {
    return core::InvalidArgument("geometric seam detector: keyframe " + std::to_string(view.keyframe_id) +
                                 " has no depth image");
  }
  if (view.K.width != K_.width || view.K.height != K_.height || view.K.fx != K_.fx || view.K.fy != K_.fy ||
      view.K.cx != K_.cx || view.K.cy != K_.cy) {
    return core::InvalidArgument("geometric seam detector: the keyframe's intrinsics are not the detector's");
  }
  // An empty colour image is none (a depth-only source).
  const cv::Mat* bgr = view.bgr != nullptr && !view.bgr->empty() ? view.bgr : nullptr;
  if (bgr != nullptr && (bgr->type() != CV_8UC3 || bgr->cols != K_.width || bgr->rows != K_.height)) {
    return core::InvalidArgument("geometric seam detector: keyframe " + std::to_string(view.keyframe_id) +
                                 "'s colour image must be CV_8UC3 of " + std::to_string(K_.width) + "x" +
                                 std::to_string(K_.height) + " (or none)");
  }
  core::Status s = cloud_.build(*view.depth_m);
  if (!s.ok()) return s;
  stats_.valid_points = cloud_.valid_count();
  s = planes_.segment(cloud_);
  if (!s.ok()) return s;
  stats_.planes = planes_.plane_count();
  const Eigen::Vector3d up_cam = view.T_world_cam.linear().transpose() * Eigen::Vector3d::UnitZ();
  candidates_.clear();
  stats_.candidates = fillets_.find(cloud_, planes_, up_cam, &candidates_);
  stats_.raised_regions = raised_.find(cloud_, planes_, up_cam);
  stats_.candidates += butts_.find(cloud_, raised_, bgr, *view.depth_m, &candidates_);
  candidates_.keep_most_confident(candidates_.capacity());
  // Places a candidate unless it repeats one placed already; false once the list is full.
  auto place = [&](const Detection& candidate) {
    for (int j = 0; j < out->size(); ++j) {
      if (same_seam((*out)[j], candidate, config_.duplicate_angle_rad, config_.duplicate_distance_m)) {
        ++stats_.duplicates;
        return true;
      }
    }
    Detection d = candidate;
    d.keyframe_id = view.keyframe_id;
    d.t_ns = view.t_ns;
    place_in_world(view.T_world_cam, &d);
    return out->push(d) && out->size() < config_.max_detections;
  };
  // Confident detections first, then supporting ones: a supporting line never displaces a confident
  // one (as a duplicate or past max_detections), whatever their confidences.
  for (const bool supporting : {false, true}) {
    for (int i = 0; i < candidates_.size(); ++i) {
      if (candidates_[i].support_only == supporting && !place(candidates_[i])) return core::Status();
    }
  }
  return core::Status();
}

}  // namespace hwr::detect
