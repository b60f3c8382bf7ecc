#include "hwr/sim/sim_live_log.hpp"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <string>
#include <utility>

#include "sim_frame_source.hpp"

namespace hwr::sim {
namespace {

// Renders frames for the replay. Owned through a shared_ptr by the log's load_frame, so the
// renderer and the scratch live as long as any copy of the log.
class LiveFrameLoader {
 public:
  LiveFrameLoader(SimRunSetup run, std::shared_ptr<const Renderer> renderer)
      : run_(std::move(run)), renderer_(std::move(renderer)) {}

  // Writes into the caller's frame buffers (reallocated only when their size or type differs:
  // the replay's pool frames are sized for the camera, so steady state renders in place).
  core::Status load(size_t i, hal::RgbdFrame* out) {
    if (i >= run_.frame_offsets_ns.size()) {
      return core::OutOfRange("sim-live:" + run_.spec.name + ": frame " + std::to_string(i) +
                              " requested, the run has " + std::to_string(run_.frame_offsets_ns.size()));
    }
    // One loader per replay calls this from one thread; the lock only matters when two replays
    // share a copied log (right_bgr_ is shared scratch).
    std::lock_guard<std::mutex> lock(mutex_);
    render_sim_frame(run_, *renderer_, i, &out->bgr, &out->depth_m, &right_bgr_, &out->right_gray);
    if (!run_.spec.camera.stereo) out->right_gray.release();
    out->invalid_depth_px = invalidate_unstorable_depth(run_.spec.camera.depth_scale, &out->depth_m);
    out->intrinsics = run_.spec.camera.intrinsics;
    out->t_ns = run_.t0_ns + run_.frame_offsets_ns[i];
    out->seq = i;
    return core::Status::Ok();
  }

 private:
  const SimRunSetup run_;
  const std::shared_ptr<const Renderer> renderer_;
  std::mutex mutex_;
  cv::Mat right_bgr_;  // stereo: right colour image before the gray conversion
};

template <class T>
void widen_span(const std::vector<T>& v, hal::SourceInfo* info) {
  if (v.empty()) return;
  if (info->first_t_ns == 0 || v.front().t_ns < info->first_t_ns) info->first_t_ns = v.front().t_ns;
  info->last_t_ns = std::max(info->last_t_ns, v.back().t_ns);
}

}  // namespace

core::Expected<SimLiveLog> open_sim_live_log(const ScenarioSpec& spec, double duration_s) {
  if (!std::isfinite(duration_s) || duration_s < 0.0) {
    return core::InvalidArgument("scenario '" + spec.name + "': duration_s must be >= 0 seconds (0: the " +
                                 "whole scenario), got " + std::to_string(duration_s));
  }
  auto run_or = prepare_sim_run(spec, duration_s);
  if (!run_or.ok()) return run_or.status();
  auto renderer = create_sim_renderer(run_or.value());
  if (!renderer.ok()) return renderer.status();
  const SimRunSetup& run = run_or.value();
  SimStreams streams = synthesize_sim_streams(run);

  SimLiveLog out;
  out.calibration = make_sim_calibration(run.spec, run.T_scene_world);
  out.path_length_m = run.trajectory.evaluate(run.duration_s).distance_m;
  out.groundtruth_T_world_cam = std::move(streams.groundtruth_T_world_cam);
  out.groundtruth_T_world_cam_at_frames.resize(run.frame_offsets_ns.size());
  hal::ReplayLog& log = out.log;
  log.frame_t_ns.resize(run.frame_offsets_ns.size());
  for (size_t k = 0; k < run.frame_offsets_ns.size(); ++k) {
    const int64_t offset_ns = run.frame_offsets_ns[k];
    log.frame_t_ns[k] = run.t0_ns + offset_ns;
    out.groundtruth_T_world_cam_at_frames[k].t_ns = log.frame_t_ns[k];
    out.groundtruth_T_world_cam_at_frames[k].T_world_body =
        run.T_world_scene * sim_T_scene_cam(run, offset_ns);
  }

  // The same SourceInfo open_sim_run_log gives the written run, plus the stereo flag (the
  // replay of files does not load right images).
  const SimCalibration& calib = out.calibration;
  log.info.name = "sim-live:" + run.spec.name;
  log.info.intrinsics = calib.intrinsics;
  log.info.T_imu_cam = calib.T_imu_cam;
  log.info.gnss_antenna_imu_m = calib.gnss_antenna_imu_m;
  log.info.mag_hard_iron_uT = calib.mag_hard_iron_uT;
  log.info.camera_rate_hz = calib.camera_rate_hz;
  log.info.imu_rate_hz = calib.imu_rate_hz;
  log.info.stereo = calib.stereo;
  log.info.first_t_ns = log.frame_t_ns.front();
  log.info.last_t_ns = log.frame_t_ns.back();
  log.imu.reserve(streams.imu.size());
  for (const ImuRecord& r : streams.imu) log.imu.push_back(r.sample);
  log.info.has_imu = !log.imu.empty();
  widen_span(log.imu, &log.info);
  log.mag = std::move(streams.mag);
  log.info.has_mag = !log.mag.empty();
  widen_span(log.mag, &log.info);
  log.gnss.reserve(streams.gnss.size());
  for (const GnssRecord& r : streams.gnss) log.gnss.push_back(r.fix);
  log.info.has_gnss = !log.gnss.empty();
  widen_span(log.gnss, &log.info);

  auto loader = std::make_shared<LiveFrameLoader>(
      std::move(run_or.value()), std::shared_ptr<const Renderer>(std::move(renderer.value())));
  log.load_frame = [loader](size_t i, hal::RgbdFrame* f) { return loader->load(i, f); };
  return out;
}

}  // namespace hwr::sim
