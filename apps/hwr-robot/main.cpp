// hwr-robot: the robot process. A source (dataset replay, a simulator run on disk, or the
// simulator rendering live) is polled by the "hal" task into bounded rings; the fixed-rate
// scheduler's pipeline tasks drain them into pose estimation (docs/estimation.md): the inertial
// task feeds the IMU filter, the camera task tracks frames, the mapping task runs the
// sliding-window bundle adjustment and fuses settled keyframes into local maps, closed into the
// map store as they fill (docs/reconstruction.md); a full bundle adjustment ends the run. Replay runs on a
// simulated clock: deterministic, faster than real time; --realtime paces it at sensor rate.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cinttypes>
#include <cstddef>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "hwr/core/file_io.hpp"
#include "hwr/core/log.hpp"
#include "hwr/core/malloc_policy.hpp"
#include "hwr/core/scheduler.hpp"
#include "hwr/core/time.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/estimation/bal_format.hpp"
#include "hwr/estimation/estimator_config.hpp"
#include "hwr/estimation/local_bundle_adjustment.hpp"
#include "hwr/estimation/pose_estimator.hpp"
#include "hwr/hal/fault_injection.hpp"
#include "hwr/hal/hw/hw_source.hpp"
#include "hwr/hal/replay_source.hpp"
#include "hwr/hal/stream_health.hpp"
#include "hwr/mapio/map_streamer.hpp"
#include "hwr/mapio/recording_log.hpp"
#include "hwr/mapio/sensor_recorder.hpp"
#include "hwr_lcm/status_t.hpp"
#include "hwr/recon/local_mapper.hpp"
#include "hwr/recon/local_mapper_config.hpp"
#include "hwr/recon/map_store.hpp"
#include "hwr/recon/plate_fit.hpp"
#include "hwr/recon/prior_map.hpp"
#include "hwr/recon/relocalization_priors.hpp"
#include "hwr/recon/relocalization_worker.hpp"
#include "hwr/recon/segment_writer.hpp"
#include "hwr/recon/truth_weld_regions.hpp"
#include "operator_channel.hpp"
#include "hwr/detect/detector_factory.hpp"
#if HWR_WITH_SIM
#include "hwr/sim/run_writer.hpp"
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/sim_live_log.hpp"
#include "hwr/sim/sim_run_replay.hpp"
#endif

