#pragma once
// Relocalization off the control loop (issue #6 item 2: "else keep trying while the robot moves and
// say 'not localized'"). The robot's mapping task offers a query now and then (offer()); a worker
// thread runs Relocalizer::relocalize() on a copy of it against the prior map, which only this
// thread touches. The mapping task never waits: offer() returns false while an attempt is running
// or before the robot has moved retry_every_m since the last one, and localized() is one atomic
// load. Once an attempt succeeds, T_prior_world is fixed and the worker stops searching.
//
// The query copy (the keyframe's features, the local map's points near the camera, the priors) is
// sized in start(): offer() copies into it without allocating. The worker thread allocates (see
// relocalizer.hpp "Memory"): it is not on the control loop.
//
// Threads: offer(), localized(), T_prior_world() and the counters are for the one thread that runs
// the scheduler; status() and stop() may be called from any thread.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/estimation/frame_features.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/recon/keyframe_cloud.hpp"
#include "hwr/recon/prior_map.hpp"
#include "hwr/recon/relocalizer.hpp"
#include "hwr/recon/voxel_map.hpp"

namespace hwr::recon {

struct RelocalizationWorkerConfig {
  RelocalizerConfig relocalizer;
  double first_attempt_m = 0.5;  // distance moved before the first attempt (the local map needs views)
  double retry_every_m = 0.5;    // after a failed attempt, this much more motion before the next
  // The local map sent with a query: the voxels within local_radius_m of the camera, every k-th one
  // (creation order) so that at most max_local_points go. The relocalizer subsamples further.
  double local_radius_m = 8.0;
  int max_local_points = 100'000;
  int max_attempts_logged = 256;  // status(): the first ones are kept
};

// One attempt, for the end-of-run report.
struct RelocalizationAttempt {
  double moved_m = 0;
  double wall_s = 0;
  RelocalizationReason reason = RelocalizationReason::kNdtFailed;
  bool position_prior = false, yaw_prior = false;
  int local_points = 0;
};

struct RelocalizationWorkerStatus {
  int attempts = 0;
  bool localized = false;
  Eigen::Isometry3d T_prior_world = Eigen::Isometry3d::Identity();
  double moved_at_localization_m = 0;
  double wall_s_total = 0;                 // relocalize() time over every attempt
  std::string last_message;                // the last attempt's one-line result
  std::vector<RelocalizationAttempt> log;  // up to max_attempts_logged
};

// The priors of a query (the caller fills them from the magnetometer and GNSS).
struct RelocalizationPriors {
  PositionPrior position;
  bool yaw_valid = false;
  double yaw_prior_rad = 0, yaw_sigma_rad = 0;
};

class RelocalizationWorker {
 public:
  // Takes the prior map (only the worker thread uses it from now on) and builds its appearance
  // index on the worker thread before the first attempt. Errors: the relocalizer's
  // (kInvalidArgument), max_local_points < 1, a radius or distance not positive.
  static core::Expected<std::unique_ptr<RelocalizationWorker>> start(PriorMap prior,
                                                                     const RelocalizationWorkerConfig& config,
                                                                     const hal::PinholeIntrinsics& K,
                                                                     int max_features);
  ~RelocalizationWorker();  // stop()

  // Offers a query: the keyframe (its features and pose in the current world), the active local
  // map (voxels in its segment frame, T_world_segment), the distance moved since the run started
  // and the priors. Returns true when the worker took it (idle, not localized, moved enough);
  // false otherwise, without copying anything. Never blocks on the attempt; never allocates.
  // A query with more features than max_features is refused (false, counted).
  bool offer(const estimation::FrameFeatures& features, const Eigen::Isometry3d& T_world_cam,
             const VoxelMap& local_map, const Eigen::Isometry3d& T_world_segment, double moved_m,
             const RelocalizationPriors& priors);
  // Whether an attempt succeeded; then T_prior_world() is fixed for the rest of the run.
  bool localized() const { return localized_.load(std::memory_order_acquire); }
  const Eigen::Isometry3d& T_prior_world() const { return T_prior_world_; }
  bool busy() const { return busy_.load(std::memory_order_acquire); }
  uint64_t offers_taken() const { return offers_taken_; }
  uint64_t offers_refused() const { return offers_refused_; }

  // Waits for a running attempt to end (end of a replay: its answer still counts).
  void wait_idle();
  RelocalizationWorkerStatus status() const;  // allocates: telemetry and the end-of-run report
  void stop();                                // joins the thread; idempotent

  RelocalizationWorker(const RelocalizationWorker&) = delete;
  RelocalizationWorker& operator=(const RelocalizationWorker&) = delete;

 private:
  RelocalizationWorker(PriorMap prior, Relocalizer relocalizer, const RelocalizationWorkerConfig& config,
                       const hal::PinholeIntrinsics& K, int max_features);
  void run();

  RelocalizationWorkerConfig config_;
  PriorMap prior_;
  Relocalizer relocalizer_;
  int max_features_;

  // The query copy: written by offer() only while !busy_, read by the worker only while busy_.
  estimation::FrameFeatures features_;
  Eigen::Isometry3d T_world_cam_ = Eigen::Isometry3d::Identity();
  std::vector<CloudPoint> local_world_;  // capacity max_local_points
  int local_n_ = 0;
  double moved_m_ = 0;
  RelocalizationPriors priors_;

  double next_attempt_m_ = 0;  // scheduler thread
  uint64_t offers_taken_ = 0, offers_refused_ = 0;

  std::atomic<bool> busy_{false};
  std::atomic<bool> localized_{false};
  Eigen::Isometry3d T_prior_world_ = Eigen::Isometry3d::Identity();  // written once, before localized_

  mutable std::mutex mutex_;  // guards status_, stop_, the wake-up
  std::condition_variable wake_, idle_;
  bool stop_ = false;
  RelocalizationWorkerStatus status_;
  std::thread thread_;
};

}  // namespace hwr::recon
