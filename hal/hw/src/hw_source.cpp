#include "hwr/hal/hw/hw_source.hpp"

#include <chrono>
#include <limits>

#include "hwr/core/log.hpp"
#include "hwr/hal/hw/a9_reader.hpp"
#include "hwr/hal/hw/gnss_reader.hpp"
#include "hwr/hal/hw/tty_port.hpp"
#include "hwr/hal/hw/usb_hid.hpp"
#include "hwr/hal/hw/zed_camera_reader.hpp"
#include "hwr/hal/hw/zed_sensor_reader.hpp"

namespace hwr::hal::hw {
namespace {

int64_t monotonic_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

constexpr double kA9RateHz = 150.0;         // hardware.md: ~150 Hz
constexpr double kZedSensorRateHz = 400.0;  // hardware.md: sensor reports ~400 Hz

}  // namespace

core::Expected<std::unique_ptr<HwSource>> HwSource::open(const HwConfig& config, const std::string& name,
                                                         int64_t now_ns) {
  return open(config, name, now_ns, nullptr);
}

core::Expected<std::unique_ptr<HwSource>> HwSource::open(const HwConfig& config, const std::string& name,
                                                         int64_t now_ns, std::unique_ptr<UsbHidOps> zed_usb) {
  std::unique_ptr<HwSource> s(new HwSource());
  s->config_ = config;
  SourceInfo& info = s->info_;
  info.name = name;
  info.first_t_ns = now_ns;
  info.last_t_ns = std::numeric_limits<int64_t>::max() / 4;  // live: no end
  info.gnss_antenna_imu_m = config.gnss_antenna_imu_m;
  info.mag_hard_iron_uT = config.mag_hard_iron_uT;
  info.T_imu_cam = config.T_imu_cam;
  if (config.camera.enabled) {
    auto cam = ZedCameraReader::open(config);
    if (!cam.ok()) return cam.status();
    s->camera_ = std::move(cam.value());
    info.intrinsics = s->camera_->rectified_intrinsics();
    info.T_imu_cam = config.T_imu_cam * s->camera_->T_cam_rect();  // the pipeline sees the rectified left
    info.stereo = true;
    info.camera_rate_hz = config.camera.fps;
  }
  if (config.zed_sensors) {
    s->zed_sensors_ = std::make_unique<ZedSensorReader>(zed_usb ? std::move(zed_usb) : make_libusb_hid_ops(),
                                                        ZedSensorOutputs{});
    if (core::Status st = s->zed_sensors_->open(now_ns); !st.ok()) {
      return core::Status(st.code(), "zed_sensors: " + st.message());
    }
    if (config.imu == ImuKind::kZed) {
      info.has_imu = true;
      info.imu_rate_hz = kZedSensorRateHz;
      info.has_mag = true;
    }
    if (s->camera_) s->frame_stamps_ = std::make_unique<core::SpscRing<CameraFrameStamp>>(64);
  }
  if (config.a9_enabled) {
    auto port = TtyPort::open(config.a9_device, config.a9_baud);
    if (!port.ok()) return core::Status(port.status().code(), "a9: " + port.status().message());
    s->a9_port_ = std::move(port.value());
    if (config.imu == ImuKind::kA9) {
      info.has_imu = true;
      info.imu_rate_hz = kA9RateHz;
    }
  }
  if (config.gnss_enabled) {
    auto port = TtyPort::open(config.gnss_device, config.gnss_baud);
    if (!port.ok()) return core::Status(port.status().code(), "gnss: " + port.status().message());
    s->gnss_port_ = std::move(port.value());
    info.has_gnss = true;
  }
  return s;
}

HwSource::~HwSource() { stop(); }

void HwSource::fail(const core::Status& st) {
  {
    std::lock_guard<std::mutex> lock(error_mutex_);
    if (error_.ok()) error_ = st;
  }
  failed_.store(true, std::memory_order_release);
}

template <class Step>
void HwSource::run_thread(const char* what, Step step) {
  threads_.emplace_back([this, what, step]() mutable {
    while (!stop_.load(std::memory_order_acquire)) {
      core::Status st = step(monotonic_ns());
      if (!st.ok()) {
        HWR_LOG_ERROR("hw", "%s: %s", what, st.message().c_str());
        // The GNSS reader reports a refused configuration once and goes on; everything else stops.
        if (std::string(what) != "gnss") {
          fail(st);
          return;
        }
      }
    }
  });
}

core::Status HwSource::start(SensorStreams* streams) {
  if (!threads_.empty()) return core::InvalidArgument("hw source: already started");
  if (camera_) {
    const auto& K = info_.intrinsics;
    if (streams->config().width != K.width || streams->config().height != K.height ||
        !streams->config().stereo) {
      return core::InvalidArgument("hw source: the frame pool is not sized for the camera's rectified " +
                                   std::to_string(K.width) + "x" + std::to_string(K.height) +
                                   " stereo frames");
    }
    if (frame_stamps_) camera_->set_frame_stamps(frame_stamps_.get());
    run_thread("camera", [this, streams](int64_t now) { return camera_->step(now, streams); });
  }
  if (zed_sensors_) {
    ZedSensorOutputs out;
    if (config_.imu == ImuKind::kZed) {  // only the estimator's IMU writes the IMU ring
      out.imu = &streams->imu;
      out.mag = &streams->mag;
    }
    out.frame_stamps = frame_stamps_.get();
    zed_sensors_->set_outputs(out);
    run_thread("zed_sensors", [this](int64_t now) { return zed_sensors_->step(now); });
  }
  if (a9_port_ && config_.imu == ImuKind::kA9) {  // only the estimator's IMU writes the IMU ring
    a9_ = std::make_unique<A9Reader>(std::move(a9_port_), &streams->imu);
    run_thread("a9", [this](int64_t now) { return a9_->step(now); });
  }
  if (gnss_port_) {
    GnssReaderOptions o;
    o.rate_hz = config_.gnss_rate_hz;
    o.configure = config_.gnss_configure;
    gnss_ = std::make_unique<GnssReader>(std::move(gnss_port_), &streams->gnss, o);
    run_thread("gnss", [this](int64_t now) { return gnss_->step(now); });
  }
  return core::Status::Ok();
}

void HwSource::stop() {
  stop_.store(true, std::memory_order_release);
  for (std::thread& t : threads_) {
    if (t.joinable()) t.join();
  }
  threads_.clear();
}

core::Status HwSource::poll(int64_t /*until_ns*/, SensorStreams* /*streams*/) {
  if (!failed_.load(std::memory_order_acquire)) return core::Status::Ok();
  std::lock_guard<std::mutex> lock(error_mutex_);
  return error_;
}

SourceCounters HwSource::counters() const {
  SourceCounters c;
  if (camera_) {
    const ZedCameraCounters z = camera_->counters();
    c.frames = z.frames;
    c.frames_dropped = z.pool_empty + z.ring_full;
    c.frame_errors = z.depth_errors + z.incomplete + z.bad_timestamps;
  }
  if (a9_ && config_.imu == ImuKind::kA9) c.imu = a9_->counters().samples;
  if (zed_sensors_ && config_.imu == ImuKind::kZed) {
    const ZedSensorReaderCounters z = zed_sensors_->counters();
    c.imu = z.imu_samples;
    c.mag = z.mag_samples;
  }
  if (gnss_) c.gnss = gnss_->counters().fixes;
  return c;
}

HwSourceCounters HwSource::hw_counters() const {
  HwSourceCounters h;
  if (camera_) {
    const ZedCameraCounters z = camera_->counters();
    h.camera_disconnects = z.disconnects;
    h.camera_reconnects = z.reconnects;
    h.camera_incomplete = z.incomplete;
    h.camera_driver_dropped = z.driver_dropped;
  }
  if (a9_) {
    h.a9_disconnects = a9_->counters().disconnects;
    h.a9_crc_errors = a9_->counters().crc_errors;
  }
  if (zed_sensors_) {
    const ZedSensorReaderCounters z = zed_sensors_->counters();
    h.zed_sensor_disconnects = z.disconnects;
    h.zed_sensor_reports_dropped = z.repeated + z.imu_not_valid + z.parse_errors + z.out_of_order;
    h.zed_clock_synced = z.sync_locked;
    h.zed_clock_drift_ppm = z.sync_drift_ppm;
  }
  if (gnss_) {
    h.gnss_disconnects = gnss_->counters().disconnects;
    h.gnss_fixes_from_gga = gnss_->counters().fixes_from_gga;
  }
  return h;
}

}  // namespace hwr::hal::hw
