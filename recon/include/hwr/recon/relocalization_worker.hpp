#pragma once
// Relocalization and prior-map update off the control loop (issue #6 items 2-3: "else keep trying
// while the robot moves and say 'not localized'"; "after relocalization, current observations update
// the prior map"). The robot's mapping task offers a query now and then (offer()); a worker
// thread runs Relocalizer::relocalize() on a copy of it against the prior map, which only this
// thread touches. The mapping task never waits: offer() returns false while an attempt is running
// or before the robot has moved retry_every_m since the last one, and localized() is one atomic
// load. Once an attempt succeeds, T_prior_world is fixed and the worker stops searching.
// With update_prior, the worker then runs the map update (prior_map_updater.hpp): the mapping task
// offers each settled keyframe's images and pose (offer_keyframe(), copied into keyframe_slots
// preallocated slots; a keyframe offered while they are all full is dropped and counted), and takes
// the updated prior segments back (take_updated()) for the map store and the ground station.
// finish() processes what is queued, closes the open segments and joins the thread.
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
#include "hwr/recon/prior_map_updater.hpp"
#include "hwr/recon/relocalization_confirmation.hpp"
#include "hwr/recon/relocalizer.hpp"
#include "hwr/recon/voxel_map.hpp"

namespace hwr::recon {

struct RelocalizationWorkerConfig {
  RelocalizerConfig relocalizer;
  // A weak fit found without a position prior, or a fit whose ORB polish was refused, waits for a
  // later attempt to agree (relocalization_confirmation.hpp).
  RelocalizationConfirmationConfig confirmation;
  double first_attempt_m = 0.5;  // distance moved before the first attempt (the local map needs views)
  double retry_every_m = 0.5;    // after a failed attempt, this much more motion before the next
  // The local map sent with a query: the voxels within local_radius_m of the camera, every k-th one
  // (creation order) so that at most max_local_points go. The relocalizer subsamples further.
  double local_radius_m = 8.0;
  int max_local_points = 100'000;
  int max_attempts_logged = 256;  // status(): the first ones are kept
  bool update_prior = true;       // run the map update once localized
  PriorMapUpdaterConfig update;
  // Settled keyframes waiting for the map update (a depth image each, 1.2 MB at 640 x 480). With a pose
  // per prior segment the update takes ~0.1 s of CPU per keyframe on this host: 4 slots dropped 46-94 of
  // the lab revisit's keyframes, 16 drop none (the same share of the moved plate's old place deleted,
  // 38.4 %; hwr-robot --source sim:lab-revisit --prior-map, docs/prior_map_update.md).
  int keyframe_slots = 16;
};

// The local map a query carries (RelocalizationWorkerConfig::local_radius_m, max_local_points): the
// voxels of `local_map` (segment frame) within radius_m of c_world_m once moved by T_world_segment,
// every k-th in creation order, k from the whole map's size so that at most `capacity` fit (the count
// near the camera is not known before the pass: a conservative, never overfull choice). Writes them to
// out[0, n) in the world frame and returns n. No allocation (RelocalizationWorker::offer, and
// hwr-bench reloc, which sends what the robot sends).
int gather_local_map(const VoxelMap& local_map, const Eigen::Isometry3d& T_world_segment,
                     const Eigen::Vector3d& c_world_m, double radius_m, CloudPoint* out, int capacity);

// An updated prior segment (a new version) for the map store and the ground station.
struct UpdatedSegment {
  SegmentRecord record;  // in its segment frame; record.T_world_segment is in the prior frame
  int version = 1;
  int points_deleted = 0;
  bool final = false;  // the latest version at the end of the run (for the map store)
};

// One attempt, for the end-of-run report.
struct RelocalizationAttempt {
  double moved_m = 0;
  double wall_s = 0;
  RelocalizationReason reason = RelocalizationReason::kNdtFailed;
  bool position_prior = false, yaw_prior = false;
  int local_points = 0;
  bool pending_confirmation = false;  // a localized pose held until a later attempt agrees
};

struct RelocalizationWorkerStatus {
  int attempts = 0;
  bool localized = false;
  Eigen::Isometry3d T_prior_world = Eigen::Isometry3d::Identity();
  double moved_at_localization_m = 0;
  double wall_s_total = 0;                 // relocalize() time over every attempt
  std::string last_message;                // the last attempt's one-line result
  std::vector<RelocalizationAttempt> log;  // up to max_attempts_logged
  PriorMapUpdaterCounters update;          // map update (after localization)
  uint64_t keyframes_dropped = 0;          // offered while every slot was taken
  std::string update_error;                // the first map-update error, if any
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
  // Whether offer() would take a query now (idle, not localized, moved enough): the caller computes
  // the query's priors only then.
  bool wants_query(double moved_m) const { return !localized() && !busy() && moved_m >= next_attempt_m_; }
  // Whether an attempt succeeded; then T_prior_world() is fixed for the rest of the run.
  bool localized() const { return localized_.load(std::memory_order_acquire); }
  const Eigen::Isometry3d& T_prior_world() const { return T_prior_world_; }
  bool busy() const { return busy_.load(std::memory_order_acquire); }
  uint64_t offers_taken() const { return offers_taken_; }
  uint64_t offers_refused() const { return offers_refused_; }

  // Map update (after localization): a settled keyframe's colour and depth images and its pose in the
  // current world. False when not localized, updates are off, or every slot is taken (dropped,
  // counted). Copies into preallocated slots: never allocates, never blocks on the update.
  bool offer_keyframe(const cv::Mat& bgr, const cv::Mat& depth_m, const Eigen::Isometry3d& T_world_cam);
  // Pops one updated prior segment, if any (the mapping task, each cycle; end of run after finish()).
  bool take_updated(UpdatedSegment* out);
  // End of run: the queued keyframes are processed, the open segments closed (their updates queued
  // for take_updated()), the thread joined.
  void finish();

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
  void run_updates();  // after localization
  struct QueuedSink;

  std::unique_ptr<PriorMapUpdater> updater_;  // update_prior
  struct KeyframeSlot {
    cv::Mat bgr, depth_m;
    Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  };
  std::vector<KeyframeSlot> slots_;
  size_t slot_head_ = 0, slot_count_ = 0;  // guarded by mutex_; the head slot is the worker's until popped
  std::vector<UpdatedSegment> updated_;    // guarded by mutex_
  bool finishing_ = false;                 // guarded by mutex_

  hal::PinholeIntrinsics K_;
  RelocalizationWorkerConfig config_;
  PriorMap prior_;
  Relocalizer relocalizer_;
  RelocalizationConfirmation confirmation_;  // worker thread
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
