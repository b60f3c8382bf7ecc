#include "hwr/estimation/pose_estimator.hpp"

#include <algorithm>
#include <chrono>

#include "hwr/core/log.hpp"
#include "hwr/core/so3.hpp"
#include "hwr/core/time.hpp"

namespace hwr::estimation {
namespace {

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

namespace {

PoseEstimatorConfig with_depth_noise(PoseEstimatorConfig c) {
  c.tracker.refine.depth_sigma_per_m2 = c.depth_sigma_per_m2;
  c.tracker.refine.scale_factor = c.tracker.orb.scale_factor;
  c.tracker.ransac.scale_factor = c.tracker.orb.scale_factor;
  c.local_ba.options.depth_sigma_per_m2 = c.depth_sigma_per_m2;
  return c;
}

}  // namespace

PoseEstimator::PoseEstimator(const PoseEstimatorConfig& config, const hal::SourceInfo& source)
    : config_(with_depth_noise(config)),
      source_(source),
      use_imu_(config.use_imu && source.has_imu),
      tracker_(config_.tracker, source.intrinsics),
      local_ba_(config_.local_ba, config.tracker.map_point_capacity),
      mekf_(config.imu_noise),
      static_init_(config.static_init),
      history_(config.pose_history_capacity) {
  imu_queue_.resize(static_cast<size_t>(std::max(config.imu_queue_capacity, 16)));
  records_.reserve(static_cast<size_t>(config.max_frames));
  timings_.reserve(static_cast<size_t>(config.max_frames));
  visual_only_ = !use_imu_;
}

void PoseEstimator::add_imu(const hal::ImuSample& sample) {
  if (!use_imu_) return;
  ++counters_.imu_samples;
  if (imu_count_ == imu_queue_.size()) {
    // The camera side is far behind: propagate the oldest sample rather than lose it.
    hal::ImuSample s;
    imu_front(&s);
    imu_pop();
    consume_imu(s);
    ++counters_.imu_queue_overflows;
  }
  imu_queue_[(imu_head_ + imu_count_) % imu_queue_.size()] = sample;
  ++imu_count_;
}

void PoseEstimator::add_mag(const hal::MagSample& sample) {
  if (use_imu_ && !mekf_.initialized()) static_init_.add_mag(sample);
}

bool PoseEstimator::imu_front(hal::ImuSample* s) const {
  if (imu_count_ == 0) return false;
  *s = imu_queue_[imu_head_];
  return true;
}

void PoseEstimator::imu_pop() {
  imu_head_ = (imu_head_ + 1) % imu_queue_.size();
  --imu_count_;
}

void PoseEstimator::consume_imu(const hal::ImuSample& s) {
  if (s.t_ns <= last_imu_t_ns_) return;  // non-increasing: the filter would reject it anyway
  if (!mekf_.initialized()) {
    static_init_.add_imu(s);
    if (static_init_.ready() && !visual_only_) {
      auto x0 = static_init_.result();
      if (x0.ok()) {
        mekf_.initialize(x0.value(), static_init_.initial_covariance());
        history_.push(mekf_.state());
      }
    }
    last_imu_t_ns_ = s.t_ns;
    return;
  }
  if (mekf_.propagate(s)) history_.push(mekf_.state());
  last_imu_t_ns_ = s.t_ns;
}

void PoseEstimator::advance_imu(int64_t until_ns) {
  hal::ImuSample s;
  while (imu_front(&s) && s.t_ns <= until_ns) {
    imu_pop();
    consume_imu(s);
  }
}

const TrackResult& PoseEstimator::process_frame(const hal::RgbdFrame& frame) {
  const int64_t t_start = now_ns();
  FrameTiming timing;
  timing.t_ns = frame.t_ns;
  if (frame.t_ns <= last_frame_t_ns_) {
    ++counters_.frames_out_of_order;
    return last_;
  }
  last_frame_t_ns_ = frame.t_ns;
  if (first_frame_t_ns_ == INT64_MIN) first_frame_t_ns_ = frame.t_ns;

  // Filter to the frame time: queued samples up to it, then the straddling interval split with the
  // next sample's rates (zero-order hold), so the state is exactly at the frame time.
  advance_imu(frame.t_ns);
  hal::ImuSample next;
  if (mekf_.initialized() && mekf_.state().t_ns < frame.t_ns && imu_front(&next)) {
    hal::ImuSample at_frame = next;
    at_frame.t_ns = frame.t_ns;
    if (mekf_.propagate(at_frame)) history_.push(mekf_.state());
  }
  if (use_imu_ && !visual_only_ && !mekf_.initialized()) {
    if (frame.t_ns - first_frame_t_ns_ > core::s_to_ns(config_.static_init_timeout_s)) {
      HWR_LOG_WARN("estimation", "no static IMU initialisation after %.1f s: continuing visual-only",
                   config_.static_init_timeout_s);
      visual_only_ = true;
    } else {
      ++counters_.frames_waiting_for_init;
      last_ = TrackResult{};
      timing.total_ns = now_ns() - t_start;
      if (timings_.size() < timings_.capacity()) timings_.push_back(timing);
      return last_;
    }
  }
  const Eigen::Isometry3d& T_imu_cam = source_.T_imu_cam;
  Eigen::Isometry3d T_world_cam_pred = Eigen::Isometry3d::Identity();
  bool have_prediction = mekf_.initialized();
  // The filter is exactly at the frame time unless the frame came late (the filter is past it:
  // predict from the pose history) or no IMU sample after it has arrived yet (the filter is
  // behind it: predict from the newest state). Either way the frame gives no filter update.
  bool filter_at_frame = have_prediction && mekf_.state().t_ns == frame.t_ns;
  if (have_prediction) {
    if (mekf_.state().t_ns > frame.t_ns) {
      ++counters_.frames_late_for_filter;
      if (!history_.interpolate_camera(frame.t_ns, T_imu_cam, &T_world_cam_pred).ok())
        have_prediction = false;
    } else {
      T_world_cam_pred = mekf_.state().T_world_imu() * T_imu_cam;
      if (!filter_at_frame) ++counters_.frames_ahead_of_imu;
    }
  }
  timing.imu_ns = now_ns() - t_start;

  last_ = tracker_.track(frame, have_prediction ? &T_world_cam_pred : nullptr, T_world_cam_pred);

  const int64_t t_update = now_ns();
  if (filter_at_frame && (last_.state == TrackState::kTracking || last_.state == TrackState::kRecovered)) {
    update_filter(last_);
  }
  timing.imu_ns += now_ns() - t_update;

  if (last_.state != TrackState::kWaiting && records_.size() < records_.capacity()) {
    const int ref = tracker_.keyframes().newest_id();
    const Eigen::Isometry3d T_kf_cam = tracker_.keyframes().pose(ref).inverse() * last_.T_world_cam;
    records_.push_back(
        {frame.t_ns, ref, Eigen::Quaterniond(T_kf_cam.linear()).normalized(), T_kf_cam.translation()});
  }
  if (last_.keyframe) local_ba_due_ = true;  // the mapping task's work: triangulation, local BA

  timing.track = last_.timings;
  timing.features = last_.features;
  timing.matches = last_.matches;
  timing.inliers = last_.inliers;
  timing.state = last_.state;
  timing.keyframe = last_.keyframe;
  timing.total_ns = now_ns() - t_start;
  if (timings_.size() < timings_.capacity()) timings_.push_back(timing);
  return last_;
}

void PoseEstimator::update_filter(const TrackResult& r) {
  // The refiner's covariance is of δξ with T_cam_world ← exp(δξ)·T_cam_world. Then
  // T_world_imu ← T_world_imu · exp(−Ad(T_imu_cam)·δξ) (right perturbation of T_world_imu), i.e.
  // δθ = −(Ad δξ)_φ (body frame) and δp = R_world_imu · (−(Ad δξ)_ρ).
  const Eigen::Isometry3d& T_imu_cam = source_.T_imu_cam;
  const Eigen::Isometry3d T_world_imu_meas = r.T_world_cam * T_imu_cam.inverse();
  Eigen::Matrix<double, 6, 6> Ad = Eigen::Matrix<double, 6, 6>::Zero();  // (ρ, φ) order
  const Eigen::Matrix3d R = T_imu_cam.linear();
  Ad.block<3, 3>(0, 0) = R;
  Ad.block<3, 3>(0, 3) = core::hat(T_imu_cam.translation()) * R;
  Ad.block<3, 3>(3, 3) = R;
  // Rows of J map δξ to the filter's [δθ, δp].
  Eigen::Matrix<double, 6, 6> J = Eigen::Matrix<double, 6, 6>::Zero();
  J.block<3, 6>(0, 0) = -Ad.block<3, 6>(3, 0);
  J.block<3, 6>(3, 0) = -T_world_imu_meas.linear() * Ad.block<3, 6>(0, 0);
  Eigen::Matrix<double, 6, 6> cov = J * r.covariance * J.transpose() * config_.visual_cov_inflation;
  for (int i = 0; i < 3; ++i) {
    cov(i, i) = std::max(cov(i, i), config_.visual_min_sigma_rad * config_.visual_min_sigma_rad);
    cov(i + 3, i + 3) = std::max(cov(i + 3, i + 3), config_.visual_min_sigma_m * config_.visual_min_sigma_m);
  }
  if (mekf_.update_pose(T_world_imu_meas, cov)) {
    gated_streak_ = 0;
  } else {
    ++counters_.visual_updates_gated;
    // The filter and the camera keep disagreeing: the filter has diverged (a long dropout, a bad
    // bias), not the camera, which is tracking a map. Restart it at the camera's pose, with the
    // velocity of the last two tracked poses and the biases it had.
    if (++gated_streak_ >= config_.gated_updates_before_reset && have_last_visual_) {
      NavState x = mekf_.state();
      const double dt_s = core::ns_to_s(x.t_ns - last_visual_t_ns_);
      if (dt_s > 0) x.v_world_mps = (T_world_imu_meas.translation() - last_visual_p_world_imu_m_) / dt_s;
      x.R_world_imu = T_world_imu_meas.linear();
      x.p_world_imu_m = T_world_imu_meas.translation();
      ImuMekf::Cov15 P = mekf_.covariance();
      P.topLeftCorner<9, 9>().setZero();
      P.topRightCorner<9, 6>().setZero();  // the old cross-terms belong to the diverged state
      P.bottomLeftCorner<6, 9>().setZero();
      P.topLeftCorner<6, 6>() = cov;
      P.block<3, 3>(6, 6) = Eigen::Matrix3d::Identity() * 0.1;  // (0.3 m/s)^2
      mekf_.initialize(x, P);
      history_.clear();
      history_.push(mekf_.state());
      gated_streak_ = 0;
      ++counters_.filter_resets;
    }
  }
  have_last_visual_ = true;
  last_visual_t_ns_ = mekf_.state().t_ns;
  last_visual_p_world_imu_m_ = T_world_imu_meas.translation();
}

core::Expected<LocalBaReport> PoseEstimator::run_local_ba() {
  local_ba_due_ = false;
  KeyframeStore& kfs = tracker_.keyframes();
  if (kfs.size() < 2) return LocalBaReport{};
  const Eigen::Isometry3d before = kfs.newest().T_world_cam;
  const int64_t t0 = now_ns();
  tracker_.map_new_keyframes();
  if (!config_.local_ba_enabled) {
    if (!timings_.empty()) timings_.back().local_ba_ns += now_ns() - t0;
    return LocalBaReport{};
  }
  auto report = local_ba_.run(&kfs, &tracker_.points(), tracker_.intrinsics(), false);
  if (!timings_.empty()) timings_.back().local_ba_ns += now_ns() - t0;
  ++counters_.local_ba_runs;
  // Poses may have been written back even when a pass failed: the tracker follows the map.
  tracker_.on_keyframe_moved(before, kfs.newest().T_world_cam);
  if (!report.ok()) ++counters_.local_ba_failures;
  return report;
}

core::Expected<LocalBaReport> PoseEstimator::finish() {
  tracker_.map_new_keyframes();
  if (!config_.full_ba_at_end || tracker_.keyframes().size() < 2) return LocalBaReport{};
  return local_ba_.run(&tracker_.keyframes(), &tracker_.points(), tracker_.intrinsics(), true);
}

std::vector<core::StampedPose> PoseEstimator::trajectory() const {
  std::vector<core::StampedPose> out;
  out.reserve(records_.size());
  for (const FrameRecord& r : records_) {
    Eigen::Isometry3d T_kf_cam = Eigen::Isometry3d::Identity();
    T_kf_cam.linear() = r.q_kf_cam.toRotationMatrix();
    T_kf_cam.translation() = r.p_kf_cam_m;
    out.push_back({r.t_ns, tracker_.keyframes().pose(r.reference_keyframe) * T_kf_cam});
  }
  return out;
}

PoseEstimatorCounters PoseEstimator::counters() const {
  PoseEstimatorCounters c = counters_;
  c.tracker = tracker_.counters();
  c.mekf = mekf_.counters();
  c.imu_initialized = mekf_.initialized();
  c.visual_only = visual_only_;
  return c;
}

}  // namespace hwr::estimation
