#include "hwr/estimation/visual_tracker.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "hwr/core/log.hpp"
#include "hwr/core/se3.hpp"
#include "hwr/core/so3.hpp"

namespace hwr::estimation {
namespace {

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

KeyframeStoreConfig keyframe_config(const TrackerConfig& c, const hal::PinholeIntrinsics& K) {
  KeyframeStoreConfig k = c.keyframes;
  k.feature_capacity = c.orb.max_features;
  k.width = K.width;
  k.height = K.height;
  k.levels = c.orb.levels;
  k.scale_factor = c.orb.scale_factor;
  return k;
}

double rotation_angle_rad(const Eigen::Matrix3d& R) { return core::so3_log(R).norm(); }

}  // namespace

const char* track_state_name(TrackState s) {
  switch (s) {
    case TrackState::kWaiting:
      return "waiting";
    case TrackState::kTracking:
      return "tracking";
    case TrackState::kRecovered:
      return "recovered";
    case TrackState::kLost:
      return "lost";
  }
  return "?";
}

VisualTracker::VisualTracker(const TrackerConfig& config, const hal::PinholeIntrinsics& K)
    : config_(config),
      K_(K),
      extractor_(config.orb, K.width, K.height),
      current_(config.orb.max_features, K.width, K.height),
      keyframes_(keyframe_config(config, K)),
      points_(config.map_point_capacity),
      projection_(config.max_local_points, config.orb.max_features),
      lsh_(config.orb.max_features, config.lsh),
      ransac_(config.orb.max_features),
      refiner_(config.orb.max_features) {
  gray_.create(K.height, K.width, CV_8UC1);
  local_refs_.resize(static_cast<size_t>(config.max_local_points));
  local_index_.resize(static_cast<size_t>(config.max_local_points));
  const auto nf = static_cast<size_t>(config.orb.max_features);
  matches_.resize(nf);
  correspondences_.resize(nf);
  correspondence_point_.resize(nf);
  correspondence_feature_.resize(nf);
  inlier_mask_.resize(nf);
  recent_points_.reserve(nf * static_cast<size_t>(config.cull_after_keyframes + 2));
}

TrackResult VisualTracker::track(const hal::RgbdFrame& frame, const Eigen::Isometry3d* T_world_cam_predicted,
                                 const Eigen::Isometry3d& T_world_cam_start) {
  TrackResult result;
  ++counters_.frames;
  if (frame.bgr.type() != CV_8UC3 || frame.bgr.cols != K_.width || frame.bgr.rows != K_.height) {
    ++counters_.bad_frames;
    result.state = initialized_ ? TrackState::kLost : TrackState::kWaiting;
    result.T_world_cam = T_world_cam_predicted ? *T_world_cam_predicted : T_world_cam_last_;
    return result;
  }

  int64_t t0 = now_ns();
  cv::cvtColor(frame.bgr, gray_, cv::COLOR_BGR2GRAY);
  if (extract_hook_ != nullptr) extract_hook_(extract_hook_user_, true);
  const core::Status st = extractor_.extract(gray_, frame.depth_m, K_, &current_);
  if (extract_hook_ != nullptr) extract_hook_(extract_hook_user_, false);
  result.features = current_.size();
  result.timings.extract_ns = now_ns() - t0;
  if (!st.ok()) {
    ++counters_.bad_frames;
    result.state = initialized_ ? TrackState::kLost : TrackState::kWaiting;
    result.T_world_cam = T_world_cam_predicted ? *T_world_cam_predicted : T_world_cam_last_;
    if (initialized_) ++counters_.lost;
    return result;
  }

  n_correspondences_ = 0;
  if (!initialized_) {
    int with_depth = 0;
    for (int i = 0; i < current_.size(); ++i) with_depth += current_.feature(i).depth_m > 0 ? 1 : 0;
    if (with_depth < config_.min_depth_features_to_start) {
      result.state = TrackState::kWaiting;
      result.T_world_cam = T_world_cam_start;
      return result;
    }
    t0 = now_ns();
    insert_keyframe(frame, T_world_cam_start);
    result.timings.keyframe_ns = now_ns() - t0;
    initialized_ = true;
    T_world_cam_last_ = T_world_cam_start;
    T_prev_last_.setIdentity();
    t_last_ns_ = frame.t_ns;
    dt_last_ns_ = 0;
    last_keyframe_inliers_ = 0;  // the "tracking thins out" test starts with the next keyframe
    result.state = TrackState::kTracking;
    result.T_world_cam = T_world_cam_start;
    result.keyframe = true;
    result.reference_keyframe = keyframes_.newest_id();
    ++counters_.tracked;
    return result;
  }

  // Prediction: the IMU's, else constant velocity scaled to this frame's interval.
  Eigen::Isometry3d T_world_cam_pred = T_world_cam_last_;
  if (T_world_cam_predicted != nullptr) {
    T_world_cam_pred = *T_world_cam_predicted;
  } else if (dt_last_ns_ > 0) {
    const double ratio = std::clamp(static_cast<double>(frame.t_ns - t_last_ns_) / dt_last_ns_, 0.0, 3.0);
    T_world_cam_pred = T_world_cam_last_ * core::se3_exp(ratio * core::se3_log(T_prev_last_));
  }
  const Eigen::Isometry3d T_cam_world_pred = T_world_cam_pred.inverse();

  t0 = now_ns();
  const int n_local = collect_local_map();
  int n_matches = projection_.match(local_refs_.data(), n_local, T_cam_world_pred, K_, current_,
                                    config_.match, matches_.data(), static_cast<int>(matches_.size()));
  if (n_matches < config_.min_matches * 2) {
    ProjectionMatchConfig wide = config_.match;
    wide.radius_px *= config_.wide_radius_factor;
    n_matches = projection_.match(local_refs_.data(), n_local, T_cam_world_pred, K_, current_, wide,
                                  matches_.data(), static_cast<int>(matches_.size()));
  }
  result.timings.match_ns = now_ns() - t0;

  t0 = now_ns();
  RefineResult refined;
  bool ok = n_matches >= config_.min_matches && estimate_pose(n_matches, T_cam_world_pred, true, &refined);
  bool recovered = false;
  if (ok) {
    // Rematch around the refined pose: more and better matches for the final refinement.
    ProjectionMatchConfig tight = config_.match;
    tight.radius_px = config_.refine_radius_px;
    const int n2 = projection_.match(local_refs_.data(), n_local, refined.T_cam_world, K_, current_, tight,
                                     matches_.data(), static_cast<int>(matches_.size()));
    if (n2 >= config_.min_matches) {
      const int nc = build_correspondences(n2);
      std::fill(inlier_mask_.begin(), inlier_mask_.begin() + nc, uint8_t{1});
      RefineConfig second = config_.refine;
      second.rounds = config_.rematch_refine_rounds;
      const RefineResult r2 =
          refiner_.refine(correspondences_.data(), nc, K_, refined.T_cam_world, second, inlier_mask_.data());
      if (r2.ok && r2.inliers >= config_.min_inliers) {
        refined = r2;
        n_matches = n2;
      } else {
        // Keep the first estimate; its correspondences were overwritten by the rematch, so this
        // frame adds no observations.
        n_matches = 0;
      }
    }
  } else {
    int n_recovery = 0;
    ok = recover(&refined, &n_recovery);
    recovered = ok;
    n_matches = ok ? n_recovery : 0;
  }
  result.timings.pose_ns = now_ns() - t0;

  if (!ok) {
    ++counters_.lost;
    result.state = TrackState::kLost;
    result.T_world_cam = T_world_cam_pred;
    result.matches = n_matches;
    result.reference_keyframe = -1;
    // Keep predicting from the motion model (or the IMU); the next frame retries.
    T_world_cam_last_ = T_world_cam_pred;
    dt_last_ns_ = frame.t_ns - t_last_ns_;
    t_last_ns_ = frame.t_ns;
    return result;
  }

  const Eigen::Isometry3d T_world_cam = refined.T_cam_world.inverse();
  n_correspondences_ = n_matches;
  int inliers = n_matches > 0 ? 0 : refined.inliers;
  for (int i = 0; i < n_matches; ++i) {
    if (!inlier_mask_[static_cast<size_t>(i)]) continue;
    ++inliers;
    MapPoint& p = points_.at(correspondence_point_[static_cast<size_t>(i)]);
    ++p.found;
  }
  result.state = recovered ? TrackState::kRecovered : TrackState::kTracking;
  if (recovered) {
    ++counters_.recovered;
  } else {
    ++counters_.tracked;
  }
  result.T_world_cam = T_world_cam;
  result.covariance = refined.covariance;
  result.matches = n_matches;
  result.inliers = inliers;

  // Keyframe decision (paper item 3), or when tracking thins out.
  const Eigen::Isometry3d T_kf_cam = keyframes_.newest().T_world_cam.inverse() * T_world_cam;
  const bool moved = T_kf_cam.translation().norm() > config_.keyframe_translation_m ||
                     rotation_angle_rad(T_kf_cam.linear()) > config_.keyframe_rotation_rad;
  const bool thin = inliers < config_.keyframe_inlier_fraction * last_keyframe_inliers_;
  if (moved || thin || recovered) {
    t0 = now_ns();
    insert_keyframe(frame, T_world_cam);
    result.timings.keyframe_ns = now_ns() - t0;
    result.keyframe = true;
    last_keyframe_inliers_ = std::max(inliers, config_.min_inliers);
  }
  result.reference_keyframe = keyframes_.newest_id();

  T_prev_last_ = T_world_cam_last_.inverse() * T_world_cam;
  dt_last_ns_ = frame.t_ns - t_last_ns_;
  T_world_cam_last_ = T_world_cam;
  t_last_ns_ = frame.t_ns;
  return result;
}

int VisualTracker::collect_local_map() {
  ++stamp_;
  int n = 0;
  const int newest = keyframes_.newest_id();
  const int oldest = std::max(keyframes_.oldest_id(), newest - config_.local_map_keyframes + 1);
  auto take = [&](const Keyframe& kf) {
    for (int f = 0; f < kf.features.size() && n < config_.max_local_points; ++f) {
      MapPoint* p = points_.get(kf.points[static_cast<size_t>(f)]);
      if (p == nullptr || p->stamp == stamp_) continue;
      p->stamp = stamp_;
      MapPointRef& ref = local_refs_[static_cast<size_t>(n)];
      ref.p_world = p->p_world_m;
      ref.descriptor = p->descriptor.data();
      ref.octave_hint = p->octave;
      local_index_[static_cast<size_t>(n)] = kf.points[static_cast<size_t>(f)].index;
      ++n;
    }
  };
  for (int id = newest; id >= oldest && n < config_.max_local_points; --id) take(*keyframes_.get(id));
  return n;
}

int VisualTracker::build_correspondences(int n_matches) {
  for (int i = 0; i < n_matches; ++i) {
    const FeatureMatch& m = matches_[static_cast<size_t>(i)];
    const Feature& f = current_.feature(m.train);
    Correspondence& c = correspondences_[static_cast<size_t>(i)];
    c.p_world = local_refs_[static_cast<size_t>(m.query)].p_world;
    c.uv_px = Eigen::Vector2d(f.u_px, f.v_px);
    c.depth_m = f.depth_m;
    c.octave = f.octave;
    correspondence_point_[static_cast<size_t>(i)] = local_index_[static_cast<size_t>(m.query)];
    correspondence_feature_[static_cast<size_t>(i)] = m.train;
  }
  return n_matches;
}

bool VisualTracker::estimate_pose(int n_matches, const Eigen::Isometry3d& T_cam_world_guess, bool have_guess,
                                  RefineResult* out) {
  const int n = build_correspondences(n_matches);
  if (have_guess) {
    // With a prediction the matches came from projecting the map with it: refine from it directly
    // (the refinement's rounds drop outliers), as ORB-SLAM's tracking with a motion model does;
    // RANSAC only when that leaves too few inliers.
    std::fill(inlier_mask_.begin(), inlier_mask_.begin() + n, uint8_t{1});
    *out = refiner_.refine(correspondences_.data(), n, K_, T_cam_world_guess, config_.refine,
                           inlier_mask_.data());
    if (out->ok && out->inliers >= config_.min_inliers &&
        out->inliers >= config_.min_inlier_ratio_without_ransac * n) {
      return true;
    }
  }
  const PoseRansacResult rs =
      ransac_.solve(correspondences_.data(), n, K_, config_.ransac, inlier_mask_.data());
  if (!rs.ok) return false;
  ++counters_.ransac_runs;
  *out = refiner_.refine(correspondences_.data(), n, K_, rs.T_cam_world, config_.refine, inlier_mask_.data());
  return out->ok && out->inliers >= config_.min_inliers;
}

bool VisualTracker::recover(RefineResult* out, int* n_correspondences) {
  // Wide matching against the newest keyframes (FLANN LSH), then RANSAC without a prior.
  const int newest = keyframes_.newest_id();
  const int oldest = std::max(keyframes_.oldest_id(), newest - config_.recovery_keyframes + 1);
  for (int id = newest; id >= oldest; --id) {
    Keyframe* kf = keyframes_.get(id);
    lsh_.build(kf->features);
    const int nm = lsh_.match(current_, matches_.data(), static_cast<int>(matches_.size()));
    // LSH matches are (query = current feature, train = keyframe feature): keep those whose
    // keyframe feature observes a map point, as (query = local ref, train = current feature).
    int n = 0;
    for (int i = 0; i < nm && n < config_.max_local_points; ++i) {
      const FeatureMatch m = matches_[static_cast<size_t>(i)];
      const MapPointHandle h = kf->points[static_cast<size_t>(m.train)];
      const MapPoint* p = points_.get(h);
      if (p == nullptr) continue;
      MapPointRef& ref = local_refs_[static_cast<size_t>(n)];
      ref.p_world = p->p_world_m;
      ref.descriptor = p->descriptor.data();
      ref.octave_hint = p->octave;
      local_index_[static_cast<size_t>(n)] = h.index;
      matches_[static_cast<size_t>(n)] = FeatureMatch{n, m.query, m.distance};
      ++n;
    }
    if (n < config_.min_matches) continue;
    if (estimate_pose(n, Eigen::Isometry3d::Identity(), false, out)) {
      *n_correspondences = n;
      return true;
    }
  }
  return false;
}

void VisualTracker::release_keyframe_points(Keyframe* kf) {
  for (int f = 0; f < kf->features.size(); ++f) {
    const MapPointHandle h = kf->points[static_cast<size_t>(f)];
    kf->points[static_cast<size_t>(f)] = MapPointHandle{};
    MapPoint* p = points_.get(h);
    if (p == nullptr || --p->observations > 0) continue;
    points_.remove(h);
    ++counters_.points_retired;
  }
}

void VisualTracker::evict_oldest_if_full() {
  if (keyframes_.size() < keyframes_.config().capacity) return;
  release_keyframe_points(keyframes_.get(keyframes_.oldest_id()));
}

void VisualTracker::retire_points_if_low() {
  // Two keyframes' worth of free slots keeps the next keyframe's depth points and its
  // triangulation from being refused. Only keyframes outside the local map and the recovery set
  // are retired, oldest first; a point still observed by a newer keyframe stays.
  const int reserve = 2 * config_.orb.max_features;
  const int keep = std::max(config_.local_map_keyframes, config_.recovery_keyframes);
  oldest_with_points_ = std::max(oldest_with_points_, keyframes_.oldest_id());
  while (points_.capacity() - points_.alive() < reserve &&
         oldest_with_points_ <= keyframes_.newest_id() - keep) {
    if (Keyframe* kf = keyframes_.get(oldest_with_points_)) {
      release_keyframe_points(kf);
      ++counters_.keyframes_retired;
    }
    ++oldest_with_points_;
  }
}

void VisualTracker::insert_keyframe(const hal::RgbdFrame& frame, const Eigen::Isometry3d& T_world_cam) {
  if (keyframes_.ids_exhausted()) {
    if (counters_.keyframes_refused++ == 0) {
      HWR_LOG_WARN("estimation", "keyframe ids exhausted (max_total %d); no new keyframes",
                   keyframes_.config().max_total);
    }
    return;
  }
  evict_oldest_if_full();
  retire_points_if_low();
  Keyframe* kf = keyframes_.insert(frame.t_ns, T_world_cam);
  if (kf == nullptr) return;
  ++counters_.keyframes;
  for (int i = 0; i < current_.size(); ++i)
    kf->features.push_back(current_.feature(i), current_.descriptor(i));
  keyframes_.store_images(kf->id, frame.bgr, frame.depth_m);

  // Observations of tracked map points (the inliers of the last refinement; features were copied
  // in order, so feature indices carry over).
  for (int i = 0; i < n_correspondences_; ++i) {
    if (!inlier_mask_[static_cast<size_t>(i)]) continue;
    const int f = correspondence_feature_[static_cast<size_t>(i)];
    const MapPointHandle h = points_.handle(correspondence_point_[static_cast<size_t>(i)]);
    MapPoint* p = points_.get(h);
    if (p == nullptr || kf->points[static_cast<size_t>(f)].valid()) continue;
    kf->points[static_cast<size_t>(f)] = h;
    ++p->observations;
  }
  // New points from depth (eq. 3): every feature with depth that observes no point yet.
  for (int f = 0; f < kf->features.size(); ++f) {
    if (kf->points[static_cast<size_t>(f)].valid()) continue;
    const Feature& feat = kf->features.feature(f);
    if (!(feat.depth_m > 0)) continue;
    const MapPointHandle h =
        points_.create(T_world_cam * feat.p_cam_m, kf->features.descriptor(f), kf->id, feat.octave);
    if (!h.valid()) break;
    kf->points[static_cast<size_t>(f)] = h;
    points_.get(h)->observations = 1;
    ++counters_.points_from_depth;
    if (recent_points_.size() < recent_points_.capacity()) recent_points_.push_back({h, kf->id});
  }
}

void VisualTracker::map_new_keyframes() {
  if (keyframes_.empty()) return;
  // Every keyframe inserted since the last call (the camera task may add several per mapping run).
  for (int id = std::max(last_mapped_keyframe_ + 1, keyframes_.oldest_id()); id <= keyframes_.newest_id();
       ++id) {
    triangulate_with_previous(keyframes_.get(id));
    cull_points(id);
  }
  last_mapped_keyframe_ = keyframes_.newest_id();
}

void VisualTracker::triangulate_with_previous(Keyframe* kf) {
  Keyframe* prev = keyframes_.get(kf->id - 1);
  if (prev == nullptr) return;
  // Only worth a wide search when this keyframe has features that got no point from depth.
  int without = 0;
  for (int f = 0; f < kf->features.size(); ++f) without += kf->points[static_cast<size_t>(f)].valid() ? 0 : 1;
  if (without < config_.min_features_to_triangulate) return;
  lsh_.build(prev->features);
  const int nm = lsh_.match(kf->features, matches_.data(), static_cast<int>(matches_.size()));
  const Eigen::Isometry3d T_cam0_world = prev->T_world_cam.inverse();
  const Eigen::Isometry3d T_cam1_world = kf->T_world_cam.inverse();
  for (int i = 0; i < nm; ++i) {
    const FeatureMatch& m = matches_[static_cast<size_t>(i)];
    MapPointHandle& h1 = kf->points[static_cast<size_t>(m.query)];
    const MapPointHandle h0 = prev->points[static_cast<size_t>(m.train)];
    if (h1.valid() && points_.get(h1) != nullptr) continue;
    const Feature& f1 = kf->features.feature(m.query);
    const Feature& f0 = prev->features.feature(m.train);
    const Eigen::Vector2d uv1(f1.u_px, f1.v_px);
    if (MapPoint* p0 = points_.get(h0)) {
      // The previous keyframe's point, seen again: an observation if it reprojects here.
      const Eigen::Vector3d p_cam = T_cam1_world * p0->p_world_m;
      if (p_cam.z() <= 0) continue;
      const Eigen::Vector2d uv(K_.fx * p_cam.x() / p_cam.z() + K_.cx, K_.fy * p_cam.y() / p_cam.z() + K_.cy);
      const double scale = kf->features.scale(f1.octave);
      if ((uv - uv1).squaredNorm() > 5.991 * scale * scale) continue;
      h1 = h0;
      ++p0->observations;
      continue;
    }
    Eigen::Vector3d p_world;
    const TriangulationStatus ts =
        triangulate_two_view(T_cam0_world, T_cam1_world, K_, K_, Eigen::Vector2d(f0.u_px, f0.v_px), uv1,
                             config_.triangulation, &p_world);
    if (ts != TriangulationStatus::kOk) continue;
    const MapPointHandle h = points_.create(p_world, kf->features.descriptor(m.query), kf->id, f1.octave);
    if (!h.valid()) return;
    MapPoint* p = points_.get(h);
    p->triangulated = true;
    p->observations = 2;
    h1 = h;
    prev->points[static_cast<size_t>(m.train)] = h;
    ++counters_.points_triangulated;
    if (recent_points_.size() < recent_points_.capacity()) recent_points_.push_back({h, kf->id});
  }
}

void VisualTracker::cull_points(int newest_keyframe_id) {
  // A point created from one view that tracking never matched again within a few keyframes is
  // an outlier or unstable (ORB-SLAM's recent-point culling, Mur-Artal 2015 sec. VI-B).
  size_t keep = 0;
  for (size_t i = 0; i < recent_points_.size(); ++i) {
    const RecentPoint r = recent_points_[i];
    if (r.keyframe_id > newest_keyframe_id - config_.cull_after_keyframes) {
      recent_points_[keep++] = r;
      continue;
    }
    const MapPoint* p = points_.get(r.handle);
    if (p != nullptr && p->found == 0 && p->observations < 2) {
      points_.remove(r.handle);
      ++counters_.points_culled;
    }
  }
  recent_points_.resize(keep);
}

void VisualTracker::on_keyframe_moved(const Eigen::Isometry3d& T_world_kf_before,
                                      const Eigen::Isometry3d& T_world_kf_after) {
  T_world_cam_last_ = T_world_kf_after * T_world_kf_before.inverse() * T_world_cam_last_;
}

}  // namespace hwr::estimation
