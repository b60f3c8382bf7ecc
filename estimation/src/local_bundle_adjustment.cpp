#include "hwr/estimation/local_bundle_adjustment.hpp"

#include <algorithm>
#include <memory>

namespace hwr::estimation {
namespace {

BaCapacity window_capacity(const LocalBaConfig& c) {
  BaCapacity cap;
  cap.max_cameras = c.window_keyframes + c.fixed_keyframes;
  cap.max_points = c.max_points;
  cap.max_observations = c.max_observations;
  return cap;
}

}  // namespace

LocalBundleAdjustment::LocalBundleAdjustment(const LocalBaConfig& config, int map_point_capacity)
    : config_(config), solver_(window_capacity(config)) {
  problem_.model = BaCameraModel::kPinhole;
  const BaCapacity cap = window_capacity(config);
  problem_.cameras.reserve(static_cast<size_t>(cap.max_cameras));
  problem_.points.reserve(static_cast<size_t>(cap.max_points));
  problem_.observations.reserve(static_cast<size_t>(cap.max_observations));
  camera_keyframe_.reserve(static_cast<size_t>(cap.max_cameras));
  ba_to_point_.reserve(static_cast<size_t>(cap.max_points));
  observation_ref_.reserve(static_cast<size_t>(cap.max_observations));
  point_to_ba_.assign(static_cast<size_t>(map_point_capacity), -1);
}

bool LocalBundleAdjustment::add_point(const MapPointStore& points, MapPointHandle h, int* ba_index) {
  const MapPoint* p = points.get(h);
  if (p == nullptr) return false;
  int32_t& slot = point_to_ba_[static_cast<size_t>(h.index)];
  if (slot < 0) {
    slot = static_cast<int32_t>(problem_.points.size());
    BaPoint bp;
    bp.p_world = p->p_world_m;
    problem_.points.push_back(bp);
    ba_to_point_.push_back(h.index);
  }
  *ba_index = slot;
  return true;
}

core::Expected<LocalBaReport> LocalBundleAdjustment::run(KeyframeStore* keyframes, MapPointStore* points,
                                                         const hal::PinholeIntrinsics& K, bool full) {
  // Solve, drop the observations that are still outliers, and solve again without them: Huber
  // bounds an outlier's pull but does not remove it (ORB-SLAM's local BA does the same two passes).
  auto first = run_once(keyframes, points, K, full);
  if (!first.ok() || first->observations_removed == 0) return first;
  auto second = run_once(keyframes, points, K, full);
  if (!second.ok()) return first;  // the first pass's result stands (it was written back)
  second->summary.initial_cost = first->summary.initial_cost;
  second->summary.iterations += first->summary.iterations;
  second->observations_removed += first->observations_removed;
  second->points_removed += first->points_removed;
  return second;
}

const BaProblem& LocalBundleAdjustment::build_problem(const KeyframeStore& keyframes,
                                                      const MapPointStore& points,
                                                      const hal::PinholeIntrinsics& K, bool full,
                                                      LocalBaReport* report_out) {
  LocalBaReport report;
  for (int32_t slot : ba_to_point_) point_to_ba_[static_cast<size_t>(slot)] = -1;
  problem_.cameras.clear();
  problem_.points.clear();
  problem_.observations.clear();
  camera_keyframe_.clear();
  ba_to_point_.clear();
  observation_ref_.clear();
  if (keyframes.size() < 2) {
    *report_out = report;
    return problem_;
  }

  const int newest = keyframes.newest_id();
  int first =
      full ? keyframes.oldest_id() : std::max(keyframes.oldest_id(), newest - config_.window_keyframes + 1);
  // Keyframes whose points the tracker retired (a long run; VisualTracker) observe nothing: the
  // full BA starts at the oldest keyframe that still observes a point, and that one fixes the gauge.
  auto observes_a_point = [&](int id) {
    const Keyframe* kf = keyframes.get(id);
    for (int f = 0; f < kf->features.size(); ++f)
      if (points.get(kf->points[static_cast<size_t>(f)]) != nullptr) return true;
    return false;
  };
  while (full && first < newest && !observes_a_point(first)) ++first;
  if (first >= newest) {
    *report_out = report;
    return problem_;
  }
  const size_t max_points = full ? point_to_ba_.size() : static_cast<size_t>(config_.max_points);
  BaIntrinsics intrinsics{};
  intrinsics.fx = K.fx;
  intrinsics.fy = K.fy;
  intrinsics.cx = K.cx;
  intrinsics.cy = K.cy;
  auto add_camera = [&](int id, bool fixed) {
    BaCamera c;
    c.T_cam_world = keyframes.get(id)->T_world_cam.inverse();
    c.K = intrinsics;
    c.fixed = fixed;
    problem_.cameras.push_back(c);
    camera_keyframe_.push_back(id);
  };
  // Window keyframes; the oldest fixes the gauge. Points from the newest keyframe first, so a cap
  // on the point count drops the oldest keyframes' points.
  for (int id = first; id <= newest; ++id) add_camera(id, id == first);
  for (int id = newest; id >= first; --id) {
    const Keyframe* kf = keyframes.get(id);
    for (int f = 0; f < kf->features.size() && problem_.points.size() < max_points; ++f) {
      int ba = -1;
      add_point(points, kf->points[static_cast<size_t>(f)], &ba);
    }
  }
  // Older keyframes that see the window's points, held fixed.
  if (!full) {
    int fixed = 0;
    for (int id = first - 1; id >= keyframes.oldest_id() && fixed < config_.fixed_keyframes; --id) {
      const Keyframe* kf = keyframes.get(id);
      bool sees = false;
      for (int f = 0; f < kf->features.size() && !sees; ++f) {
        const MapPointHandle h = kf->points[static_cast<size_t>(f)];
        sees = points.get(h) != nullptr && point_to_ba_[static_cast<size_t>(h.index)] >= 0;
      }
      if (!sees) continue;
      add_camera(id, true);
      ++fixed;
    }
  }
  // Observations.
  const size_t max_obs = full ? SIZE_MAX : static_cast<size_t>(config_.max_observations);
  for (size_t c = 0; c < problem_.cameras.size(); ++c) {
    const Keyframe* kf = keyframes.get(camera_keyframe_[c]);
    for (int f = 0; f < kf->features.size() && problem_.observations.size() < max_obs; ++f) {
      const MapPointHandle h = kf->points[static_cast<size_t>(f)];
      if (points.get(h) == nullptr) continue;
      const int32_t ba = point_to_ba_[static_cast<size_t>(h.index)];
      if (ba < 0) continue;
      const Feature& feat = kf->features.feature(f);
      BaObservation o;
      o.camera = static_cast<int>(c);
      o.point = ba;
      o.uv_px = Eigen::Vector2d(feat.u_px, feat.v_px);
      o.depth_m = feat.depth_m > 0 ? feat.depth_m : 0.0;
      o.sigma_px = kf->features.scale(feat.octave);
      problem_.observations.push_back(o);
      observation_ref_.push_back({kf->id, f});
    }
  }
  report.cameras = static_cast<int>(problem_.cameras.size());
  report.points = static_cast<int>(problem_.points.size());
  report.observations = static_cast<int>(problem_.observations.size());
  for (const BaCamera& c : problem_.cameras) report.fixed_cameras += c.fixed ? 1 : 0;
  *report_out = report;
  return problem_;
}

core::Expected<LocalBaReport> LocalBundleAdjustment::run_once(KeyframeStore* keyframes, MapPointStore* points,
                                                              const hal::PinholeIntrinsics& K, bool full) {
  LocalBaReport report;
  build_problem(*keyframes, *points, K, full, &report);
  if (report.cameras - report.fixed_cameras < 1 || report.observations == 0) return report;

  core::Expected<BaSummary> summary = core::Internal("not solved");
  if (full) {
    BaCapacity cap;
    cap.max_cameras = report.cameras;
    cap.max_points = report.points;
    cap.max_observations = report.observations;
    SparseBundleAdjuster full_solver(cap);
    summary = full_solver.solve(&problem_, config_.options);
  } else {
    summary = solver_.solve(&problem_, config_.options);
  }
  if (!summary.ok()) return summary.status();
  report.summary = summary.value();

  // Write back.
  for (size_t c = 0; c < problem_.cameras.size(); ++c) {
    if (problem_.cameras[c].fixed) continue;
    keyframes->get(camera_keyframe_[c])->T_world_cam = problem_.cameras[c].T_cam_world.inverse();
  }
  for (size_t i = 0; i < problem_.points.size(); ++i) {
    points->at(ba_to_point_[i]).p_world_m = problem_.points[i].p_world;
  }
  // Observations that are still outliers leave the map.
  for (size_t i = 0; i < problem_.observations.size(); ++i) {
    const BaObservation& o = problem_.observations[i];
    const BaCamera& cam = problem_.cameras[static_cast<size_t>(o.camera)];
    const Eigen::Vector3d p_cam = cam.T_cam_world * problem_.points[static_cast<size_t>(o.point)].p_world;
    bool bad = !(p_cam.z() > 0.01) || p_cam.z() > config_.max_depth_m;
    if (!bad) {
      const Eigen::Vector2d uv(K.fx * p_cam.x() / p_cam.z() + K.cx, K.fy * p_cam.y() / p_cam.z() + K.cy);
      bad = (uv - o.uv_px).squaredNorm() > config_.outlier_chi2 * o.sigma_px * o.sigma_px;
    }
    if (!bad) continue;
    Keyframe* kf = keyframes->get(observation_ref_[i].keyframe_id);
    MapPointHandle& h = kf->points[static_cast<size_t>(observation_ref_[i].feature)];
    MapPoint* p = points->get(h);
    h = MapPointHandle{};
    ++report.observations_removed;
    if (p != nullptr && --p->observations <= 0) {
      points->remove(points->handle(ba_to_point_[static_cast<size_t>(o.point)]));
      ++report.points_removed;
    }
  }
  return report;
}

}  // namespace hwr::estimation
