#include "hwr/hal/hw/zed_sensor_reader.hpp"

#include <chrono>

#include "hwr/core/log.hpp"

namespace hwr::hal::hw {
namespace {

bool is_unplug(const core::Status& st) {
  return st.code() == core::ErrorCode::kUnavailable || st.code() == core::ErrorCode::kNotFound;
}

}  // namespace

ZedSensorReader::ZedSensorReader(std::unique_ptr<UsbHidOps> usb, const ZedSensorOutputs& outputs,
                                 const ZedHidConfig& hid, const CameraClockSyncConfig& sync, Clock clock)
    : usb_(std::move(usb)), clock_(std::move(clock)), hid_(*usb_, hid), out_(outputs), sync_(sync) {}

int64_t ZedSensorReader::monotonic_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

core::Status ZedSensorReader::open(int64_t now_ns) {
  HWR_RETURN_IF_ERROR(hid_.start(now_ns));
  restart_clocks();
  connected_.store(true, std::memory_order_relaxed);
  return core::Status::Ok();
}

void ZedSensorReader::restart_clocks() {
  monitor_.reset();
  receipt_map_.reset();
  sync_.reset();
}

void ZedSensorReader::drain_frame_stamps() {
  if (out_.frame_stamps == nullptr) return;
  CameraFrameStamp stamp;
  while (out_.frame_stamps->try_pop(stamp)) {
    sync_.add_frame(stamp.t_host_ns, stamp.sequence);
    frame_stamps_.fetch_add(1, std::memory_order_relaxed);
  }
}

void ZedSensorReader::handle_report(const uint8_t* bytes, size_t n, int64_t t_receipt_ns) {
  auto parsed = parse_zed_sensor_report(bytes, n);
  if (!parsed.ok()) {
    parse_errors_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  const ZedSensorReport& report = parsed.value();
  switch (monitor_.observe(report)) {
    case ZedReportCheck::kRepeated:
      repeated_.fetch_add(1, std::memory_order_relaxed);
      return;
    case ZedReportCheck::kRestarted:  // the MCU's clock went back: both maps start over
      clock_restarts_.fetch_add(1, std::memory_order_relaxed);
      receipt_map_.reset();
      sync_.reset();
      break;
    case ZedReportCheck::kNew:
      break;
  }
  gaps_.store(monitor_.counters().gaps, std::memory_order_relaxed);
  missed_sync_events_.store(monitor_.counters().missed_sync_events, std::memory_order_relaxed);

  // Every report's receipt feeds both maps; a flagged one is also a sync event.
  sync_.add_report(report, t_receipt_ns);
  const int64_t t_by_receipt_ns = receipt_map_.map(report.t_imu_ns, t_receipt_ns);
  const std::optional<int64_t> t_by_sync_ns = sync_.to_host_clock(report.t_imu_ns);
  const int64_t t_ns = t_by_sync_ns ? *t_by_sync_ns : t_by_receipt_ns;
  const CameraClockEstimate& e = sync_.estimate();
  sync_locked_.store(e.locked, std::memory_order_relaxed);
  if (e.locked) {
    sync_drift_ppm_.store(e.drift_ppm, std::memory_order_relaxed);
    sync_residual_rms_ns_.store(e.residual_rms_ns, std::memory_order_relaxed);
  }

  if (t_ns <= last_pushed_ns_) {
    out_of_order_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  bool pushed = false;
  if (report.imu_valid) {
    if (out_.imu != nullptr) out_.imu->push_drop_oldest(to_imu_sample(report, t_ns));
    imu_samples_.fetch_add(1, std::memory_order_relaxed);
    if (t_by_sync_ns) synced_samples_.fetch_add(1, std::memory_order_relaxed);
    pushed = true;
  } else {
    imu_not_valid_.fetch_add(1, std::memory_order_relaxed);
  }
  if (const std::optional<MagSample> mag = to_mag_sample(report, t_ns)) {
    if (out_.mag != nullptr) out_.mag->push_drop_oldest(*mag);
    mag_samples_.fetch_add(1, std::memory_order_relaxed);
    pushed = true;
  }
  if (pushed) last_pushed_ns_ = t_ns;
}

core::Status ZedSensorReader::step(int64_t now_ns, int read_timeout_ms) {
  if (!connected_.load(std::memory_order_relaxed)) {
    if (!backoff_.due(now_ns)) {
      backoff_.wait_until_due(now_ns, read_timeout_ms);
      drain_frame_stamps();  // keep the camera's ring from filling while the MCU is away
      return core::Status::Ok();
    }
    if (core::Status st = hid_.start(now_ns); !st.ok()) {
      backoff_.failed(now_ns);
      return is_unplug(st) ? core::Status::Ok() : st;
    }
    backoff_.succeeded();
    restart_clocks();  // a replugged MCU restarts its clock
    connected_.store(true, std::memory_order_relaxed);
    reconnects_.store(hid_.counters().reconnects, std::memory_order_relaxed);
    HWR_LOG_INFO("zed-sensors", "reconnected");
  }
  core::Status st = hid_.keep_alive(now_ns);
  core::Expected<size_t> n =
      st.ok() ? hid_.read_report(buf_.data(), read_timeout_ms) : core::Expected<size_t>(st);
  keep_alives_.store(hid_.counters().keep_alives, std::memory_order_relaxed);
  if (!n.ok()) {
    if (n.status().code() == core::ErrorCode::kCorruptData) {  // an over-long report: skip it
      parse_errors_.fetch_add(1, std::memory_order_relaxed);
      return core::Status::Ok();
    }
    if (n.status().code() != core::ErrorCode::kUnavailable) return n.status();
    connected_.store(false, std::memory_order_relaxed);
    disconnects_.store(hid_.counters().disconnects, std::memory_order_relaxed);
    backoff_.failed(now_ns);
    HWR_LOG_WARN("zed-sensors", "%s; reconnecting", n.status().message().c_str());
    return core::Status::Ok();
  }
  drain_frame_stamps();
  if (n.value() == 0) return core::Status::Ok();  // nothing within the timeout
  // The receipt time is when the read returned (now_ns was taken before the blocking read).
  handle_report(buf_.data(), n.value(), clock_());
  return core::Status::Ok();
}

ZedSensorReaderCounters ZedSensorReader::counters() const {
  ZedSensorReaderCounters c;
  c.imu_samples = imu_samples_.load(std::memory_order_relaxed);
  c.mag_samples = mag_samples_.load(std::memory_order_relaxed);
  c.parse_errors = parse_errors_.load(std::memory_order_relaxed);
  c.imu_not_valid = imu_not_valid_.load(std::memory_order_relaxed);
  c.repeated = repeated_.load(std::memory_order_relaxed);
  c.out_of_order = out_of_order_.load(std::memory_order_relaxed);
  c.clock_restarts = clock_restarts_.load(std::memory_order_relaxed);
  c.gaps = gaps_.load(std::memory_order_relaxed);
  c.missed_sync_events = missed_sync_events_.load(std::memory_order_relaxed);
  c.frame_stamps = frame_stamps_.load(std::memory_order_relaxed);
  c.synced_samples = synced_samples_.load(std::memory_order_relaxed);
  c.disconnects = disconnects_.load(std::memory_order_relaxed);
  c.reconnects = reconnects_.load(std::memory_order_relaxed);
  c.keep_alives = keep_alives_.load(std::memory_order_relaxed);
  c.sync_locked = sync_locked_.load(std::memory_order_relaxed);
  c.sync_drift_ppm = sync_drift_ppm_.load(std::memory_order_relaxed);
  c.sync_residual_rms_ns = sync_residual_rms_ns_.load(std::memory_order_relaxed);
  return c;
}

}  // namespace hwr::hal::hw
