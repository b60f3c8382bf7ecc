#include "hwr/recon/prior_map_updater.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "hwr/core/log.hpp"

namespace hwr::recon {

struct PriorMapUpdater::Impl {
  // A prior segment as the updater knows it before reading its cloud.
  struct Entry {
    uint32_t segment_id = 0;
    Eigen::Isometry3d T_prior_segment = Eigen::Isometry3d::Identity();
    Eigen::AlignedBox3d box_prior;  // its keyframes grown by reach_m, then its cloud once read
    // Where its keyframes looked: camera centre + look_ahead_m along the optical axis (prior frame).
    std::vector<Eigen::Vector3d> look_prior;
    std::vector<Eigen::Isometry3d> T_cam_prior;  // its keyframes' (inverse poses): what they could see
    bool skip = false;                           // unreadable or too big
    int version = 0;  // 0: as in the prior store; else the latest version is in `updated`
    int deleted_total = 0;
    std::unique_ptr<SegmentRecord> updated;
  };
  // An open segment: its record and the carver over its points (segment frame).
  struct Open {
    size_t entry = 0;
    SegmentRecord record;
    int carver = 0;  // index into carvers
    uint64_t last_seen = 0;
  };

  PriorMapUpdaterConfig config;
  hal::PinholeIntrinsics K;
  MapStore store;
  std::vector<Entry> entries;
  std::vector<FreeSpaceCarver> carvers;  // max_open_segments, reused
  std::vector<Open> open;
  std::vector<std::pair<double, size_t>> seen;
  // This keyframe's depth samples for step 1 (prior frame): an 8 x 6 grid of pixels within the carving range.
  std::vector<Eigen::Vector3d> view_samples_prior;
  static constexpr int kViewSamplesU = 8, kViewSamplesV = 6;
  std::vector<int> in_view;      // open indices seen by this keyframe (capacity: max_open_segments)
  std::vector<PriorView> views;  // their carvers for the pose refinement (same capacity)
  // The last accepted refinement's correction T_refined * T_relocalized^-1 (prior frame): the
  // relocalization's error is nearly constant over a stretch of keyframes, so it is the next guess.
  // Its information is about zeta = (omega, v) in the prior's axes, v the displacement of the point
  // correction_centre_prior (that keyframe's camera centre).
  Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();
  Eigen::Matrix<double, 6, 6> correction_information = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Vector3d correction_centre_prior = Eigen::Vector3d::Zero();
  uint64_t tick = 0;
  PriorMapUpdaterCounters counters;
  PriorMapUpdateFrame last;

  PriorPoseRefiner refiner;

  Impl(const PriorMapUpdaterConfig& c, const hal::PinholeIntrinsics& k, MapStore s, PriorPoseRefiner r)
      : config(c), K(k), store(std::move(s)), refiner(std::move(r)) {}

  core::Status close(size_t i, UpdatedSegmentSink* sink) {
    Open& o = open[i];
    auto deleted = carvers[static_cast<size_t>(o.carver)].apply(&o.record.points_segment);
    core::Status st = deleted.status();
    if (deleted.ok() && deleted.value() > 0) {
      Entry& e = entries[o.entry];
      if (e.version == 0) ++counters.segments_updated;
      ++e.version;
      e.deleted_total += deleted.value();
      counters.points_deleted += deleted.value();
      HWR_LOG_INFO("map-update", "prior segment %u: %d of %zu points deleted (observed free), version %d",
                   o.record.segment_id, deleted.value(), o.record.points_segment.size() + deleted.value(),
                   e.version);
      if (sink != nullptr) sink->take_updated(o.record, e.version, deleted.value(), false);
      e.updated = std::make_unique<SegmentRecord>(std::move(o.record));
    }
    open.erase(open.begin() + static_cast<ptrdiff_t>(i));
    return st;
  }