namespace {

using hwr::core::kNsPerS;
using hwr::estimation::TrackState;

// Scheduler task table: rate, time budget, priority (0 = highest).
constexpr hwr::core::TaskSpec kTasks[] = {
    {"hal", 200.0, 1'000'000, 0},      // poll the source into the rings
    {"inertial", 200.0, 500'000, 1},   // IMU filter propagation; magnetometer, GNSS
    {"camera", 30.0, 25'000'000, 2},   // visual tracking of every new frame
    {"mapping", 10.0, 60'000'000, 3},  // sliding-window bundle adjustment after a new keyframe
    {"telemetry", 1.0, 1'000'000, 9},  // status line
};
enum TaskIndex : size_t { kHal = 0, kInertial, kCamera, kMapping, kTelemetry, kTaskCount };

// --regions truth: a joint is "detected" when its box centre is this far in front of the camera (the
// fine cloud takes pixels up to 3.5 m, config/map.yaml), and the boxes are the plates' bounds + 5 cm.
constexpr double kTruthMinRangeM = 0.3, kTruthMaxRangeM = 4.0, kTruthBoxMarginM = 0.05;

// IMU samples newer than this stay queued so a frame still finds the samples around its time.
constexpr int64_t kImuHoldbackNs = 60'000'000;

struct Args {
  std::string source;
  double duration_s = 0;  // 0: the whole source
  bool realtime = false;
  bool quiet = false;
  std::string traj_out, timing_out, gt_out, faults, config, ba_export, map_out, cloud_out;
  std::string link, robot_id = "robot1";
  std::string prior_map;
  // "truth": the simulator's joints as detections; "geometry": the seam detector; "onnx:PATH",
  // "tensorrt:PATH": a learned detector (falls back to the seam detector when the model is unusable).
  std::string regions;
  std::string record;  // --record FILE: what the pipeline consumes, to an LCM log
  double link_wait_s = 30.0;
  bool use_imu = true, local_ba = true, full_ba = true;
};

void usage() {
  std::fprintf(
      stderr,
      "usage: hwr-robot --source KIND:WHAT [--config FILE] [--duration S] [--realtime] [--quiet]\n"
      "                 [--traj-out FILE] [--timing-out FILE] [--gt-out FILE] [--faults SPEC]\n"
      "                 [--no-imu] [--no-local-ba] [--no-full-ba] [--ba-export FILE]\n"
      "                 [--map-out DIR] [--cloud-out FILE] [--link URL [--robot-id ID] [--link-wait S]]\n"
      "                 [--prior-map DIR] [--regions truth|geometry|onnx:MODEL|tensorrt:ENGINE]\n"
      "                 [--record FILE]\n"
      "  KIND:WHAT  sim:NAME|FILE.yaml (the simulator renders live), sim:DIR (a run written by hwr-sim),\n"
      "             tum:DIR (TUM RGB-D folder), euroc:DIR (EuRoC folder or mav0),\n"
      "             hw:CONFIG (the live sensors, config/hw.yaml; paced at real time; Ctrl-C ends the run;\n"
      "             docs/hardware.md), lcmlog:FILE (a run recorded with --record)\n"
      "  --config FILE      settings (YAML, sections estimation: and map:; config/estimation.yaml and\n"
      "                     config/map.yaml list them)\n"
      "  --traj-out FILE    camera poses T_world_cam at every tracked image time (TUM format)\n"
      "  --timing-out FILE  per-frame CSV, one column per pipeline stage (milliseconds)\n"
      "  --gt-out FILE      (sim sources) ground-truth T_world_cam at the image times (TUM format)\n"
      "  --faults SPEC      inject sensor faults, e.g. dropout=30:2,exposure=40:2.5,depth-nan=10:5:0.3\n"
      "  --ba-export FILE   the end-of-run full bundle adjustment problem, before it is solved (BAL\n"
      "                     text; hwr-bench ba --problem-file=FILE)\n"
      "  --map-out DIR      the map store: closed local maps (segments) with keyframes and junctions,\n"
      "                     written as they close (docs/reconstruction.md)\n"
      "  --cloud-out FILE   every segment's points in the world frame, at the end (binary CloudPoint\n"
      "                     array, 16 bytes per point; hwr-eval ae --cloud FILE)\n"
      "  --record FILE      record every IMU, magnetometer and GNSS sample and every frame (left\n"
      "                     colour, depth in mm, rectified right) the pipeline consumes to an LCM log\n"
      "                     (lcm-logplayer reads it; replay: --source lcmlog:FILE; docs/mapio.md);\n"
      "                     live sources drop what the disk cannot keep up with (counted), replays wait\n"
      "  --link URL         stream the map to the ground station (hwr-ground) over LCM, e.g.\n"
      "                     udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608 (docs/mapio.md)\n"
      "  --robot-id ID      this robot's name on the link ([A-Za-z0-9_-], default robot1)\n"
      "  --link-wait S      at the end, wait up to S seconds for the ground station's acks (default 30)\n"
      "  --prior-map DIR    an earlier run's map store (--map-out of that run): relocalize against it while\n"
      "                     moving, then express poses, segments and the streamed map in its frame\n"
      "                     (docs/relocalization.md)\n"
      "  --regions truth    (sim sources) the simulator's weld joints, seen from each keyframe's true pose,\n"
      "                     as welding-region detections: the map keeps a fine cloud inside them, placed\n"
      "                     with the keyframe's estimated pose (a perfect detector; docs/reconstruction.md)\n"
      "  --regions geometry the geometric seam detector (detect/, any source with depth):\n"
      "                     fillet and butt joints found on each keyframe's depth and colour images,\n"
      "                     placed with its estimated pose (docs/detection.md)\n"
      "  --regions onnx:MODEL      a learned detector (ONNX through OpenCV DNN: YOLOv10 [1,N,6] or\n"
      "  --regions tensorrt:ENGINE [1,4+C,N] heads; TensorRT when built with it); a missing, corrupt or\n"
      "                     incompatible model is said and the geometric seam detector is used instead\n"
      "  With a detector, the welding regions are a list the operator corrects from the ground station\n"
      "  (confirm, reject, move, add over --link), kept in --map-out DIR/detections.yaml and read back\n"
      "  from --prior-map DIR on the next visit (docs/detection.md)\n");
}

// Replay paced at sensor rate: the timeline is the source's time, advancing with CLOCK_MONOTONIC.
class PacedClock final : public hwr::core::Clock {
 public:
  explicit PacedClock(int64_t source_t0_ns) : t0_(source_t0_ns), mono0_(mono_.now_ns()) {}
  int64_t now_ns() const override { return t0_ + (mono_.now_ns() - mono0_); }
  void sleep_until_ns(int64_t t_ns) override { mono_.sleep_until_ns(mono0_ + (t_ns - t0_)); }

 private:
  hwr::core::MonotonicClock mono_;
  int64_t t0_, mono0_;
};

struct Robot {
  hwr::hal::SensorStreams* streams = nullptr;
  hwr::hal::SensorSource* source = nullptr;
  hwr::core::Scheduler* scheduler = nullptr;
  hwr::estimation::PoseEstimator* estimator = nullptr;
  hwr::recon::LocalMapper* mapper = nullptr;
  hwr::recon::SegmentSink* segments = nullptr;
  hwr::recon::SegmentSink* segments_updated = nullptr;  // updated prior segments (--map-out), as they are
  hwr::mapio::MapStreamer* streamer = nullptr;          // --link: map chunks and telemetry
  hwr::mapio::SensorRecorder* recorder = nullptr;       // --record: every sample and frame consumed
  hwr::recon::RelocalizationWorker* reloc = nullptr;    // --prior-map
  // --prior-map: the magnetometer and GNSS priors of the queries (relocalization_priors.hpp), fed
  // with the newest tracked camera pose (at most a frame older than the sample).
  hwr::recon::CurrentSensorPriors* sensor_priors = nullptr;
  const hwr::recon::PriorSensorFrames* prior_frames = nullptr;
  Eigen::Isometry3d T_cam_imu = Eigen::Isometry3d::Identity();
  Eigen::Vector3d antenna_imu_m = Eigen::Vector3d::Zero();
  Eigen::Isometry3d T_world_cam_last = Eigen::Isometry3d::Identity();
  bool pose_valid = false;
  std::string last_priors;  // what the last query's priors held (fill()'s line)
  // The frame every output is expressed in: the run's world until relocalized, then the prior's
  // (T_out_world = T_prior_world).
  Eigen::Isometry3d T_out_world = Eigen::Isometry3d::Identity();
  bool in_prior_frame = false;
  double moved_m = 0;  // path of the newest keyframes so far
  int last_keyframe = -1;
  Eigen::Vector3d last_keyframe_p = Eigen::Vector3d::Zero();
  int update_offered_upto = -1;  // newest keyframe offered to the map update
  // --regions truth: the joints' boxes and the true camera poses (time-sorted) the detections come from.
  const std::vector<hwr::recon::TruthJointBox>* truth_joints = nullptr;
  const std::vector<hwr::core::StampedPose>* truth_T_world_cam = nullptr;
  int detected_upto = -1;                          // newest keyframe looked at
  std::vector<hwr::recon::WeldRegion> detections;  // scratch (sized for every joint at start-up)
  // --regions geometry: the detector and its output list (sized at start-up).
  hwr::detect::Detector* detector = nullptr;
  hwr::detect::DetectionList* detected = nullptr;
  // The operator channel (with a detector): the detection list, operator commands (operator_channel.hpp).
  hwr::robot::OperatorChannel* operator_channel = nullptr;
  uint64_t detect_errors = 0;
  uint64_t region_detections = 0;
  uint64_t updated_segments = 0, updated_points_deleted = 0;
  uint64_t updated_stream_refused = 0;  // updated segment versions the link refused a piece of
  // Updated prior segments on their way to the link, oldest first (stream_updated_segments); sized
  // for two per prior segment at start-up (one going out, its newest version waiting behind it).
  struct UpdateToStream {
    hwr::recon::UpdatedSegment update;
    int sent = 0;  // points already taken by the link
  };
  std::vector<UpdateToStream> updates_to_stream;
  uint64_t updated_stream_wait_ticks = 0;  // mapping ticks that left a version (or its rest) waiting
  uint64_t updated_stream_superseded = 0;  // versions replaced by a newer one before they went out
  hwr::hal::StreamMonitor imu{200.0};
  hwr::hal::StreamMonitor camera{30.0};
  uint64_t mag = 0, gnss = 0, gnss_3d = 0;
  int64_t last_frame_ms_x100 = 0;
  hwr::core::Status error;
  bool quiet = false;
};

// SIGINT / SIGTERM: the hal task stops the scheduler and the run ends as a replay's end does (the
// last keyframes are mapped, stores and the detection list written, the link drained).
std::atomic<bool> g_stop_requested{false};
void on_stop_signal(int) { g_stop_requested.store(true); }

void hal_task(void* ctx, int64_t now_ns) {
  auto* r = static_cast<Robot*>(ctx);
  if (!r->error.ok()) return;
  r->error = r->source->poll(now_ns, r->streams);
  if (!r->error.ok() || r->source->finished() || g_stop_requested.load()) r->scheduler->request_stop();
}

void inertial_task(void* ctx, int64_t now_ns) {
  auto* r = static_cast<Robot*>(ctx);
  hwr::hal::ImuSample s;
  while (r->streams->imu.try_pop(s)) {
    if (r->recorder != nullptr) r->recorder->record_imu(s);
    if (r->imu.check(s)) r->estimator->add_imu(s);
  }
  r->estimator->advance_imu(now_ns - kImuHoldbackNs);
  hwr::hal::MagSample m;
  while (r->streams->mag.try_pop(m)) {
    if (r->recorder != nullptr) r->recorder->record_mag(m);
    ++r->mag;
    r->estimator->add_mag(m);
    r->mapper->add_mag(m);  // keyframe metadata for relocalization
    if (r->sensor_priors != nullptr && r->pose_valid) {
      r->sensor_priors->add_mag(m, (r->T_world_cam_last * r->T_cam_imu).linear());
    }
  }
  hwr::hal::GnssFix g;
  while (r->streams->gnss.try_pop(g)) {
    if (r->recorder != nullptr) r->recorder->record_gnss(g);
    ++r->gnss;
    if (g.has_3d_fix()) ++r->gnss_3d;
    r->mapper->add_gnss(g);
    if (r->sensor_priors != nullptr && r->pose_valid) {
      r->sensor_priors->add_gnss(g, r->T_world_cam_last * r->T_cam_imu * r->antenna_imu_m);
    }
  }
}

void camera_task(void* ctx, int64_t) {
  auto* r = static_cast<Robot*>(ctx);
  hwr::hal::RgbdFrame* f = nullptr;
  while (r->streams->frames.try_pop(f)) {
    if (r->recorder != nullptr) r->recorder->record_frame(*f);
    r->camera.check(*f);
    const hwr::estimation::TrackResult& tr = r->estimator->process_frame(*f);
    r->pose_valid = tr.state == hwr::estimation::TrackState::kTracking ||
                    tr.state == hwr::estimation::TrackState::kRecovered;
    if (r->pose_valid) r->T_world_cam_last = tr.T_world_cam;
    if (r->streamer != nullptr) {
      r->streamer->post_pose(f->t_ns, r->T_out_world * tr.T_world_cam,
                             tr.state == hwr::estimation::TrackState::kTracking ||
                                 tr.state == hwr::estimation::TrackState::kRecovered);
    }
    r->streams->frame_pool.release(f);
  }
}

// --prior-map: offer the newest keyframe and the local map around it to the relocalization worker
// (it takes one when idle and the robot has moved enough since its last attempt), and switch the
// outputs to the prior's frame once it has localized. Never waits for the worker.
void relocalization_step(Robot* r) {
  if (r->reloc->localized() && !r->in_prior_frame) {
    r->T_out_world = r->reloc->T_prior_world();
    r->in_prior_frame = true;
  }
  const hwr::estimation::KeyframeStore& kfs = r->estimator->tracker().keyframes();
  const int newest = kfs.newest_id();
  if (newest < 0 || newest == r->last_keyframe) return;
  const hwr::estimation::Keyframe* kf = kfs.get(newest);
  if (kf == nullptr) return;
  const Eigen::Vector3d p = kf->T_world_cam.translation();
  if (r->last_keyframe >= 0) r->moved_m += (p - r->last_keyframe_p).norm();
  r->last_keyframe = newest;
  r->last_keyframe_p = p;
  if (r->in_prior_frame) {
    // Map update: the keyframes the mapper has settled (keyframe_lag behind the newest), once each.
    const int settled = newest - r->mapper->config().keyframe_lag;
    if (r->update_offered_upto < 0) r->update_offered_upto = settled - 1;
    for (int id = r->update_offered_upto + 1; id <= settled; ++id) {
      const hwr::estimation::Keyframe* k = kfs.get(id);
      const cv::Mat* bgr = kfs.bgr(id);
      const cv::Mat* depth = kfs.depth_m(id);
      if (k != nullptr && bgr != nullptr && depth != nullptr)
        r->reloc->offer_keyframe(*bgr, *depth, k->T_world_cam);
    }
    r->update_offered_upto = std::max(r->update_offered_upto, settled);
    return;
  }
  if (!r->reloc->wants_query(r->moved_m)) return;
  // The priors, twice a metre of motion at most, until localized. Not allocation-free: fill() fits
  // the current run's GNSS track (up to gnss_capacity fixes) and computes its heading (a few ms), and
  // returns a line of text.
  hwr::recon::RelocalizationQuery q;
  r->last_priors = r->sensor_priors->fill(*r->prior_frames, kf->T_world_cam, &q);
  hwr::recon::RelocalizationPriors priors;
  priors.position = q.position;
  priors.yaw_valid = q.yaw_valid;
  priors.yaw_prior_rad = q.yaw_prior_rad;
  priors.yaw_sigma_rad = q.yaw_sigma_rad;
  r->reloc->offer(kf->features, kf->T_world_cam, r->mapper->active_map(), r->mapper->active_T_world_segment(),
                  r->moved_m, priors);
}

// Updated prior segments to the ground station, oldest first, in the streamer's slot-sized pieces,
// each only when a slot is free for it (MapStreamer::submit_while_free): the map's own batches keep
// the slots busy while the ground station acknowledges, and a refused piece would be a hole in that
// version. What the link cannot take yet waits for a later mapping tick. wait_s > 0 (the end of the
// run): waits up to wait_s in all for slots, then submits the rest all the same (a version with a
// refused piece is counted and fails the run's exit code, as for the map's own batches).
void stream_updated_segments(Robot* r, double wait_s) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(wait_s);
  size_t done = 0;
  for (auto& w : r->updates_to_stream) {
    const hwr::recon::UpdatedSegment& u = w.update;
    const auto* pts = reinterpret_cast<const hwr::mapio::ChunkPoint*>(u.record.points_segment.data());
    const int n = static_cast<int>(u.record.points_segment.size());
    const auto segment_id = static_cast<int32_t>(u.record.segment_id);
    bool whole = r->streamer->submit_while_free(segment_id, u.version, u.record.T_world_segment, pts, n, true,
                                                &w.sent);
    while (!whole && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
      whole = r->streamer->submit_while_free(segment_id, u.version, u.record.T_world_segment, pts, n, true,
                                             &w.sent);
    }
    if (!whole && wait_s <= 0) break;  // in order: the rest waits behind this one
    if (!whole && !r->streamer->submit(segment_id, u.version, u.record.T_world_segment, pts + w.sent, nullptr,
                                       n - w.sent, true, 0.0)) {
      ++r->updated_stream_refused;  // the completion is still owed (map_streamer.hpp)
    }
    ++done;
  }
  if (done < r->updates_to_stream.size()) ++r->updated_stream_wait_ticks;
  r->updates_to_stream.erase(r->updates_to_stream.begin(),
                             r->updates_to_stream.begin() + static_cast<ptrdiff_t>(done));
}

// Prior segments the map update changed: every version towards the ground station as it is made
// (stream_updated_segments), the latest one (end of run) into the map store. A version not yet begun
// is replaced by a newer one of the same segment; one partly sent is finished first.
void take_updated_segments(Robot* r, double stream_wait_s) {
  hwr::recon::UpdatedSegment u;
  while (r->reloc->take_updated(&u)) {
    if (u.final) {
      // The latest version, at the end of the run: the one the map store keeps.
      ++r->updated_segments;
      r->updated_points_deleted += static_cast<uint64_t>(u.points_deleted);
      if (r->segments_updated != nullptr) r->segments_updated->take(std::move(u.record));
      continue;
    }
    if (r->streamer == nullptr) continue;
    auto waiting = std::find_if(r->updates_to_stream.begin(), r->updates_to_stream.end(),
                                [&u](const Robot::UpdateToStream& w) {
                                  return w.sent == 0 && w.update.record.segment_id == u.record.segment_id;
                                });
    if (waiting != r->updates_to_stream.end()) {
      waiting->update = std::move(u);
      ++r->updated_stream_superseded;
    } else {
      r->updates_to_stream.push_back(Robot::UpdateToStream{std::move(u), 0});
    }
  }
  if (r->streamer != nullptr && !r->updates_to_stream.empty()) stream_updated_segments(r, stream_wait_s);
}

// --regions truth: each new keyframe "detects" the joints its true pose sees; the mapper places them
// with the keyframe's estimated pose (recon/truth_weld_regions.hpp). Before the keyframes are fused.
void detect_truth_regions(Robot* r) {
  const hwr::estimation::KeyframeStore& kfs = r->estimator->tracker().keyframes();
  if (kfs.empty()) return;
  for (int id = std::max(r->detected_upto + 1, kfs.oldest_id()); id <= kfs.newest_id(); ++id) {
    const hwr::estimation::Keyframe* kf = kfs.get(id);
    Eigen::Isometry3d T_world_cam_true;
    if (kf == nullptr ||
        !hwr::recon::truth_pose_at(*r->truth_T_world_cam, kf->t_ns, 50'000'000, &T_world_cam_true))
      continue;
    hwr::recon::truth_detections(*r->truth_joints, T_world_cam_true, r->source->info().intrinsics,
                                 kTruthMinRangeM, kTruthMaxRangeM, id, kf->t_ns, &r->detections);
    for (const hwr::recon::WeldRegion& d : r->detections) {
      r->mapper->add_weld_region(d, kf->T_world_cam);
      ++r->region_detections;
    }
  }
  r->detected_upto = std::max(r->detected_upto, kfs.newest_id());
}

// "onnx:PATH" / "tensorrt:PATH" -> PATH.
std::string choice_model_path(const std::string& regions) { return regions.substr(regions.find(':') + 1); }

// --regions geometry|onnx:|tensorrt:: each new keyframe whose images are still in the store goes
// through the detector; its regions are placed with the keyframe's estimated pose. Before the
// keyframes are fused.
void detect_regions(Robot* r) {
  const hwr::estimation::KeyframeStore& kfs = r->estimator->tracker().keyframes();
  if (kfs.empty()) return;
  for (int id = std::max(r->detected_upto + 1, kfs.oldest_id()); id <= kfs.newest_id(); ++id) {
    const hwr::estimation::Keyframe* kf = kfs.get(id);
    const cv::Mat* depth = kfs.depth_m(id);
    if (kf == nullptr || depth == nullptr || depth->empty()) continue;
    hwr::detect::KeyframeView view;
    view.keyframe_id = id;
    view.t_ns = kf->t_ns;
    view.K = r->source->info().intrinsics;
    view.bgr = kfs.bgr(id);
    view.depth_m = depth;
    view.T_world_cam = kf->T_world_cam;
    const hwr::core::Status s = r->detector->detect(view, r->detected);
    if (!s.ok()) {
      if (r->detect_errors++ == 0)
        HWR_LOG_WARN("robot", "detector: keyframe %d: %s", id, s.message().c_str());
      continue;
    }
    for (int i = 0; i < r->detected->size(); ++i) {
      const hwr::detect::Detection& d = (*r->detected)[i];
      if (r->operator_channel != nullptr &&
          r->operator_channel->suppress(kf->T_world_cam * d.T_cam_box, d.half_size_m))
        continue;  // on a region the operator rejected
      if (r->operator_channel != nullptr) r->operator_channel->add_detection(d);
      if (d.support_only) continue;  // only supports a seam a confident detection finds (seam_fusion.hpp)
      r->mapper->add_weld_region(hwr::recon::weld_region_from_detection(d), kf->T_world_cam);
      ++r->region_detections;
    }
  }
  r->detected_upto = std::max(r->detected_upto, kfs.newest_id());
}

void mapping_task(void* ctx, int64_t now_ns) {
  auto* r = static_cast<Robot*>(ctx);
  if (r->truth_joints != nullptr) detect_truth_regions(r);
  if (r->detector != nullptr) detect_regions(r);
  if (r->operator_channel != nullptr) {
    // Before relocalizing against a prior map, this run does not know the frame of the prior's list.
    const bool map_frame_known = r->reloc == nullptr || r->in_prior_frame;
    r->operator_channel->step(&r->mapper->fine_map_for_operator(), r->estimator->tracker().keyframes(),
                              r->T_out_world, map_frame_known, now_ns);
  }
  if (r->estimator->local_ba_due()) {
    auto report = r->estimator->run_local_ba();
    if (!report.ok()) HWR_LOG_WARN("robot", "local bundle adjustment: %s", report.status().message().c_str());
  }
  // Keyframes settled by the sliding window go into the active local map (docs/reconstruction.md).
  r->mapper->update(r->estimator->tracker().keyframes(), r->segments);
  if (r->reloc != nullptr) {
    relocalization_step(r);
    take_updated_segments(r, 0.0);  // the mapping task never waits for the link
  }
}

// HWR_STATUS for the ground station: per-task scheduler counters and the stream/estimation counters.
void post_status(Robot* r, int64_t now_ns, const hwr::core::TaskTelemetry* t,
                 const hwr::hal::SourceCounters& c) {
  hwr_lcm::status_t s;
  s.t_ns = now_ns;
  s.num_tasks = static_cast<int32_t>(kTaskCount);
  for (size_t i = 0; i < kTaskCount; ++i) {
    s.task_name.emplace_back(t[i].name != nullptr ? t[i].name : "");
    s.task_runs.push_back(static_cast<int64_t>(t[i].runs));
    s.task_overruns.push_back(static_cast<int64_t>(t[i].overruns));
    s.task_slips.push_back(static_cast<int64_t>(t[i].slips));
  }
  const auto e = r->estimator->counters();
  const hwr::mapio::MapStreamerStats ls = r->streamer->stats();
  const std::pair<const char*, int64_t> counters[] = {
      {"camera.frames", static_cast<int64_t>(c.frames)},
      {"camera.dropped", static_cast<int64_t>(c.frames_dropped)},
      {"camera.gaps", static_cast<int64_t>(r->camera.health().gaps)},
      {"imu.dropped", static_cast<int64_t>(r->streams->imu.dropped())},
      {"tracker.keyframes", static_cast<int64_t>(e.tracker.keyframes)},
      {"tracker.lost", static_cast<int64_t>(e.tracker.lost)},
      {"link.chunks", ls.chunks},
      {"link.resends", ls.resends},
      {"link.batches_refused", ls.batches_refused},
      {"link.completions_owed", ls.completions_owed},
      {"link.completions_lost", ls.completions_lost},
  };
  for (const auto& [name, value] : counters) {
    s.counter_name.emplace_back(name);
    s.counter_value.push_back(value);
  }
  s.num_counters = static_cast<int32_t>(s.counter_name.size());
  r->streamer->post_status(s);
}

void telemetry_task(void* ctx, int64_t now_ns) {
  auto* r = static_cast<Robot*>(ctx);
  const hwr::hal::SourceCounters c = r->source->counters();
  hwr::core::TaskTelemetry t[kTaskCount];
  r->scheduler->snapshot(t, kTaskCount);
  if (r->streamer != nullptr) post_status(r, now_ns, t, c);
  if (r->quiet) return;
  uint64_t overruns = 0;
  for (const auto& x : t) overruns += x.overruns;
  const auto e = r->estimator->counters();
  const auto& timings = r->estimator->timings();
  double ms = 0;
  const size_t n = std::min<size_t>(timings.size(), 30);
  for (size_t i = timings.size() - n; i < timings.size(); ++i) ms += timings[i].total_ns * 1e-6;
  std::fprintf(stderr,
               "\rhwr-robot t=%7.1fs frames=%" PRIu64 " %s kf=%" PRIu64 " pts=%d lost=%" PRIu64
               " frame=%.1fms dropped=%" PRIu64 " overruns=%" PRIu64 "   ",
               hwr::core::ns_to_s(now_ns - r->scheduler->start_ns()), c.frames,
               e.visual_only ? (e.tracker.frames ? "visual-only" : "waiting")
                             : (e.imu_initialized ? "visual-inertial" : "imu-init"),
               e.tracker.keyframes, r->estimator->tracker().points().alive(), e.tracker.lost,
               n ? ms / n : 0.0, c.frames_dropped + r->streams->imu.dropped(), overruns);
  if (!isatty(STDERR_FILENO)) std::fputc('\n', stderr);
}

// Where closed segments go: the map store's writer thread (--map-out), the world-frame cloud
// (--cloud-out), and a one-line summary per junction for the end-of-run report.
// With --prior-map, segment ids continue after the prior's (id_offset), so the two runs' segments
// can live in one store, and segments are expressed in the prior's frame: those that close before
// the robot has relocalized are held (at most max_held; a run that has not relocalized by then
// gives up holding and writes in its own frame, said at the end) and released in the prior frame
// once it has.
class RobotSegmentSink final : public hwr::recon::SegmentSink {
 public:
  hwr::recon::StoreSegmentWriter* writer = nullptr;
  bool keep_world_cloud = false;
  std::vector<hwr::recon::CloudPoint> cloud_world;  // in the output frame
  std::vector<std::string> junction_lines;
  uint64_t segments = 0, points = 0;
  const Robot* robot = nullptr;  // T_out_world, in_prior_frame
  bool hold_until_localized = false;
  size_t max_held = 8;
  uint32_t id_offset = 0;
  bool gave_up_holding = false;
  uint64_t written_in_run_frame = 0;  // segments not in the prior frame (not relocalized in time)

