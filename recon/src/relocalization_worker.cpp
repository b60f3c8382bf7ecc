#include "hwr/recon/relocalization_worker.hpp"

#include <chrono>
#include <cmath>
#include <utility>

#include "hwr/core/log.hpp"

namespace hwr::recon {

core::Expected<std::unique_ptr<RelocalizationWorker>> RelocalizationWorker::start(
    PriorMap prior, const RelocalizationWorkerConfig& config, const hal::PinholeIntrinsics& K,
    int max_features) {
  if (config.max_local_points < 1)
    return core::InvalidArgument("relocalization: max_local_points must be >= 1");
  if (!(config.local_radius_m > 0) || !std::isfinite(config.local_radius_m)) {
    return core::InvalidArgument("relocalization: local_radius_m must be positive");
  }
  if (!(config.first_attempt_m >= 0) || !(config.retry_every_m > 0) || !std::isfinite(config.retry_every_m)) {
    return core::InvalidArgument("relocalization: first_attempt_m must be >= 0 and retry_every_m positive");
  }
  if (config.max_attempts_logged < 0) return core::InvalidArgument("relocalization: max_attempts_logged < 0");
  if (config.update_prior && config.keyframe_slots < 1) {
    return core::InvalidArgument("relocalization: keyframe_slots must be >= 1");
  }
  if (!(config.confirmation.agree_m > 0) || !(config.confirmation.agree_rad > 0)) {
    return core::InvalidArgument("relocalization: confirmation agree_m and agree_rad must be positive");
  }
  if (!(config.confirmation.min_separation_m >= 0) || !std::isfinite(config.confirmation.min_separation_m)) {
    return core::InvalidArgument("relocalization: confirmation min_separation_m must be >= 0");
  }
  auto relocalizer = Relocalizer::create(config.relocalizer, K, max_features);
  if (!relocalizer.ok()) return relocalizer.status();
  std::unique_ptr<PriorMapUpdater> updater;
  if (config.update_prior) {
    auto u = PriorMapUpdater::create(prior.dir(), config.update, K);
    if (!u.ok()) return u.status();
    updater = std::make_unique<PriorMapUpdater>(std::move(u.value()));
  }
  std::unique_ptr<RelocalizationWorker> w(
      new RelocalizationWorker(std::move(prior), std::move(relocalizer.value()), config, K, max_features));
  w->updater_ = std::move(updater);
  w->thread_ = std::thread([p = w.get()] { p->run(); });
  return w;
}

RelocalizationWorker::RelocalizationWorker(PriorMap prior, Relocalizer relocalizer,
                                           const RelocalizationWorkerConfig& config,
                                           const hal::PinholeIntrinsics& K, int max_features)
    : K_(K),
      config_(config),
      prior_(std::move(prior)),
      relocalizer_(std::move(relocalizer)),
      confirmation_(config.confirmation),
      max_features_(max_features),
      features_(max_features, K.width, K.height),
      local_world_(static_cast<size_t>(config.max_local_points)),
      next_attempt_m_(config.first_attempt_m) {
  status_.log.reserve(static_cast<size_t>(config.max_attempts_logged));
  if (config.update_prior) {
    slots_.resize(static_cast<size_t>(config.keyframe_slots));
    for (KeyframeSlot& s : slots_) {
      s.bgr.create(K.height, K.width, CV_8UC3);
      s.depth_m.create(K.height, K.width, CV_32FC1);
    }
  }
  busy_.store(true, std::memory_order_relaxed);  // until the index is built (run())
}

RelocalizationWorker::~RelocalizationWorker() { stop(); }

void RelocalizationWorker::stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void RelocalizationWorker::finish() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    finishing_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

bool RelocalizationWorker::offer_keyframe(const cv::Mat& bgr, const cv::Mat& depth_m,
                                          const Eigen::Isometry3d& T_world_cam) {
  if (!localized() || updater_ == nullptr) return false;
  if (bgr.type() != CV_8UC3 || depth_m.type() != CV_32FC1 || bgr.cols != K_.width || bgr.rows != K_.height ||
      depth_m.size() != bgr.size()) {
    return false;
  }
  size_t slot = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (slot_count_ == slots_.size()) {
      ++status_.keyframes_dropped;
      return false;
    }
    slot = (slot_head_ + slot_count_) % slots_.size();
  }
  // The slot is not in the queue yet: the worker does not read it.
  bgr.copyTo(slots_[slot].bgr);  // same size and type: no allocation
  depth_m.copyTo(slots_[slot].depth_m);
  slots_[slot].T_world_cam = T_world_cam;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++slot_count_;
  }
  wake_.notify_one();
  return true;
}

