#include "hwr/sim/sim_run_replay.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <memory>

#include "hwr/hal/sensor_csv.hpp"
#include "hwr/hal/tum_dataset.hpp"

namespace hwr::sim {
namespace {

bool exists(const std::string& p) {
  struct stat st {};
  return ::stat(p.c_str(), &st) == 0;
}

template <class T>
void widen_span(const std::vector<T>& v, hal::SourceInfo* info) {
  if (v.empty()) return;
  if (info->first_t_ns == 0 || v.front().t_ns < info->first_t_ns) info->first_t_ns = v.front().t_ns;
  info->last_t_ns = std::max(info->last_t_ns, v.back().t_ns);
}

}  // namespace

core::Expected<SimRunLog> open_sim_run_log(const std::string& dir) {
  if (!exists(dir + "/calibration.yaml")) {
    return core::NotFound(dir + ": not a simulator run (no calibration.yaml); write one with hwr-sim --out " +
                          dir);
  }
  auto calib = load_sim_calibration(dir + "/calibration.yaml");
  if (!calib.ok()) return calib.status();

  SimRunLog out;
  out.calibration = calib.value();
  hal::ReplayLog& log = out.log;
  log.info.name = "sim:" + dir;
  log.info.intrinsics = calib->intrinsics;
  log.info.T_imu_cam = calib->T_imu_cam;
  log.info.gnss_antenna_imu_m = calib->gnss_antenna_imu_m;
  log.info.mag_hard_iron_uT = calib->mag_hard_iron_uT;
  log.info.camera_rate_hz = calib->camera_rate_hz;
  log.info.imu_rate_hz = calib->imu_rate_hz;

  if (exists(dir + "/rgb.txt")) {
    hal::TumDatasetOptions opt;
    opt.intrinsics = calib->intrinsics;
    opt.depth_scale = calib->depth_scale;
    opt.max_association_dt_s = 0.5 / std::max(1.0, calib->camera_rate_hz);
    auto ds = hal::TumDataset::open(dir, opt);
    if (!ds.ok()) return ds.status();
    auto shared = std::make_shared<hal::TumDataset>(std::move(ds.value()));
    for (size_t i = 0; i < shared->size(); ++i) log.frame_t_ns.push_back(shared->frame_time_ns(i));
    if (!log.frame_t_ns.empty()) {
      log.info.first_t_ns = log.frame_t_ns.front();
      log.info.last_t_ns = log.frame_t_ns.back();
    }
    log.load_frame = [shared](size_t i, hal::RgbdFrame* f) { return shared->load_frame(i, f); };
  }
  if (exists(dir + "/imu.csv")) {
    auto imu = hal::read_imu_csv(dir + "/imu.csv");
    if (!imu.ok()) return imu.status();
    log.imu = std::move(imu.value());
    log.info.has_imu = !log.imu.empty();
    widen_span(log.imu, &log.info);
  }
  if (exists(dir + "/mag.csv")) {
    auto mag = hal::read_mag_csv(dir + "/mag.csv");
    if (!mag.ok()) return mag.status();
    log.mag = std::move(mag.value());
    log.info.has_mag = !log.mag.empty();
    widen_span(log.mag, &log.info);
  }
  if (exists(dir + "/gnss.csv")) {
    auto gnss = hal::read_gnss_csv(dir + "/gnss.csv");
    if (!gnss.ok()) return gnss.status();
    log.gnss = std::move(gnss.value());
    log.info.has_gnss = !log.gnss.empty();
    widen_span(log.gnss, &log.info);
  }
  if (log.frame_t_ns.empty() && log.imu.empty()) {
    return core::NotFound(dir + ": the run has neither images (rgb.txt) nor imu.csv");
  }
  return out;
}

}  // namespace hwr::sim