  // Opens entry e (closing the least recently seen segment that is not in `keep` when all slots are
  // taken). Returns the open index, or -1 when the segment is skipped.
  core::Expected<int> open_entry(size_t e, UpdatedSegmentSink* sink) {
    for (size_t i = 0; i < open.size(); ++i) {
      if (open[i].entry == e) return static_cast<int>(i);
    }
    std::vector<bool> used(carvers.size(), false);
    if (open.size() == carvers.size()) {
      size_t lru = open.size();
      for (size_t i = 0; i < open.size(); ++i) {
        if (open[i].last_seen == tick) continue;  // seen by this keyframe: kept
        if (lru == open.size() || open[i].last_seen < open[lru].last_seen) lru = i;
      }
      if (lru == open.size()) return -1;  // every slot is in view (seen is capped to the slots)
      const core::Status st = close(lru, sink);
      if (!st.ok()) return st;
    }
    for (const Open& o : open) used[static_cast<size_t>(o.carver)] = true;
    core::Expected<SegmentRecord> record = entries[e].updated
                                               ? core::Expected<SegmentRecord>(*entries[e].updated)
                                               : store.read_segment(entries[e].segment_id);
    if (!record.ok()) {
      entries[e].skip = true;
      return record.status();
    }
    if (record->points_segment.size() > static_cast<size_t>(config.max_segment_points)) {
      entries[e].skip = true;
      ++counters.segments_too_big;
      return -1;
    }
    Open o;
    o.entry = e;
    o.carver = static_cast<int>(std::find(used.begin(), used.end(), false) - used.begin());
    o.record = std::move(record.value());
    const core::Status st = carvers[static_cast<size_t>(o.carver)].set_prior(
        o.record.points_segment.data(), static_cast<int>(o.record.points_segment.size()));
    if (!st.ok()) {
      entries[e].skip = true;
      return st;
    }
    // Its real extent from now on.
    Eigen::AlignedBox3d box;
    for (const CloudPoint& p : o.record.points_segment) {
      box.extend(entries[e].T_prior_segment * Eigen::Vector3d(p.x_m, p.y_m, p.z_m));
    }
    if (!box.isEmpty()) entries[e].box_prior = box;
    ++counters.segments_opened;
    open.push_back(std::move(o));
    return static_cast<int>(open.size() - 1);
  }
};

core::Expected<PriorMapUpdater> PriorMapUpdater::create(const std::string& prior_dir,
                                                        const PriorMapUpdaterConfig& config,
                                                        const hal::PinholeIntrinsics& K) {
  if (!K.valid()) return core::InvalidArgument("map update: invalid intrinsics");
  if (config.max_open_segments < 1 || config.max_segment_points < 1 || config.carve_stride_px < 1) {
    return core::InvalidArgument(
        "map update: max_open_segments, max_segment_points and carve_stride_px must be >= 1");
  }
  if (!(config.reach_m > 0) || !(config.look_ahead_m >= 0) || !std::isfinite(config.look_ahead_m)) {
    return core::InvalidArgument("map update: reach_m must be positive and look_ahead_m finite and >= 0");
  }
  if (!(config.carried_information >= 0.0 && config.carried_information <= 1.0)) {
    return core::InvalidArgument("map update: carried_information must be in [0, 1] (got " +
                                 std::to_string(config.carried_information) + ")");
  }
  auto store = MapStore::open_existing(prior_dir);
  if (!store.ok()) return store.status();
  auto refiner = PriorPoseRefiner::create(config.refine, K);
  if (!refiner.ok()) return refiner.status();
  auto impl = std::make_unique<Impl>(config, K, std::move(store.value()), std::move(refiner.value()));
  impl->seen.reserve(static_cast<size_t>(config.max_open_segments) + 1);
  impl->view_samples_prior.reserve(Impl::kViewSamplesU * Impl::kViewSamplesV);
  impl->in_view.reserve(static_cast<size_t>(config.max_open_segments));
  impl->views.reserve(static_cast<size_t>(config.max_open_segments));
  impl->last.views.reserve(static_cast<size_t>(config.max_open_segments));
  for (int i = 0; i < config.max_open_segments; ++i) {
    auto c = FreeSpaceCarver::create(config.carver, config.max_segment_points);
    if (!c.ok()) return c.status();
    impl->carvers.push_back(std::move(c.value()));
  }
  auto list = impl->store.list_segments();
  if (!list.ok()) return list.status();
  for (const SegmentSummary& s : list.value()) {
    auto seg = impl->store.read_keyframes(s.segment_id);
    if (!seg.ok()) {
      HWR_LOG_WARN("map-update", "prior segment %u skipped: %s", s.segment_id,
                   seg.status().message().c_str());
      continue;
    }
    Impl::Entry e;
    e.segment_id = s.segment_id;
    e.T_prior_segment = seg->T_world_segment;
    for (const StoredKeyframe& kf : seg->keyframes) {
      e.box_prior.extend(kf.T_world_cam.translation());
      e.look_prior.push_back(kf.T_world_cam * Eigen::Vector3d(0, 0, config.look_ahead_m));
      e.T_cam_prior.push_back(kf.T_world_cam.inverse());
    }
    if (e.box_prior.isEmpty()) e.box_prior.extend(seg->T_world_segment.translation());
    const Eigen::Vector3d reach = Eigen::Vector3d::Constant(config.reach_m);
    e.box_prior = Eigen::AlignedBox3d(e.box_prior.min() - reach, e.box_prior.max() + reach);
    impl->entries.push_back(std::move(e));
  }
  return PriorMapUpdater(std::move(impl));
}

PriorMapUpdater::PriorMapUpdater(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
PriorMapUpdater::PriorMapUpdater(PriorMapUpdater&&) noexcept = default;
PriorMapUpdater& PriorMapUpdater::operator=(PriorMapUpdater&&) noexcept = default;
PriorMapUpdater::~PriorMapUpdater() = default;

const PriorMapUpdaterCounters& PriorMapUpdater::counters() const { return impl_->counters; }
const PriorMapUpdateFrame& PriorMapUpdater::last_frame() const { return impl_->last; }
const Eigen::Isometry3d& PriorMapUpdater::correction() const { return impl_->correction; }

core::Status PriorMapUpdater::observe(const cv::Mat& depth_m, const Eigen::Isometry3d& T_prior_cam,
                                      UpdatedSegmentSink* sink) {
  Impl& m = *impl_;
  if (depth_m.type() != CV_32FC1 || depth_m.cols != m.K.width || depth_m.rows != m.K.height) {
    return core::InvalidArgument("map update: expected a CV_32FC1 depth image of the camera's size");
  }
  ++m.tick;
  ++m.counters.keyframes;
  m.last.views.clear();
  m.last.refinement = PriorPoseRefinement();
  m.last.T_prior_cam_in = m.last.T_prior_cam_guess = m.last.T_prior_cam_used = T_prior_cam;
  // 1. Prior segments in view (box within the carving range), those whose keyframes saw most of this
  // view's depth samples first, then those that looked at the place this camera looks at, at most one
  // per slot. By box distance alone every segment whose box holds the camera tied at 0 and the lowest
  // ids won: in the lab revisit the two later passes by the moved plate were never opened; by look-at
  // alone the first pass's segment 8 was not (header).
  const Eigen::Vector3d c = T_prior_cam.translation();
  const Eigen::Vector3d look = T_prior_cam * Eigen::Vector3d(0, 0, m.config.look_ahead_m);
  const double view_m = m.config.carver.max_depth_m;
  m.view_samples_prior.clear();
  if (m.config.rank_by_view_samples) {
    for (int j = 0; j < Impl::kViewSamplesV; ++j) {
      for (int i = 0; i < Impl::kViewSamplesU; ++i) {
        const int u = (2 * i + 1) * m.K.width / (2 * Impl::kViewSamplesU);
        const int v = (2 * j + 1) * m.K.height / (2 * Impl::kViewSamplesV);
        const float z = depth_m.ptr<float>(v)[u];
        if (!(z >= m.config.carver.min_depth_m && z <= m.config.carver.max_depth_m)) continue;
        const Eigen::Vector3d p_cam((u - m.K.cx) / m.K.fx * z, (v - m.K.cy) / m.K.fy * z, z);
        m.view_samples_prior.push_back(T_prior_cam * p_cam);
      }
    }
  }
  m.seen.clear();
  for (size_t e = 0; e < m.entries.size(); ++e) {
    if (m.entries[e].skip) continue;
    if (m.entries[e].box_prior.exteriorDistance(c) > view_m) continue;
    double nearest = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& l : m.entries[e].look_prior)
      nearest = std::min(nearest, (l - look).squaredNorm());
    int seen_samples = 0;
    for (const Eigen::Vector3d& p : m.view_samples_prior) {
      for (const Eigen::Isometry3d& T_cam_prior : m.entries[e].T_cam_prior) {
        const Eigen::Vector3d q = T_cam_prior * p;
        if (!(q.z() > m.config.carver.min_depth_m && q.z() < m.config.reach_m)) continue;
        const double u = m.K.fx * q.x() / q.z() + m.K.cx, v = m.K.fy * q.y() / q.z() + m.K.cy;
        if (u >= 0 && v >= 0 && u < m.K.width && v < m.K.height) {
          ++seen_samples;
          break;
        }
      }
    }
    m.seen.emplace_back(static_cast<double>(-seen_samples) + nearest / (1.0 + nearest), e);
  }
  std::sort(m.seen.begin(), m.seen.end());
  if (m.seen.size() > m.carvers.size()) m.seen.resize(m.carvers.size());
  std::vector<int>& in_view = m.in_view;
  in_view.clear();
  core::Status first_error;
  for (const auto& [d, e] : m.seen) {
    auto o = m.open_entry(e, sink);
    if (!o.ok()) {
      if (first_error.ok()) first_error = o.status();
      continue;
    }
    if (o.value() < 0) continue;
    m.open[static_cast<size_t>(o.value())].last_seen = m.tick;
  }
  for (size_t i = 0; i < m.open.size(); ++i) {
    if (m.open[i].last_seen == m.tick) in_view.push_back(static_cast<int>(i));
  }
  if (in_view.empty()) {
    ++m.counters.no_prior_in_view;
    return first_error;
  }
  // 2. The pose, refined against every segment in view from the carried correction (header).
  m.views.clear();
  for (int i : in_view) {
    const Impl::Open& o = m.open[static_cast<size_t>(i)];
    m.views.push_back({&m.carvers[static_cast<size_t>(o.carver)], m.entries[o.entry].T_prior_segment});
  }
  PriorPoseGuess guess;
  guess.T_prior_cam = m.correction * T_prior_cam;
  guess.T_prior_cam_anchor = T_prior_cam;
  // The carried information (prior frame, about correction_centre_prior), decayed once per keyframe
  // and moved to this camera: xi (camera frame) -> zeta = N xi, N = diag(R, R), at the camera's
  // centre -> P zeta at the old centre, P = [I 0; [dc]x I] (a rotation omega about the old centre
  // moves this one by omega x dc more).
  m.correction_information *= m.config.carried_information;
  const auto camera_to_prior = [](const Eigen::Matrix3d& R_prior_cam) {
    Eigen::Matrix<double, 6, 6> N = Eigen::Matrix<double, 6, 6>::Zero();
    N.topLeftCorner<3, 3>() = R_prior_cam;
    N.bottomRightCorner<3, 3>() = R_prior_cam;
    return N;
  };
  // The carried information about zeta at `centre` instead of the old centre: P^T I P.
  const auto carried_at = [&](const Eigen::Vector3d& centre) {
    Eigen::Matrix<double, 6, 6> P = Eigen::Matrix<double, 6, 6>::Identity();
    const Eigen::Vector3d dc = centre - m.correction_centre_prior;
    P.bottomLeftCorner<3, 3>() << 0.0, -dc.z(), dc.y(), dc.z(), 0.0, -dc.x(), -dc.y(), dc.x(), 0.0;
    return Eigen::Matrix<double, 6, 6>(P.transpose() * m.correction_information * P);
  };
  {
    const Eigen::Matrix<double, 6, 6> N = camera_to_prior(guess.T_prior_cam.linear());
    guess.information = N.transpose() * carried_at(guess.T_prior_cam.translation()) * N;
  }
  auto refined = m.refiner.refine(m.views.data(), static_cast<int>(m.views.size()), depth_m, guess);
  if (!refined.ok()) return refined.status();
  switch (refined->result) {
    case PoseRefinement::kConverged:
      ++m.counters.poses_refined;
      break;
    case PoseRefinement::kNotConverged:
      ++m.counters.refine_not_converged;
      break;
    case PoseRefinement::kTooFewRays:
      ++m.counters.refine_too_few_rays;
      break;
    case PoseRefinement::kTooLarge:
      ++m.counters.refine_too_large;
      break;
    case PoseRefinement::kOff:
      break;
  }
  const Eigen::Isometry3d& T_prior_cam_used = refined->T_prior_cam;
  m.last.T_prior_cam_guess = guess.T_prior_cam;
  m.last.T_prior_cam_used = T_prior_cam_used;
  m.last.refinement = refined.value();
  // 3. Carve every segment in view.
  bool any_carved = false;
  for (size_t vi = 0; vi < in_view.size(); ++vi) {
    Impl::Open& o = m.open[static_cast<size_t>(in_view[vi])];
    // Each segment's own pose (header, step 2): the segments in view disagree by millimetres to a
    // centimetre, more than the check allows, so the joint pose is only where each refinement starts.
    // (Refined only where the joint pose failed the check, the lab revisit lost 55 -> 40 % of the old
    // place: the votes are better with each segment's pose.)
    Eigen::Isometry3d T_prior_cam_segment = T_prior_cam_used;
    PriorPoseRefinement segment_refined;
    if (m.config.refine_per_segment && in_view.size() > 1 && refined->result == PoseRefinement::kConverged) {
      PriorPoseGuess g;
      g.T_prior_cam = T_prior_cam_used;
      g.T_prior_cam_anchor = T_prior_cam_used;  // its correction: from the joint pose
      auto r = m.refiner.refine_again(&m.views[vi], 1, g, m.config.segment_max_iterations);
      if (!r.ok()) return r.status();
      segment_refined = r.value();
      if (segment_refined.result == PoseRefinement::kConverged &&
          segment_refined.correction_m <= m.config.segment_max_correction_m &&
          segment_refined.correction_rad <= m.config.segment_max_correction_rad) {
        T_prior_cam_segment = segment_refined.T_prior_cam;
        ++m.counters.segment_poses_refined;
      }
    }
    // The pose check on the refinement's measured planes (free_space_carver.hpp), when it measured any.
    const bool planes = m.config.check_on_planes && m.refiner.plane_count() > 0;
    auto stats = m.carvers[static_cast<size_t>(o.carver)].observe(
        depth_m, m.K, m.entries[o.entry].T_prior_segment.inverse() * T_prior_cam_segment,
        m.config.carve_stride_px, planes ? m.refiner.planes() : nullptr,
        planes ? m.refiner.plane_count() : 0);
    if (!stats.ok()) return stats.status();
    m.last.views.push_back(
        {m.entries[o.entry].segment_id, T_prior_cam_segment, segment_refined, stats.value()});
    if (stats->misaligned) {
      ++m.counters.frames_misaligned;
    } else {
      ++m.counters.frames_carved;
      any_carved = true;
    }
  }
  // A refinement the carver's pose check confirmed in a view carries to the next keyframe.
  if (refined->result == PoseRefinement::kConverged && any_carved) {
    // Both terms about zeta at the refined camera: the carried one moved there (not the guess's, which
    // sits at the guess's camera, up to max_correction away), the data's turned from its camera frame.
    m.correction = T_prior_cam_used * T_prior_cam.inverse();
    const Eigen::Matrix<double, 6, 6> N = camera_to_prior(T_prior_cam_used.linear());
    m.correction_information =
        carried_at(T_prior_cam_used.translation()) + N * refined->information * N.transpose();
    m.correction_centre_prior = T_prior_cam_used.translation();
  }
  return first_error;
}

core::Status PriorMapUpdater::finish(UpdatedSegmentSink* sink) {
  core::Status first_error;
  while (!impl_->open.empty()) {
    const core::Status st = impl_->close(impl_->open.size() - 1, sink);
    if (!st.ok() && first_error.ok()) first_error = st;
  }
  if (sink != nullptr) {
    for (const Impl::Entry& e : impl_->entries) {
      if (e.updated) sink->take_updated(*e.updated, e.version, e.deleted_total, true);
    }
  }
  return first_error;
}

}  // namespace hwr::recon