bool RelocalizationWorker::take_updated(UpdatedSegment* out) {
  std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
  if (!lock.owns_lock() || updated_.empty()) return false;
  *out = std::move(updated_.front());
  updated_.erase(updated_.begin());
  return true;
}

struct RelocalizationWorker::QueuedSink final : UpdatedSegmentSink {
  RelocalizationWorker* w;
  explicit QueuedSink(RelocalizationWorker* worker) : w(worker) {}
  void take_updated(const SegmentRecord& segment, int version, int points_deleted, bool final) override {
    UpdatedSegment u;
    u.record = segment;
    u.version = version;
    u.points_deleted = points_deleted;
    u.final = final;
    std::lock_guard<std::mutex> lock(w->mutex_);
    w->updated_.push_back(std::move(u));
  }
};

void RelocalizationWorker::run_updates() {
  QueuedSink sink(this);
  for (;;) {
    size_t slot = 0;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || finishing_ || slot_count_ > 0; });
      if (stop_) return;
      if (slot_count_ == 0) break;  // finishing and nothing queued
      slot = slot_head_;
    }
    const KeyframeSlot& k = slots_[slot];
    const core::Status st = updater_->observe(k.depth_m, T_prior_world_ * k.T_world_cam, &sink);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      slot_head_ = (slot_head_ + 1) % slots_.size();
      --slot_count_;
      status_.update = updater_->counters();
      if (!st.ok() && status_.update_error.empty()) status_.update_error = st.message();
    }
  }
  const core::Status st = updater_->finish(&sink);
  std::lock_guard<std::mutex> lock(mutex_);
  status_.update = updater_->counters();
  if (!st.ok() && status_.update_error.empty()) status_.update_error = st.message();
}

void RelocalizationWorker::wait_idle() {
  std::unique_lock<std::mutex> lock(mutex_);
  idle_.wait(lock, [&] { return stop_ || !busy_.load(std::memory_order_acquire); });
}

RelocalizationWorkerStatus RelocalizationWorker::status() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return status_;
}

int gather_local_map(const VoxelMap& local_map, const Eigen::Isometry3d& T_world_segment,
                     const Eigen::Vector3d& c_world_m, double radius_m, CloudPoint* out, int capacity) {
  const Eigen::Isometry3f T_world_segment_f = T_world_segment.cast<float>();
  const Eigen::Vector3f c_world = c_world_m.cast<float>();
  const float r2 = static_cast<float>(radius_m * radius_m);
  const int total = local_map.size();
  const int stride = total > capacity ? (total + capacity - 1) / capacity : 1;
  int n = 0;
  for (int i = 0; i < total && n < capacity; i += stride) {
    const Voxel& v = local_map.at_slot(local_map.created(i));
    const Eigen::Vector3f p = T_world_segment_f * Eigen::Vector3f(v.x_m, v.y_m, v.z_m);
    if ((p - c_world).squaredNorm() > r2) continue;
    CloudPoint& q = out[n++];
    q.x_m = p.x();
    q.y_m = p.y();
    q.z_m = p.z();
    q.r = static_cast<uint8_t>(v.r);
    q.g = static_cast<uint8_t>(v.g);
    q.b = static_cast<uint8_t>(v.b);
    q.flags = 0;
  }
  return n;
}

bool RelocalizationWorker::offer(const estimation::FrameFeatures& features,
                                 const Eigen::Isometry3d& T_world_cam, const VoxelMap& local_map,
                                 const Eigen::Isometry3d& T_world_segment, double moved_m,
                                 const RelocalizationPriors& priors) {
  if (!wants_query(moved_m)) return false;
  if (features.size() > max_features_ || features.capacity() != features_.capacity() ||
      features.scale_per_octave.size() != features_.scale_per_octave.size()) {
    ++offers_refused_;
    return false;
  }
  // The worker is idle (busy_ false, acquire): it reads nothing until busy_ is set again below.
  features_ = features;  // same capacity: no allocation (frame_features.hpp)
  T_world_cam_ = T_world_cam;
  moved_m_ = moved_m;
  priors_ = priors;
  local_n_ = gather_local_map(local_map, T_world_segment, T_world_cam.translation(), config_.local_radius_m,
                              local_world_.data(), static_cast<int>(local_world_.size()));
  next_attempt_m_ = moved_m + config_.retry_every_m;
  ++offers_taken_;
  {
    std::lock_guard<std::mutex> lock(mutex_);  // no lost wake-up; held for a moment only
    busy_.store(true, std::memory_order_release);
  }
  wake_.notify_one();
  return true;
}