  void take(hwr::recon::SegmentRecord&& seg) override {
    seg.segment_id += id_offset;
    if (hold_until_localized && !robot->in_prior_frame && !gave_up_holding) {
      held_.push_back(std::move(seg));
      if (held_.size() > max_held) {
        gave_up_holding = true;
        HWR_LOG_WARN("robot",
                     "--prior-map: not relocalized after %zu segments; they are written in this run's frame",
                     held_.size());
        release_held();
      }
      return;
    }
    release_held();
    emit(std::move(seg));
  }
  // Held segments go out in the output frame of now (the prior's, once relocalized).
  void release_held() {
    for (auto& h : held_) emit(std::move(h));
    held_.clear();
  }

 private:
  std::vector<hwr::recon::SegmentRecord> held_;

  void emit(hwr::recon::SegmentRecord&& seg) {
    if (robot != nullptr && robot->in_prior_frame) {
      const Eigen::Isometry3d& T = robot->T_out_world;
      seg.T_world_segment = T * seg.T_world_segment;
      for (auto& kf : seg.keyframes) kf.T_world_cam = T * kf.T_world_cam;
    } else if (hold_until_localized) {
      ++written_in_run_frame;
    }
    ++segments;
    points += seg.points_segment.size();
    if (seg.segment_id > 0) {
      const hwr::recon::JunctionRecord& j = seg.junction;
      const Eigen::Isometry3d d = j.T_prev_segment_segment_odometry.inverse() * j.T_prev_segment_segment;
      char line[256];
      std::snprintf(
          line, sizeof(line),
          "junction %u: keyframes %d -> %d, orb %d matches %d inliers, ndt %s (%d it, fitness %.3f), "
          "correction to odometry %.1f mm %.3f deg",
          seg.segment_id, j.keyframe_before, j.keyframe_after, j.orb_matches, j.orb_inliers,
          j.ndt_converged ? "converged" : "not converged", j.ndt_iterations, j.ndt_fitness,
          d.translation().norm() * 1e3, Eigen::AngleAxisd(d.linear()).angle() * 180.0 / M_PI);
      junction_lines.emplace_back(line);
    }
    if (keep_world_cloud) {
      const Eigen::Isometry3f T = seg.T_world_segment.cast<float>();
      for (const auto& p : seg.points_segment) {
        hwr::recon::CloudPoint q = p;
        const Eigen::Vector3f w = T * Eigen::Vector3f(p.x_m, p.y_m, p.z_m);
        q.x_m = w.x();
        q.y_m = w.y();
        q.z_m = w.z();
        cloud_world.push_back(q);
      }
    }
    if (writer != nullptr) writer->take(std::move(seg));
  }
};

// The active local map's voxels, streamed as the map fills (in the output frame: the prior's
// once relocalized; ids after the prior's with --prior-map) (recon::MapStreamSink -> mapio).
// CloudPoint and ChunkPoint share one 16-byte layout. In replay (simulated clock, faster than real
// time) the mapping task waits for a free batch slot rather than drop map data to its own speed; but
// once a wait times out (no ground station acknowledging) it stops waiting until acks come again, so
// a missing ground station cannot stall the pipeline. With --realtime it never waits. A refused
// batch is lost to the link (the map store, --map-out, still has it) and fails the run's exit code.
static_assert(sizeof(hwr::recon::CloudPoint) == sizeof(hwr::mapio::ChunkPoint) &&
                  offsetof(hwr::recon::CloudPoint, r) == offsetof(hwr::mapio::ChunkPoint, r),
              "CloudPoint and ChunkPoint must share their layout");
class LinkStreamSink final : public hwr::recon::MapStreamSink {
 public:
  LinkStreamSink(hwr::mapio::MapStreamer* streamer, double wait_s, const Robot* robot, uint32_t id_offset)
      : streamer_(streamer), wait_s_(wait_s), robot_(robot), id_offset_(id_offset) {}
  void stream(uint32_t segment_id, const Eigen::Isometry3d& T_world_segment,
              const hwr::recon::CloudPoint* points_segment, const uint32_t* voxel_ids, int n,
              bool segment_complete) override {
    const int64_t last_ack = streamer_->stats().last_ack_ns;
    if (stalled_ && last_ack != stalled_at_ack_) stalled_ = false;  // the ground station answers again
    const bool ok = streamer_->submit(static_cast<int32_t>(segment_id + id_offset_), 0,
                                      robot_->T_out_world * T_world_segment,
                                      reinterpret_cast<const hwr::mapio::ChunkPoint*>(points_segment),
                                      voxel_ids, n, segment_complete, stalled_ ? 0.0 : wait_s_);
    if (!ok && !stalled_ && wait_s_ > 0) {
      stalled_ = true;
      stalled_at_ack_ = last_ack;
      if (!warned_) {
        std::fprintf(
            stderr,
            "hwr-robot: --link: no batch slot freed in %.0f s: is hwr-ground running on the same URL? "
            "Map batches are dropped from the link until it acknowledges again\n",
            wait_s_);
        warned_ = true;
      }
    }
  }

