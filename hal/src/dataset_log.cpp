// open_dataset_log(): TUM RGB-D and EuRoC folders as ReplayLogs.
#include <sys/stat.h>

#include <memory>

#include "hwr/hal/euroc_dataset.hpp"
#include "hwr/hal/replay_source.hpp"
#include "hwr/hal/stereo_depth.hpp"
#include "hwr/hal/tum_dataset.hpp"

namespace hwr::hal {
namespace {

bool is_dir(const std::string& p) {
  struct stat st {};
  return ::stat(p.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

template <class T>
void fill_span(const std::vector<T>& v, SourceInfo* info) {
  if (v.empty()) return;
  if (info->first_t_ns == 0 || v.front().t_ns < info->first_t_ns) info->first_t_ns = v.front().t_ns;
  if (v.back().t_ns > info->last_t_ns) info->last_t_ns = v.back().t_ns;
}

core::Expected<ReplayLog> open_tum(const std::string& dir) {
  TumDatasetOptions options;
  options.intrinsics = tum_intrinsics_for(dir);
  auto ds = TumDataset::open(dir, options);
  if (!ds.ok()) return ds.status();
  auto shared = std::make_shared<TumDataset>(std::move(ds.value()));
  ReplayLog log;
  log.info.name = "tum:" + dir;
  log.info.intrinsics = shared->options().intrinsics;
  // TUM records a 3-axis accelerometer only (no gyro), so there is no IMU stream.
  log.info.camera_rate_hz = 30.0;
  for (size_t i = 0; i < shared->size(); ++i) log.frame_t_ns.push_back(shared->frame_time_ns(i));
  if (!log.frame_t_ns.empty()) {
    log.info.first_t_ns = log.frame_t_ns.front();
    log.info.last_t_ns = log.frame_t_ns.back();
  }
  log.load_frame = [shared](size_t i, RgbdFrame* out) { return shared->load_frame(i, out); };
  return log;
}

core::Expected<ReplayLog> open_euroc(std::string dir) {
  if (is_dir(dir + "/mav0")) dir += "/mav0";
  auto ds = EurocDataset::open(dir);
  if (!ds.ok()) return ds.status();
  auto shared = std::make_shared<EurocDataset>(std::move(ds.value()));
  ReplayLog log;
  log.info.name = "euroc:" + dir;
  log.imu = shared->imu();
  log.info.has_imu = !log.imu.empty();
  log.info.imu_rate_hz = shared->imu_calib().present ? shared->imu_calib().rate_hz : 200.0;
  log.info.camera_rate_hz = shared->cam0().rate_hz;
  fill_span(log.imu, &log.info);
  if (shared->has_stereo() && shared->size() > 0) {
    StereoRig rig;
    rig.left = shared->cam0().intrinsics;
    rig.right = shared->cam1().intrinsics;
    rig.T_left_right = shared->T_cam0_cam1();
    auto stereo = StereoDepth::create(rig);
    if (!stereo.ok())
      return core::Status(stereo.status().code(), dir + ": stereo rig: " + stereo.status().message());
    auto depth = std::make_shared<StereoDepth>(std::move(stereo.value()));
    log.info.stereo = true;
    log.info.intrinsics = depth->rectified_intrinsics();
    // The frames are in the rectified left camera: T_imu_rect = T_imu_body · T_body_cam0 · T_cam0_rect.
    log.info.T_imu_cam =
        shared->imu_calib().T_body_imu.inverse() * shared->cam0().T_body_cam * depth->T_cam0_rect();
    for (size_t i = 0; i < shared->size(); ++i) log.frame_t_ns.push_back(shared->frame_time_ns(i));
    log.info.first_t_ns = std::min(log.info.first_t_ns == 0 ? log.frame_t_ns.front() : log.info.first_t_ns,
                                   log.frame_t_ns.front());
    log.info.last_t_ns = std::max(log.info.last_t_ns, log.frame_t_ns.back());
    // Scratch images live with the loader (prefetch thread only).
    auto left = std::make_shared<cv::Mat>();
    auto right = std::make_shared<cv::Mat>();
    log.load_frame = [shared, depth, left, right](size_t i, RgbdFrame* out) {
      core::Status st = shared->load_stereo(i, left.get(), right.get());
      if (!st.ok()) return st;
      return depth->compute(*left, *right, shared->frame_time_ns(i), i, out);
    };
  }
  return log;
}

}  // namespace

core::Expected<ReplayLog> open_dataset_log(const std::string& spec) {
  const size_t colon = spec.find(':');
  if (colon == std::string::npos) {
    return core::InvalidArgument("source '" + spec + "': expected KIND:PATH with KIND tum or euroc");
  }
  const std::string kind = spec.substr(0, colon);
  const std::string path = spec.substr(colon + 1);
  if (!is_dir(path)) return core::NotFound(path + ": no such folder (source '" + spec + "')");
  if (kind == "tum") return open_tum(path);
  if (kind == "euroc") return open_euroc(path);
  return core::InvalidArgument("source '" + spec + "': unknown kind '" + kind + "' (tum, euroc)");
}

}  // namespace hwr::hal