void RelocalizationWorker::run() {
  // The appearance index over every prior descriptor (~1 s for the lab's map): built here, so the
  // first attempt's time is the relocalization's and the robot starts without waiting for it.
  relocalizer_.prepare(prior_);
  // The clouds that fit the prior map's budget, read now for the same reason (prior_map.hpp).
  // stop() does not wait for the rest (2-3 s for the sim outdoor prior).
  const PreloadStats preload = prior_.preload_clouds([this] {
    std::lock_guard<std::mutex> lock(mutex_);
    return !stop_;
  });
  HWR_LOG_INFO(
      "reloc-worker", "prior map: %d of %zu segment clouds in memory (%lld points), %d left on disk%s",
      preload.segments_in_memory, prior_.segments().size(), static_cast<long long>(preload.points_in_memory),
      static_cast<int>(prior_.segments().size()) - preload.segments_in_memory -
          prior_.counters().unreadable_segments,
      preload.cancelled ? " (preload stopped: the worker is stopping)" : "");
  // The whole prior's NDT targets (relocalizer.hpp prepare_targets), when every cloud fit the budget.
  const Relocalizer::WholePriorTargets whole = relocalizer_.prepare_targets(prior_, [this] {
    std::lock_guard<std::mutex> lock(mutex_);
    return !stop_;
  });
  if (whole.built) {
    HWR_LOG_INFO("reloc-worker",
                 "prior map: NDT targets of the whole prior at %d resolutions (%lld voxels) in %.2f s",
                 whole.levels, static_cast<long long>(whole.voxels), whole.seconds);
  } else {
    HWR_LOG_INFO("reloc-worker", "prior map: NDT targets gathered per attempt (%s)", whole.why_not.c_str());
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    busy_.store(false, std::memory_order_release);
  }
  idle_.notify_all();
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || finishing_ || busy_.load(std::memory_order_acquire); });
      if (stop_ || (finishing_ && !busy_.load(std::memory_order_acquire))) {
        busy_.store(false, std::memory_order_release);
        idle_.notify_all();
        return;
      }
    }
    RelocalizationQuery q;
    q.features = &features_;
    q.T_world_cam = T_world_cam_;
    q.local_map_world = {&local_world_[0].x_m, local_n_,
                         static_cast<int>(sizeof(CloudPoint) / sizeof(float))};
    q.moved_m = moved_m_;
    q.position = priors_.position;
    q.yaw_valid = priors_.yaw_valid;
    q.yaw_prior_rad = priors_.yaw_prior_rad;
    q.yaw_sigma_rad = priors_.yaw_sigma_rad;
    const RelocalizationResult r = relocalizer_.relocalize(q, &prior_);
    const ConfirmationVerdict verdict = confirmation_.offer(r, q);
    const bool localized = verdict == ConfirmationVerdict::kAccepted;
    // Why a localized result was held (relocalization_confirmation.hpp), for the status and the log.
    const char* held = !r.localized || localized ? ""
                       : r.polish_refused
                           ? " (its ORB polish was refused: pending until a later attempt agrees)"
                           : " (a weak fit without a position prior: pending until a later "
                             "attempt agrees)";
    int attempt = 0;
    if (localized) T_prior_world_ = confirmation_.accepted_T_prior_world();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      attempt = ++status_.attempts;
      status_.wall_s_total += r.wall_s;
      status_.last_message = r.message + held;
      if (status_.log.size() < static_cast<size_t>(config_.max_attempts_logged)) {
        RelocalizationAttempt a;
        a.moved_m = moved_m_;
        a.wall_s = r.wall_s;
        a.reason = r.reason;
        a.position_prior = q.position.valid;
        a.yaw_prior = q.yaw_valid;
        a.local_points = local_n_;
        a.pending_confirmation = r.localized && verdict == ConfirmationVerdict::kPending;
        status_.log.push_back(a);
      }
      if (localized) {
        status_.localized = true;
        status_.T_prior_world = T_prior_world_;
        status_.moved_at_localization_m = moved_m_;
        localized_.store(true, std::memory_order_release);  // T_prior_world_ is written above
      }
      busy_.store(false, std::memory_order_release);
    }
    idle_.notify_all();
    HWR_LOG_INFO("reloc", "attempt %d at %.1f m moved (%d local points): %s%s", attempt, moved_m_, local_n_,
                 r.message.c_str(), held);
    if (localized) {
      if (updater_ != nullptr) run_updates();
      return;
    }
  }
}

}  // namespace hwr::recon