 private:
  hwr::mapio::MapStreamer* streamer_;
  double wait_s_;
  const Robot* robot_;
  uint32_t id_offset_;
  bool stalled_ = false, warned_ = false;
  int64_t stalled_at_ack_ = 0;
};

std::string utc_run_id() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y%m%dT%H%M%SZ", &tm);
  return buf;
}

struct OpenedSource {
  hwr::hal::ReplayLog log;
  std::vector<hwr::core::StampedPose> gt_at_frames;  // sim live only
  // Sim sources: the weld work pieces (world frame) and the true T_world_cam, time-sorted (at the
  // frames for a live run, at the IMU rate from groundtruth.txt for a run folder).
  bool has_weld_truth = false;
  hwr::recon::WeldGroundTruth weld_truth;
  std::vector<hwr::core::StampedPose> truth_T_world_cam;
};

hwr::core::Expected<OpenedSource> open_source(const std::string& spec) {
  OpenedSource out;
  if (spec.rfind("sim:", 0) == 0) {
#if HWR_WITH_SIM
    const std::string what = spec.substr(4);
    if (std::filesystem::is_directory(what)) {
      auto run = hwr::sim::open_sim_run_log(what);
      if (!run.ok()) return run.status();
      out.log = std::move(run->log);
      // The truth files hwr-sim writes beside the images (absent: --regions truth says so).
      auto weld = hwr::recon::read_weld_groundtruth(what + "/weld_groundtruth.yaml");
      auto traj = hwr::core::read_tum_trajectory(what + "/groundtruth.txt");
      if (weld.ok() && traj.ok()) {
        out.has_weld_truth = true;
        out.weld_truth = std::move(weld.value());
        out.truth_T_world_cam = std::move(traj.value());
      }
      return out;
    }
    auto scenario = hwr::sim::load_scenario(what);
    if (!scenario.ok()) return scenario.status();
    auto live = hwr::sim::open_sim_live_log(scenario.value());
    if (!live.ok()) return live.status();
    out.log = std::move(live->log);
    out.gt_at_frames = std::move(live->groundtruth_T_world_cam_at_frames);
    auto weld = hwr::recon::parse_weld_groundtruth(
        hwr::sim::weld_groundtruth_yaml(scenario.value(), live->calibration.T_scene_world.inverse()),
        scenario->name + " weld ground truth");
    if (!weld.ok()) return weld.status();
    out.has_weld_truth = true;
    out.weld_truth = std::move(weld.value());
    out.truth_T_world_cam = out.gt_at_frames;
    return out;
#else
    return hwr::core::Unavailable("this build has no simulator support (HWR_WITH_SIM=OFF)");
#endif
  }
  if (spec.rfind("lcmlog:", 0) == 0) {
    hwr::mapio::RecordingLogStats stats;
    auto rec = hwr::mapio::open_recording_log(spec.substr(7), &stats);
    if (!rec.ok()) return rec.status();
    if (stats.undecodable + stats.bad_images + stats.incomplete_frames + stats.resyncs > 0) {
      std::fprintf(stderr,
                   "hwr-robot: %s: damaged recording: skipped %" PRIu64 " undecodable events, %" PRIu64
                   " bad images, %" PRIu64 " incomplete frames, %" PRIu64 " damaged event headers\n",
                   spec.c_str(), stats.undecodable, stats.bad_images, stats.incomplete_frames, stats.resyncs);
    }
    out.log = std::move(rec.value());
    return out;
  }
  auto log = hwr::hal::open_dataset_log(spec);
  if (!log.ok()) return log.status();
  out.log = std::move(log.value());
  return out;
}

hwr::core::Status write_timings(const std::string& path,
                                const std::vector<hwr::estimation::FrameTiming>& rows) {
  std::string csv =
      "t_s,imu_ms,extract_ms,match_ms,pose_ms,keyframe_ms,total_ms,local_ba_ms,features,matches,inliers,"
      "state,keyframe\n";
  char line[256];
  for (const auto& r : rows) {
    std::snprintf(line, sizeof(line), "%.6f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%d,%d,%d,%s,%d\n",
                  hwr::core::ns_to_s(r.t_ns), r.imu_ns * 1e-6, r.track.extract_ns * 1e-6,
                  r.track.match_ns * 1e-6, r.track.pose_ns * 1e-6, r.track.keyframe_ns * 1e-6,
                  r.total_ns * 1e-6, r.local_ba_ns * 1e-6, r.features, r.matches, r.inliers,
                  hwr::estimation::track_state_name(r.state), r.keyframe ? 1 : 0);
    csv += line;
  }
  return hwr::core::write_file_atomic(path, csv);
}

