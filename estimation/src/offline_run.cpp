#include "hwr/estimation/offline_run.hpp"

#include <chrono>
#include <memory>

#include "hwr/core/log.hpp"

namespace hwr::estimation {

core::Expected<OfflineRun> run_offline(const hal::ReplayLog& log, const OfflineRunOptions& options) {
  if (!log.load_frame) return core::InvalidArgument("run_offline: the log has no frame loader");
  if (!log.info.intrinsics.valid())
    return core::InvalidArgument("run_offline: the log has no camera intrinsics");
  auto estimator = std::make_unique<PoseEstimator>(options.estimator, log.info);
  if (options.on_start) options.on_start(*estimator);
  OfflineRun out;
  hal::RgbdFrame frame;
  frame.bgr.create(log.info.intrinsics.height, log.info.intrinsics.width, CV_8UC3);
  frame.depth_m.create(log.info.intrinsics.height, log.info.intrinsics.width, CV_32FC1);
  if (log.info.stereo)
    frame.right_gray.create(log.info.intrinsics.height, log.info.intrinsics.width, CV_8UC1);
  // The same hold-back as hwr-robot's inertial task.
  constexpr int64_t kHoldbackNs = 60'000'000;
  size_t next_imu = 0, next_mag = 0;
  const size_t n_frames =
      options.max_frames > 0 ? std::min(options.max_frames, log.frame_t_ns.size()) : log.frame_t_ns.size();
  for (size_t i = 0; i < n_frames; ++i) {
    const int64_t t = log.frame_t_ns[i];
    // Everything a source would have delivered by the frame's time (plus one IMU period).
    while (next_imu < log.imu.size() && log.imu[next_imu].t_ns <= t + 10'000'000) {
      estimator->add_imu(log.imu[next_imu++]);
    }
    while (next_mag < log.mag.size() && log.mag[next_mag].t_ns <= t) estimator->add_mag(log.mag[next_mag++]);
    estimator->advance_imu(t - kHoldbackNs);
    const core::Status st = log.load_frame(i, &frame);
    if (!st.ok()) {
      ++out.frame_errors;
      HWR_LOG_WARN("estimation", "frame %zu: %s", i, st.message().c_str());
      continue;
    }
    if (options.around_track) options.around_track(i, true);
    estimator->process_frame(frame);
    if (options.around_track) options.around_track(i, false);
    if (estimator->local_ba_due()) {
      auto r = estimator->run_local_ba();
      if (!r.ok()) HWR_LOG_WARN("estimation", "local bundle adjustment: %s", r.status().message().c_str());
    }
    ++out.frames;
    if (options.after_frame) options.after_frame(i, *estimator);
  }
  out.trajectory_before_full_ba = estimator->trajectory();
  const auto t0 = std::chrono::steady_clock::now();
  auto full = estimator->finish();
  out.full_ba_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (full.ok()) {
    out.full_ba = full.value();
  } else {
    HWR_LOG_WARN("estimation", "full bundle adjustment: %s", full.status().message().c_str());
  }
  if (options.at_end) options.at_end(*estimator);
  out.trajectory = estimator->trajectory();
  out.timings = estimator->timings();
  out.counters = estimator->counters();
  return out;
}

}  // namespace hwr::estimation