// DIR/relocalization.yaml of a --prior-map run: where this run's frame sits in the prior's.
hwr::core::Status write_relocalization_yaml(const std::string& map_dir, const std::string& prior_dir,
                                            const std::string& prior_run_id, uint32_t first_segment_id,
                                            const hwr::recon::RelocalizationWorkerStatus& rs) {
  std::string y;
  char line[512];
  std::snprintf(line, sizeof(line),
                "# hwr-robot --prior-map: this run's world frame in the prior run's (T_prior_world maps this "
                "run's world coordinates into the prior's)\nprior_map: \"%s\"\nprior_run_id: \"%s\"\n"
                "first_segment_id: %u\nlocalized: %s\nattempts: %d\nrelocalization_s: %.4f\n",
                prior_dir.c_str(), prior_run_id.c_str(), first_segment_id, rs.localized ? "true" : "false",
                rs.attempts, rs.wall_s_total);
  y += line;
  if (rs.localized) {
    const Eigen::Quaterniond q(rs.T_prior_world.linear());
    const Eigen::Vector3d t = rs.T_prior_world.translation();
    std::snprintf(line, sizeof(line),
                  "moved_at_localization_m: %.4f\nT_prior_world:\n  t_m: [%.6f, %.6f, %.6f]\n"
                  "  q_xyzw: [%.9f, %.9f, %.9f, %.9f]\n",
                  rs.moved_at_localization_m, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
    y += line;
  }
  // Each attempt (the worker keeps the first max_attempts_logged): where, how long, what it said, with
  // which priors, and whether its pose was held for a later attempt to confirm.
  y += rs.log.empty() ? "attempt_log: []\n" : "attempt_log:\n";
  for (const hwr::recon::RelocalizationAttempt& a : rs.log) {
    std::snprintf(line, sizeof(line),
                  "  - {moved_m: %.3f, wall_s: %.4f, result: \"%s\", position_prior: %s, yaw_prior: %s, "
                  "local_points: %d, pending_confirmation: %s}\n",
                  a.moved_m, a.wall_s, hwr::recon::relocalization_reason_name(a.reason),
                  a.position_prior ? "true" : "false", a.yaw_prior ? "true" : "false", a.local_points,
                  a.pending_confirmation ? "true" : "false");
    y += line;
  }
  if (rs.localized) {
    const hwr::recon::PriorMapUpdaterCounters& u = rs.update;
    std::snprintf(
        line, sizeof(line),
        "map_update:\n  keyframes: %llu\n  keyframes_dropped: %llu\n  carving_views: %llu\n"
        "  views_failed_pose_check: %llu\n  segments_updated: %llu\n  points_deleted: %lld\n",
        static_cast<unsigned long long>(u.keyframes), static_cast<unsigned long long>(rs.keyframes_dropped),
        static_cast<unsigned long long>(u.frames_carved + u.frames_misaligned),
        static_cast<unsigned long long>(u.frames_misaligned),
        static_cast<unsigned long long>(u.segments_updated), static_cast<long long>(u.points_deleted));
    y += line;
  }
  return hwr::core::write_file_atomic(map_dir + "/relocalization.yaml", y);
}

int run(Args args) {
  // hw:CONFIG: the live sensors (hal/hw, docs/hardware.md). Their timeline is CLOCK_MONOTONIC, so the
  // scheduler runs paced (as with --realtime) from now.
  const bool live = args.source.rfind("hw:", 0) == 0;
  if (live) args.realtime = true;
  auto opened = live ? hwr::core::Expected<OpenedSource>(OpenedSource{}) : open_source(args.source);
  if (!opened.ok()) {
    std::fprintf(stderr, "hwr-robot: %s\n", opened.status().message().c_str());
    return 1;
  }
  hwr::hal::ReplayLog log = std::move(opened->log);
  std::shared_ptr<hwr::hal::FaultReport> fault_report;
  std::unique_ptr<hwr::hal::hw::HwSource> hw;
  if (live) {
    if (!args.faults.empty()) {
      std::fprintf(stderr, "hwr-robot: --faults applies to replayed sources, not to hw:\n");
      return 2;
    }
    auto hw_cfg = hwr::hal::hw::load_hw_config(args.source.substr(3));
    if (!hw_cfg.ok()) {
      std::fprintf(stderr, "hwr-robot: %s\n", hw_cfg.status().message().c_str());
      return 1;
    }
    auto opened_hw =
        hwr::hal::hw::HwSource::open(hw_cfg.value(), args.source, hwr::core::MonotonicClock().now_ns());
    if (!opened_hw.ok()) {
      std::fprintf(stderr, "hwr-robot: %s\n", opened_hw.status().message().c_str());
      return 1;
    }
    hw = std::move(opened_hw.value());
    log.info = hw->info();
  } else if (!args.faults.empty()) {
    auto spec = hwr::hal::parse_fault_spec(args.faults);
    if (!spec.ok()) {
      std::fprintf(stderr, "hwr-robot: --faults: %s\n", spec.status().message().c_str());
      return 2;
    }
    auto faulty = hwr::hal::apply_faults(std::move(log), spec.value(), &fault_report);
    if (!faulty.ok()) {
      std::fprintf(stderr, "hwr-robot: --faults: %s\n", faulty.status().message().c_str());
      return 1;
    }
    log = std::move(faulty.value());
  }
  const hwr::hal::SourceInfo info = log.info;
  if (!info.intrinsics.valid()) {
    std::fprintf(stderr, "hwr-robot: source %s has no camera intrinsics\n", info.name.c_str());
    return 1;
  }
  hwr::hal::SensorStreamsConfig cfg;
  cfg.width = info.intrinsics.width;
  cfg.height = info.intrinsics.height;
  cfg.stereo = info.stereo;
  hwr::hal::SensorStreams streams(cfg);
  std::unique_ptr<hwr::hal::SensorSource> source;
  if (live) {
    if (hwr::core::Status hs = hw->start(&streams); !hs.ok()) {
      std::fprintf(stderr, "hwr-robot: %s\n", hs.message().c_str());
      return 1;
    }
    source = std::move(hw);
  } else {
    auto replay = hwr::hal::ReplaySource::create(std::move(log), &streams);
    if (!replay.ok()) {
      std::fprintf(stderr, "hwr-robot: %s\n", replay.status().message().c_str());
      return 1;
    }
    source = std::move(replay.value());
  }
  std::unique_ptr<hwr::mapio::SensorRecorder> recorder;
  if (!args.record.empty()) {
    hwr::mapio::SensorRecorderConfig rec_cfg;
    rec_cfg.wait_when_full = !live;  // a replay's recording is complete; live sensors are never held up
    auto rec = hwr::mapio::SensorRecorder::open(args.record, info, rec_cfg);
    if (!rec.ok()) {
      std::fprintf(stderr, "hwr-robot: %s\n", rec.status().message().c_str());
      return 1;
    }
    recorder = std::move(rec.value());
  }
  std::signal(SIGINT, on_stop_signal);  // Ctrl-C / systemctl stop: end the run cleanly
  std::signal(SIGTERM, on_stop_signal);

  hwr::estimation::PoseEstimatorConfig est_cfg;
  hwr::recon::LocalMapperConfig map_cfg;
  if (!args.config.empty()) {
    auto doc = hwr::core::ConfigDocument::load_file(args.config);
    hwr::core::Status cs = doc.status();
    if (doc.ok()) {
      hwr::estimation::read_estimator_config(doc->root().child("estimation"), &est_cfg);
      hwr::recon::read_local_mapper_config(doc->root().child("map"), &map_cfg);
      cs = doc->finish();
    }
    if (!cs.ok()) {
      std::fprintf(stderr, "hwr-robot: --config: %s\n", cs.message().c_str());
      return 2;
    }
  }
  est_cfg.use_imu = est_cfg.use_imu && args.use_imu;
  est_cfg.local_ba_enabled = est_cfg.local_ba_enabled && args.local_ba;
  est_cfg.full_ba_at_end = est_cfg.full_ba_at_end && args.full_ba;
  auto estimator = std::make_unique<hwr::estimation::PoseEstimator>(est_cfg, info);
  // A detector's boxes hold what one keyframe saw: a region grows to hold every detection of it.
  if (args.regions != "truth" && !args.regions.empty()) map_cfg.fine.grow_to_cover = true;
  auto mapper = hwr::recon::LocalMapper::create(map_cfg, info.intrinsics, est_cfg.tracker.orb.max_features);
  if (!mapper.ok()) {
    std::fprintf(stderr, "hwr-robot: map: %s\n", mapper.status().message().c_str());
    return 2;
  }
  Robot robot;
  // --prior-map: the earlier run's map, read lazily (docs/relocalization.md); the worker thread
  // relocalizes against it while the robot moves.
  std::unique_ptr<hwr::recon::RelocalizationWorker> reloc;
  hwr::recon::RelocalizationPriorsConfig priors_cfg;
  hwr::recon::PriorSensorFrames prior_frames;
  std::unique_ptr<hwr::recon::CurrentSensorPriors> sensor_priors;
  uint32_t segment_id_offset = 0;
  std::string prior_run_id;
  if (!args.prior_map.empty()) {
    auto prior = hwr::recon::PriorMap::open(args.prior_map);
    if (!prior.ok()) {
      std::fprintf(stderr, "hwr-robot: --prior-map: %s\n", prior.status().message().c_str());
      return 1;
    }
    if (prior->keyframes().empty()) {
      std::fprintf(stderr, "hwr-robot: --prior-map: %s holds no keyframes to relocalize against\n",
                   args.prior_map.c_str());
      return 1;
    }
    for (const auto& seg : prior->segments())
      segment_id_offset = std::max(segment_id_offset, seg.segment_id + 1);
    prior_run_id = prior->metadata().run_id;
    // The same robot on both visits: this run's antenna and magnetometer calibration.
    priors_cfg.antenna_imu_m = info.gnss_antenna_imu_m;
    priors_cfg.mag.hard_iron_imu_uT = info.mag_hard_iron_uT;
    Eigen::Isometry3d prior_T_imu_cam = prior->metadata().T_imu_cam;
    if (!prior->metadata().T_imu_cam_recorded) {
      prior_T_imu_cam = info.T_imu_cam;
      std::fprintf(
          stderr,
          "hwr-robot: --prior-map: %s does not record T_imu_cam (written before it did); this run's is "
          "used for its magnetometer heading\n",
          args.prior_map.c_str());
    } else if ((prior_T_imu_cam.matrix() - info.T_imu_cam.matrix()).cwiseAbs().maxCoeff() > 1e-3) {
      // The same robot on both visits should have one mount; a different one (a recalibration, or a
      // store written by an hwr-robot that recorded an identity) turns the prior's magnetometer heading.
      std::fprintf(
          stderr,
          "hwr-robot: --prior-map: warning: %s records a camera-IMU extrinsic T_imu_cam that differs "
          "from this run's by up to %.3f; the prior's is used for its magnetometer heading (if the "
          "heading is refused or far from the GNSS one, check the prior's calibration)\n",
          args.prior_map.c_str(), (prior_T_imu_cam.matrix() - info.T_imu_cam.matrix()).cwiseAbs().maxCoeff());
    }
    auto frames = hwr::recon::prior_sensor_frames(prior.value(), prior_T_imu_cam, priors_cfg);
    if (!frames.ok()) {
      std::fprintf(stderr, "hwr-robot: --prior-map: %s\n", frames.status().message().c_str());
      return 1;
    }
    prior_frames = std::move(frames.value());
    std::fprintf(stderr, "hwr-robot: prior map sensors: %s\n", prior_frames.summary.c_str());
    std::fprintf(stderr, "hwr-robot: prior map %s (run %s): %zu segments, %zu keyframes\n",
                 args.prior_map.c_str(), prior_run_id.c_str(), prior->segments().size(),
                 prior->keyframes().size());
    robot.updates_to_stream.reserve(2 * prior->segments().size());
    auto w = hwr::recon::RelocalizationWorker::start(std::move(prior.value()),
                                                     hwr::recon::RelocalizationWorkerConfig{},
                                                     info.intrinsics, est_cfg.tracker.orb.max_features);
    if (!w.ok()) {
      std::fprintf(stderr, "hwr-robot: --prior-map: %s\n", w.status().message().c_str());
      return 2;
    }
    reloc = std::move(w.value());
    sensor_priors = std::make_unique<hwr::recon::CurrentSensorPriors>(priors_cfg);
  }
  RobotSegmentSink segments;
  segments.keep_world_cloud = !args.cloud_out.empty();
  segments.robot = &robot;
  segments.hold_until_localized = reloc != nullptr;
  segments.id_offset = segment_id_offset;
  std::unique_ptr<hwr::recon::StoreSegmentWriter> store_writer;
  if (!args.map_out.empty()) {
    hwr::recon::StoreMetadata meta;
    meta.run_id = utc_run_id();
    meta.intrinsics = info.intrinsics;
    meta.T_imu_cam = info.T_imu_cam;
    auto store = hwr::recon::MapStore::open(args.map_out, meta);
    if (!store.ok()) {
      std::fprintf(stderr, "hwr-robot: --map-out: %s\n", store.status().message().c_str());
      return 1;
    }
    // A store holds one run: its segment ids start at 0 (a prior map is read with --prior-map,
    // issue #6).
    auto existing = store->list_segments();
    if (!existing.ok() || !existing->empty()) {
      const std::string what =
          existing.ok() ? std::to_string(existing->size()) + " segments of run " + store->metadata().run_id
                        : existing.status().message();
      std::fprintf(stderr, "hwr-robot: --map-out: %s already holds %s; give a new directory\n",
                   args.map_out.c_str(), what.c_str());
      return 1;
    }
    store_writer = std::make_unique<hwr::recon::StoreSegmentWriter>(std::move(store.value()));
    segments.writer = store_writer.get();
  }

  std::unique_ptr<hwr::mapio::MapStreamer> streamer;
  std::unique_ptr<LinkStreamSink> link_sink;
  if (!args.link.empty()) {
    // run_id: wall-clock nanoseconds at start, unique per robot run.
    const int64_t run_id = static_cast<int64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                                    std::chrono::system_clock::now().time_since_epoch())
                                                    .count());
    auto s =
        hwr::mapio::MapStreamer::start(args.link, args.robot_id, run_id, hwr::mapio::MapStreamerConfig{});
    if (!s.ok()) {
      std::fprintf(stderr, "hwr-robot: --link: %s\n", s.status().message().c_str());
      return 1;
    }
    streamer = std::move(s.value());
    link_sink = std::make_unique<LinkStreamSink>(streamer.get(), args.realtime ? 0.0 : 60.0, &robot,
                                                 segment_id_offset);
    mapper->set_stream_sink(link_sink.get());
    std::fprintf(stderr, "hwr-robot: streaming the map as %s run %lld over %s\n", args.robot_id.c_str(),
                 static_cast<long long>(run_id), args.link.c_str());
  }

  // A live source's timeline is CLOCK_MONOTONIC itself: the scheduler starts at the present, not at
  // the source's opening (set-up since then may have taken seconds).
  const int64_t t0 = live ? hwr::core::MonotonicClock().now_ns() : info.first_t_ns;
  hwr::core::SimClock sim_clock(t0);
  PacedClock paced_clock(t0);
  hwr::core::MonotonicClock exec_clock;
  hwr::core::Clock& timeline = args.realtime ? static_cast<hwr::core::Clock&>(paced_clock) : sim_clock;

  hwr::core::Scheduler sched(kTasks, kTaskCount, timeline);
  sched.set_execution_clock(exec_clock);  // budgets are checked against real work
  robot.streams = &streams;
  robot.reloc = reloc.get();
  robot.segments_updated = store_writer.get();
  robot.sensor_priors = sensor_priors.get();
  robot.prior_frames = &prior_frames;
  robot.T_cam_imu = info.T_imu_cam.inverse();
  robot.antenna_imu_m = info.gnss_antenna_imu_m;
  robot.source = source.get();
  robot.scheduler = &sched;
  robot.estimator = estimator.get();
  robot.mapper = &mapper.value();
  std::vector<hwr::recon::TruthJointBox> truth_joints;
  if (args.regions == "truth") {
    if (!opened->has_weld_truth) {
      std::fprintf(
          stderr,
          "hwr-robot: --regions truth needs a simulator source with its weld ground truth (sim:NAME, "
          "or sim:DIR holding weld_groundtruth.yaml and groundtruth.txt); %s has none\n",
          args.source.c_str());
      return 2;
    }
    truth_joints = hwr::recon::truth_joint_boxes(opened->weld_truth, kTruthBoxMarginM);
    robot.truth_joints = &truth_joints;
    robot.truth_T_world_cam = &opened->truth_T_world_cam;
    robot.detections.reserve(truth_joints.size());
    std::fprintf(stderr,
                 "hwr-robot: welding regions: the simulator's %zu joints as detections (a perfect detector, "
                 "placed with the estimated poses)\n",
                 truth_joints.size());
  }
  hwr::detect::MadeDetector detector;
  hwr::detect::DetectionList detections(32);
  if (args.regions != "truth" && !args.regions.empty()) {
    hwr::detect::DetectorChoice choice;
    if (args.regions != "geometry") {
      const size_t colon = args.regions.find(':');
      choice.backend = args.regions.compare(0, colon, "onnx") == 0 ? hwr::detect::DetectorBackend::kOnnx
                                                                   : hwr::detect::DetectorBackend::kTensorRt;
      choice.model.model_path = choice_model_path(args.regions);
    }
    auto made = hwr::detect::make_detector(choice, info.intrinsics);
    if (!made.ok()) {
      std::fprintf(stderr, "hwr-robot: --regions %s: %s\n", args.regions.c_str(),
                   made.status().message().c_str());
      return 2;
    }
    detector = std::move(made.value());
    if (detector.fell_back()) {
      std::fprintf(stderr,
                   "hwr-robot: --regions %s: the model is unusable (%s); using the geometric seam detector\n",
                   args.regions.c_str(), detector.fallback_reason.c_str());
    }
    robot.detector = detector.detector.get();
    robot.detected = &detections;
    if (detector.backend == hwr::detect::DetectorBackend::kGeometry) {
      std::fprintf(stderr,
                   "hwr-robot: welding regions: the geometric seam detector on each keyframe's depth\n");
    } else {
      std::fprintf(stderr, "hwr-robot: welding regions: the %s detector (%s) on each keyframe\n",
                   hwr::detect::detector_backend_name(detector.backend),
                   choice_model_path(args.regions).c_str());
    }
  }
  // The operator channel: the detectors' regions as a list the operator corrects (operator_channel.hpp),
  // kept in the map store and, on the next visit, read back from the prior map.
  std::unique_ptr<hwr::robot::OperatorChannel> operator_channel;
  if (robot.detector != nullptr) {
    hwr::detect::DetectionLedger ledger;
    if (!args.prior_map.empty()) {
      const std::string path = args.prior_map + "/detections.yaml";
      auto loaded = hwr::detect::DetectionLedger::load(path);
      if (loaded.ok()) {
        ledger = std::move(loaded.value());
        std::fprintf(
            stderr,
            "hwr-robot: welding regions: %zu from the prior map's list (%s), placed once relocalized\n",
            ledger.entries().size(), path.c_str());
      } else if (loaded.status().code() != hwr::core::ErrorCode::kNotFound) {
        // The operator's decisions are not dropped silently: the file must be mended or removed.
        std::fprintf(stderr, "hwr-robot: --prior-map: %s\n", loaded.status().message().c_str());
        return 1;
      }
    }
    const std::string save_path = args.map_out.empty() ? "" : args.map_out + "/detections.yaml";
    operator_channel = std::make_unique<hwr::robot::OperatorChannel>(std::move(ledger), info.intrinsics,
                                                                     streamer.get(), save_path);
    robot.operator_channel = operator_channel.get();
  }
  robot.segments = &segments;
  robot.streamer = streamer.get();
  robot.recorder = recorder.get();
  robot.quiet = args.quiet;
  robot.imu = hwr::hal::StreamMonitor(info.imu_rate_hz > 0 ? info.imu_rate_hz : 200.0);
  robot.camera = hwr::hal::StreamMonitor(info.camera_rate_hz > 0 ? info.camera_rate_hz : 30.0);
  sched.bind(kHal, hal_task, &robot);
  sched.bind(kInertial, inertial_task, &robot);
  sched.bind(kCamera, camera_task, &robot);
  sched.bind(kMapping, mapping_task, &robot);
  sched.bind(kTelemetry, telemetry_task, &robot);
  sched.start(t0);

  char span[32] = "live";
  if (!live)
    std::snprintf(span, sizeof(span), "%.1f s", hwr::core::ns_to_s(info.last_t_ns - info.first_t_ns));
  std::fprintf(stderr, "hwr-robot: source %s: %s, %s%s%s%s\n", info.name.c_str(), span, "camera",
               info.has_imu ? " + imu" : "", info.has_mag ? " + magnetometer" : "",
               info.has_gnss ? " + gnss" : "");
  const int64_t end = args.duration_s > 0 ? t0 + hwr::core::s_to_ns(args.duration_s)
                                          : info.last_t_ns + hwr::core::kNsPerS / 10;
  const int64_t wall0 = exec_clock.now_ns();
  hwr::core::Status st = sched.run_until(end);
  // Hand the last samples to the pipeline: frames first (their IMU samples are queued), then the
  // rest of the IMU queue.
  inertial_task(&robot, end);
  camera_task(&robot, end);
  estimator->advance_imu(end + kImuHoldbackNs);
  robot.recorder = nullptr;  // everything the pipeline took is recorded
  const hwr::core::Status record_status = recorder ? recorder->close() : hwr::core::Status::Ok();
  mapping_task(&robot, end);
  if (reloc) {
    // A replay runs faster than the worker: the attempt under way still counts.
    reloc->wait_idle();
    relocalization_step(&robot);
  }
  const double wall_s = hwr::core::ns_to_s(exec_clock.now_ns() - wall0);
  if (!st.ok()) robot.error = st;
  if (!args.quiet) std::fputc('\n', stderr);

  int rc = 0;
  if (!args.ba_export.empty()) {
    // The problem finish() solves next, built apart so that exporting changes nothing.
    hwr::estimation::LocalBundleAdjustment exporter(est_cfg.local_ba, est_cfg.tracker.map_point_capacity);
    hwr::estimation::LocalBaReport rep;
    const auto& tracker = estimator->tracker();
    const hwr::estimation::BaProblem& pb =
        exporter.build_problem(tracker.keyframes(), tracker.points(), tracker.intrinsics(), true, &rep);
    const hwr::core::Status ws = pb.cameras.size() < 2
                                     ? hwr::core::Unavailable("fewer than 2 keyframes to export")
                                     : hwr::estimation::write_bal(pb, args.ba_export);
    if (!ws.ok()) {
      std::fprintf(stderr, "hwr-robot: --ba-export: %s\n", ws.message().c_str());
      rc = 1;
    } else {
      std::printf("bundle adjustment problem: %d cameras, %d points, %d observations -> %s (BAL)\n",
                  rep.cameras, rep.points, rep.observations, args.ba_export.c_str());
    }
  }
  const int64_t full0 = exec_clock.now_ns();
  auto full = estimator->finish();
  const double full_s = hwr::core::ns_to_s(exec_clock.now_ns() - full0);
  // The keyframes not yet fused (the lag) go in with their final poses; the last segment closes.
  mapper->finish(estimator->tracker().keyframes(), &segments);
  segments.release_held();
  if (reloc) {
    // The map update's queued keyframes and open segments, then its last new versions.
    reloc->finish();
    take_updated_segments(&robot, args.link_wait_s);
  }
  if (store_writer) store_writer->drain();
  if (operator_channel) {
    // Commands that came in at the end, then the list as the run leaves it.
    operator_channel->step(&mapper->fine_map_for_operator(), estimator->tracker().keyframes(),
                           robot.T_out_world, !reloc || robot.in_prior_frame, end);
    const hwr::core::Status os = operator_channel->save();
    if (!os.ok()) {
      std::fprintf(stderr, "hwr-robot: the detection list: %s\n", os.message().c_str());
      rc = 1;
    }
  }

  char table[4096];
  sched.format_telemetry(table, sizeof(table));
  const hwr::hal::SourceCounters c = source->counters();
  const auto& ih = robot.imu.health();
  const auto& ch = robot.camera.health();
  std::printf("scheduler telemetry (simulated %.2f s in %.2f s wall):\n%s",
              hwr::core::ns_to_s(sched.next_release_ns(0) - t0), wall_s, table);
  std::printf("camera: frames=%" PRIu64 " dropped=%" PRIu64 " unreadable=%" PRIu64 " gaps=%" PRIu64
              " low_depth=%" PRIu64 " max_interval_ms=%.1f\n",
              ch.samples, c.frames_dropped, c.frame_errors, ch.gaps, robot.camera.frames_low_depth(),
              ch.max_interval_ns * 1e-6);
  std::printf("imu: samples=%" PRIu64 " dropped=%" PRIu64 " gaps=%" PRIu64 " non_finite=%" PRIu64
              " non_increasing=%" PRIu64 "\n",
              ih.samples, streams.imu.dropped(), ih.gaps, ih.non_finite, ih.non_increasing_t);
  if (c.decode_waits > 0) {
    std::printf("replay: the hal task waited %" PRIu64
                " times, %.2f s in all, for frames to be decoded (replay is "
                "I/O-bound; these waits are the hal task's overruns)\n",
                c.decode_waits, hwr::core::ns_to_s(c.decode_wait_ns));
  }
  std::printf("magnetometer: samples=%" PRIu64 "  gnss: fixes=%" PRIu64 " with_3d_fix=%" PRIu64 "\n",
              robot.mag, robot.gnss, robot.gnss_3d);
  if (recorder) {
    const hwr::mapio::SensorRecorderCounters rec_counts = recorder->counters();
    std::printf("recording: imu=%" PRIu64 " mag=%" PRIu64 " gnss=%" PRIu64 " frames=%" PRIu64
                " dropped=%" PRIu64 " (%.1f MB) -> %s\n",
                rec_counts.imu, rec_counts.mag, rec_counts.gnss, rec_counts.frames, rec_counts.dropped,
                static_cast<double>(rec_counts.bytes) * 1e-6, recorder->path().c_str());
    if (!record_status.ok()) {
      std::fprintf(stderr, "hwr-robot: %s\n", record_status.message().c_str());
      rc = 1;
    } else if (rec_counts.dropped > 0) {
      std::fprintf(
          stderr,
          "hwr-robot: --record: %" PRIu64
          " samples or frames not recorded: the disk did not keep up (record to NVMe), or frames not of "
          "the camera's size\n",
          rec_counts.dropped);
    }
  }
  if (fault_report) {
    std::printf("faults injected: frames_removed=%" PRIu64 " exposure_changed=%" PRIu64
                " depth_holes=%" PRIu64 " imu_removed=%" PRIu64 "\n",
                fault_report->frames_removed.load(), fault_report->frames_exposure_changed.load(),
                fault_report->frames_with_depth_holes.load(), fault_report->imu_removed.load());
  }
  const auto e = estimator->counters();
  std::printf("estimation: mode=%s frames=%" PRIu64 " tracked=%" PRIu64 " recovered=%" PRIu64 " lost=%" PRIu64
              " waiting=%" PRIu64 " bad_frames=%" PRIu64 " late_for_filter=%" PRIu64 " ahead_of_imu=%" PRIu64
              " point_pool_full=%" PRIu64 " keyframes_refused=%" PRIu64 "\n",
              e.visual_only ? "visual-only" : "visual-inertial", e.tracker.frames, e.tracker.tracked,
              e.tracker.recovered, e.tracker.lost, e.frames_waiting_for_init, e.tracker.bad_frames,
              e.frames_late_for_filter, e.frames_ahead_of_imu, e.tracker.point_pool_exhausted,
              e.tracker.keyframes_refused);
  std::printf("estimation: keyframes=%" PRIu64 " points=%d (depth %" PRIu64 ", triangulated %" PRIu64
              ", culled %" PRIu64 ", retired %" PRIu64 ") local_ba=%" PRIu64 " (failed %" PRIu64
              ") imu_updates=%" PRIu64 " gated=%" PRIu64 " filter_resets=%" PRIu64 "\n",
              e.tracker.keyframes, estimator->tracker().points().alive(), e.tracker.points_from_depth,
              e.tracker.points_triangulated, e.tracker.points_culled, e.tracker.points_retired,
              e.local_ba_runs, e.local_ba_failures, e.mekf.updates, e.visual_updates_gated, e.filter_resets);
  if (full.ok()) {
    std::printf(
        "full bundle adjustment: cameras=%d points=%d observations=%d cost %.4g -> %.4g in %d iterations, "
        "%.2f s\n",
        full->cameras, full->points, full->observations, full->summary.initial_cost, full->summary.final_cost,
        full->summary.iterations, full_s);
  } else {
    std::fprintf(stderr,
                 "hwr-robot: full bundle adjustment failed (%s); the trajectory is the sliding-window one\n",
                 full.status().message().c_str());
  }
  {
    const auto& m = mapper->counters();
    std::printf("map: segments=%" PRIu64 " points=%" PRIu64 " keyframes_fused=%" PRIu64
                " without_images=%" PRIu64 " junctions: orb-seeded=%" PRIu64 " ndt-refined=%" PRIu64
                " of %" PRIu64 "\n",
                m.segments_closed, m.points_closed, m.keyframes_fused, m.keyframes_without_images,
                m.junctions_orb, m.junctions_ndt, m.segments_closed > 0 ? m.segments_closed - 1 : 0);
    for (const auto& line : segments.junction_lines) std::printf("  %s\n", line.c_str());
    const auto& f = mapper->fine_map().counters();
    if (f.regions_added + f.detections_invalid + f.regions_refused > 0) {
      std::printf("map: welding regions=%" PRIu64 " (detections %" PRIu64 ", merged %" PRIu64
                  ", refused %" PRIu64 ", invalid %" PRIu64 ") fine points offered=%" PRIu64 " in %" PRIu64
                  " keyframes, fine voxels=%" PRIu64 " (%.0f mm, refused full %" PRIu64 ")\n",
                  f.regions_added, robot.region_detections, f.detections_merged, f.regions_refused,
                  f.detections_invalid, f.points_inserted, f.keyframes_in_view, m.fine_points_closed,
                  map_cfg.fine.voxels.voxel_m * 1e3, mapper->fine_map().fine_map().counters().refused_full);
    }
    if (robot.detect_errors > 0) {
      std::printf("map: seam detector: %" PRIu64 " keyframes refused (the first is in the log)\n",
                  robot.detect_errors);
    }
    if (operator_channel) {
      const auto& o = operator_channel->counters();
      size_t rejected = 0, confirmed = 0, unplaced = 0;
      for (const auto& entry : operator_channel->ledger().entries()) {
        rejected += entry.state == hwr::detect::DetectionState::kRejected;
        confirmed += entry.state == hwr::detect::DetectionState::kConfirmed;
        unplaced += !entry.placed;
      }
      if (unplaced > 0) {
        // Not relocalized: the list holds the prior map's entries in the prior's frame and this run's in
        // its own (as the segments of such a run are).
        std::printf(
            "operator: warning: %zu entries of the prior map's list were never placed in this run "
            "(not relocalized): they keep the prior map's frame, this run's entries its own\n",
            unplaced);
      }
      std::printf("operator: detections=%zu confirmed=%zu rejected=%zu commands applied=%" PRIu64
                  " refused=%" PRIu64 " repeated=%" PRIu64 " suppressed_detections=%" PRIu64
                  " restored_from_prior=%" PRIu64 " (duplicates merged %" PRIu64 ") -> %s\n",
                  operator_channel->ledger().entries().size(), confirmed, rejected, o.commands_applied,
                  o.commands_refused, o.commands_repeated, o.detections_suppressed, o.regions_restored,
                  o.duplicates_merged,
                  operator_channel->save_path().empty() ? "(no --map-out: not kept)"
                                                        : operator_channel->save_path().c_str());
    }
    if (store_writer) {
      const auto w = store_writer->counters();
      std::printf("map store: %" PRIu64 " segments written (%" PRIu64 " failed, %" PRIu64 " stalls) -> %s\n",
                  w.written, w.failed, w.stalls, args.map_out.c_str());
      if (w.failed > 0) rc = 1;
    }
    if (reloc) {
      const hwr::recon::RelocalizationWorkerStatus rs = reloc->status();
      if (rs.localized) {
        const Eigen::Isometry3d& T = rs.T_prior_world;
        const double yaw_deg = std::atan2(T.linear()(1, 0), T.linear()(0, 0)) * 180.0 / M_PI;
        std::printf(
            "relocalization: localized in the prior map %s after %.2f m of motion, attempt %d, %.2f s of "
            "relocalization in all; T_prior_world: t = (%.3f, %.3f, %.3f) m, yaw %.2f deg; "
            "poses, segments and the streamed map are in the prior's frame\n",
            args.prior_map.c_str(), rs.moved_at_localization_m, rs.attempts, rs.wall_s_total,
            T.translation().x(), T.translation().y(), T.translation().z(), yaw_deg);
      } else {
        std::printf(
            "relocalization: NOT localized in the prior map %s (%d attempts, %.2f s, %.2f m moved); "
            "last: %s; outputs are in this run's frame\n",
            args.prior_map.c_str(), rs.attempts, rs.wall_s_total, robot.moved_m,
            rs.last_message.empty() ? "no attempt" : rs.last_message.c_str());
      }
      if (rs.localized) {
        const auto& u = rs.update;
        std::printf(
            "map update: %" PRIu64 " keyframes (%" PRIu64 " dropped, %" PRIu64
            " without prior in view), %" PRIu64 " carving views (%" PRIu64 " failed the pose check), %" PRIu64
            " prior segments updated, %" PRIu64 " points deleted%s%s\n",
            u.keyframes, rs.keyframes_dropped, u.no_prior_in_view, u.frames_carved + u.frames_misaligned,
            u.frames_misaligned, robot.updated_segments, robot.updated_points_deleted,
            rs.update_error.empty() ? "" : "; error: ", rs.update_error.c_str());
        if (robot.updated_stream_wait_ticks > 0) {
          std::printf("map update: updated versions waited %" PRIu64
                      " mapping ticks for the link's batch slots; %" PRIu64
                      " versions were replaced by a newer one before they went out\n",
                      robot.updated_stream_wait_ticks, robot.updated_stream_superseded);
        }
        if (robot.updated_stream_refused > 0) {
          std::fprintf(stderr,
                       "hwr-robot: --link: %" PRIu64
                       " updated prior segment versions not streamed whole (no batch slot freed in "
                       "--link-wait)\n",
                       robot.updated_stream_refused);
          rc = 1;
        }
      }
      if (!robot.last_priors.empty())
        std::printf("relocalization: last query's priors: %s\n", robot.last_priors.c_str());
      if (segments.written_in_run_frame > 0) {
        std::printf("relocalization: %" PRIu64 " segments were written in this run's frame\n",
                    segments.written_in_run_frame);
      }
      if (!args.map_out.empty()) {
        const hwr::core::Status ws =
            write_relocalization_yaml(args.map_out, args.prior_map, prior_run_id, segment_id_offset, rs);
        if (!ws.ok()) {
          std::fprintf(stderr, "hwr-robot: --map-out: %s\n", ws.message().c_str());
          rc = 1;
        }
      }
    }
    if (streamer) {
      // The robot has stopped: the rest of the map goes out; wait for the ground station.
      const auto wait0 = std::chrono::steady_clock::now();
      const bool all_acked = streamer->flush(args.link_wait_s);
      const double waited_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wait0).count();
      const hwr::mapio::MapStreamerStats ls = streamer->stats();
      std::printf(
          "link: %lld chunks, %lld points, %.2f MB (raw %.2f MB, %.1fx smaller), sends %lld, resends %lld, "
          "acked %lld, refused batches %lld (completions owed %lld, lost %lld), encode errors %lld; %s %.2f "
          "s "
          "after the stop\n",
          static_cast<long long>(ls.chunks), static_cast<long long>(ls.points), ls.payload_bytes * 1e-6,
          ls.raw_bytes * 1e-6,
          ls.payload_bytes > 0 ? static_cast<double>(ls.raw_bytes) / ls.payload_bytes : 0.0,
          static_cast<long long>(ls.sends), static_cast<long long>(ls.resends),
          static_cast<long long>(ls.acked), static_cast<long long>(ls.batches_refused),
          static_cast<long long>(ls.completions_owed), static_cast<long long>(ls.completions_lost),
          static_cast<long long>(ls.encode_errors), all_acked ? "all acknowledged" : "NOT all acknowledged",
          waited_s);
      if (!all_acked) {
        std::fprintf(
            stderr,
            "hwr-robot: --link: %d chunks not acknowledged after %.0f s (is hwr-ground running on the "
            "same URL?)%s\n",
            ls.in_flight, args.link_wait_s, args.map_out.empty() ? "" : "; the map store has the whole map");
        rc = 1;
      }
      if (ls.batches_refused > 0 || ls.encode_errors > 0) {
        std::fprintf(
            stderr,
            "hwr-robot: --link: the ground station's map has holes: %lld batches refused, %lld chunks "
            "not encoded%s\n",
            static_cast<long long>(ls.batches_refused), static_cast<long long>(ls.encode_errors),
            args.map_out.empty() ? "" : " (the map store has the whole map)");
        rc = 1;
      }
    }
    if (!args.cloud_out.empty()) {
      const hwr::core::Status ws = hwr::recon::write_cloud_file(args.cloud_out, segments.cloud_world.data(),
                                                                segments.cloud_world.size());
      if (!ws.ok()) {
        std::fprintf(stderr, "hwr-robot: --cloud-out: %s\n", ws.message().c_str());
        rc = 1;
      } else {
        std::printf("cloud: %zu points (world frame) -> %s\n", segments.cloud_world.size(),
                    args.cloud_out.c_str());
      }
    }
  }
  if (!args.traj_out.empty()) {
    auto traj = estimator->trajectory();
    // In the output frame (the prior's once relocalized: one rigid transform for the whole run).
    for (auto& sp : traj) sp.T_world_body = robot.T_out_world * sp.T_world_body;
    const hwr::core::Status ws = hwr::core::write_tum_trajectory(args.traj_out, traj);
    if (!ws.ok()) {
      std::fprintf(stderr, "hwr-robot: --traj-out: %s\n", ws.message().c_str());
      rc = 1;
    } else {
      std::printf("trajectory: %zu poses -> %s\n", traj.size(), args.traj_out.c_str());
    }
  }
  if (!args.timing_out.empty()) {
    const hwr::core::Status ws = write_timings(args.timing_out, estimator->timings());
    if (!ws.ok()) {
      std::fprintf(stderr, "hwr-robot: --timing-out: %s\n", ws.message().c_str());
      rc = 1;
    } else {
      std::printf("timings: %zu frames -> %s\n", estimator->timings().size(), args.timing_out.c_str());
    }
  }
  if (!args.gt_out.empty()) {
    if (opened->gt_at_frames.empty()) {
      std::fprintf(stderr, "hwr-robot: --gt-out: this source has no ground truth at image times\n");
      rc = 1;
    } else {
      const hwr::core::Status ws = hwr::core::write_tum_trajectory(args.gt_out, opened->gt_at_frames);
      if (!ws.ok()) {
        std::fprintf(stderr, "hwr-robot: --gt-out: %s\n", ws.message().c_str());
        rc = 1;
      } else {
        std::printf("ground truth: %zu poses -> %s\n", opened->gt_at_frames.size(), args.gt_out.c_str());
      }
    }
  }
  if (!robot.error.ok()) {
    std::fprintf(stderr, "hwr-robot: %s\n", robot.error.to_string().c_str());
    return 1;
  }
  return rc;
}

}  // namespace

int main(int argc, char** argv) {
  // Before any thread: segments' buffers are mmap'd and given back, so the resident size stays flat.
  if (const auto st = hwr::core::fix_malloc_mmap_threshold(); !st.ok())
    std::fprintf(stderr, "hwr-robot: %s (continuing with glibc's defaults)\n", st.message().c_str());
  Args args;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* name) -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "hwr-robot: %s needs a value\n", name);
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--source") {
      args.source = value("--source");
    } else if (a == "--duration") {
      char* end = nullptr;
      const char* v = value("--duration");
      args.duration_s = std::strtod(v, &end);
      if (*end != '\0' || !(args.duration_s > 0 && args.duration_s <= 1e6)) {
        std::fprintf(stderr, "hwr-robot: --duration: expected seconds in (0, 1e6], got '%s'\n", v);
        return 2;
      }
    } else if (a == "--config") {
      args.config = value("--config");
    } else if (a == "--traj-out") {
      args.traj_out = value("--traj-out");
    } else if (a == "--timing-out") {
      args.timing_out = value("--timing-out");
    } else if (a == "--gt-out") {
      args.gt_out = value("--gt-out");
    } else if (a == "--faults") {
      args.faults = value("--faults");
    } else if (a == "--map-out") {
      args.map_out = value("--map-out");
    } else if (a == "--cloud-out") {
      args.cloud_out = value("--cloud-out");
    } else if (a == "--prior-map") {
      args.prior_map = value("--prior-map");
    } else if (a == "--regions") {
      args.regions = value("--regions");
      const bool model = (args.regions.rfind("onnx:", 0) == 0 && args.regions.size() > 5) ||
                         (args.regions.rfind("tensorrt:", 0) == 0 && args.regions.size() > 9);
      if (args.regions != "truth" && args.regions != "geometry" && !model) {
        std::fprintf(stderr,
                     "hwr-robot: --regions: expected 'truth', 'geometry', 'onnx:MODEL' or 'tensorrt:ENGINE', "
                     "got '%s'\n",
                     args.regions.c_str());
        return 2;
      }
    } else if (a == "--link") {
      args.link = value("--link");
    } else if (a == "--robot-id") {
      args.robot_id = value("--robot-id");
    } else if (a == "--link-wait") {
      args.link_wait_s = std::atof(value("--link-wait"));
    } else if (a == "--record") {
      args.record = value("--record");
    } else if (a == "--ba-export") {
      args.ba_export = value("--ba-export");
    } else if (a == "--no-imu") {
      args.use_imu = false;
    } else if (a == "--no-local-ba") {
      args.local_ba = false;
    } else if (a == "--no-full-ba") {
      args.full_ba = false;
    } else if (a == "--realtime") {
      args.realtime = true;
    } else if (a == "--quiet") {
      args.quiet = true;
    } else if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else {
      std::fprintf(stderr, "hwr-robot: unknown option '%s'\n", a.c_str());
      usage();
      return 2;
    }
  }
  if (args.source.empty()) {
    usage();
    return 2;
  }
  return run(args);
}
