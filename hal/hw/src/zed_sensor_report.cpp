#include "hwr/hal/hw/zed_sensor_report.hpp"

#include <cstdint>
#include <cstring>
#include <limits>
#include <string>

namespace hwr::hal::hw {
namespace {

template <class T>
T read_le(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof v);  // the MCU and both targets (x86-64, aarch64) are little-endian
  return v;
}

std::optional<double> temperature(int16_t raw) {
  if (raw == kZedTempNotValid) return std::nullopt;
  return raw * kZedTempCPerCount;
}

ZedReadingState reading_state(uint8_t raw) {
  return raw <= 2 ? static_cast<ZedReadingState>(raw) : ZedReadingState::kUnknown;
}

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

__extension__ typedef unsigned __int128 u128;  // GCC/Clang on both targets; __extension__: -Wpedantic

}  // namespace

int64_t zed_ticks_to_ns(uint64_t ticks) {
  // ticks × 39062.5 = ticks × 78125 / 2; the product needs up to 64 + 17 bits.
  const u128 ns = static_cast<u128>(ticks) * 78125u / 2u;
  constexpr auto kMax = static_cast<u128>(std::numeric_limits<int64_t>::max());
  return ns > kMax ? std::numeric_limits<int64_t>::max() : static_cast<int64_t>(ns);
}

core::Expected<ZedSensorReport> parse_zed_sensor_report(const uint8_t* bytes, size_t n) {
  return parse_zed_sensor_report(bytes, n, nullptr);
}

core::Expected<ZedSensorReport> parse_zed_sensor_report(const uint8_t* bytes, size_t n,
                                                        ZedSensorReportCounters* counters) {
  if (bytes == nullptr || n < kZedSensorReportSize) {
    if (counters != nullptr) ++counters->too_short;
    return core::CorruptData("ZED sensor report: " + std::to_string(bytes == nullptr ? 0 : n) +
                             " bytes, need " + std::to_string(kZedSensorReportSize) +
                             " (a short USB transfer; the next report is read normally)");
  }
  if (bytes[0] != kZedSensorReportId) {
    if (counters != nullptr) ++counters->wrong_id;
    return core::ParseError("ZED sensor report: report id " + std::to_string(bytes[0]) +
                            ", expected 1 (sensor data)");
  }
  ZedSensorReport r;
  r.imu_not_valid_raw = bytes[1];
  r.imu_valid = r.imu_not_valid_raw == 0;
  r.timestamp_raw = read_le<uint64_t>(bytes + 2);
  r.t_imu_ns = zed_ticks_to_ns(r.timestamp_raw);
  for (size_t i = 0; i < 3; ++i) {
    r.gyro_raw[i] = read_le<int16_t>(bytes + 10 + 2 * i);
    r.accel_raw[i] = read_le<int16_t>(bytes + 16 + 2 * i);
    r.mag_raw[i] = read_le<int16_t>(bytes + 31 + 2 * i);
    const auto e = static_cast<Eigen::Index>(i);
    r.gyro_radps[e] = r.gyro_raw[i] * kZedGyroDegpsPerCount * kDegToRad;
    r.accel_mps2[e] = r.accel_raw[i] * kZedAccelMps2PerCount;
    r.mag_uT[e] = r.mag_raw[i] * kZedMagUtPerCount;
  }
  r.frame_sync_raw = bytes[22];
  r.frame_sync = r.frame_sync_raw != 0;
  r.sync_caps = bytes[23];
  r.frame_sync_count = read_le<uint32_t>(bytes + 24);
  r.imu_temp_raw = read_le<int16_t>(bytes + 28);
  r.imu_temp_c = temperature(r.imu_temp_raw);
  r.mag_valid_raw = bytes[30];
  r.mag_state = reading_state(r.mag_valid_raw);
  r.moving = bytes[37];
  r.moving_count = read_le<uint32_t>(bytes + 38);
  r.falling = bytes[42];
  r.falling_count = read_le<uint32_t>(bytes + 43);
  r.env_valid_raw = bytes[47];
  r.env_state = reading_state(r.env_valid_raw);
  r.env_temp_raw = read_le<int16_t>(bytes + 48);
  r.env_temp_c = temperature(r.env_temp_raw);
  r.pressure_raw = read_le<uint32_t>(bytes + 50);
  r.humidity_raw = read_le<uint32_t>(bytes + 54);
  r.camera_temp_left_raw = read_le<int16_t>(bytes + 58);
  r.camera_temp_right_raw = read_le<int16_t>(bytes + 60);
  r.camera_temp_left_c = temperature(r.camera_temp_left_raw);
  r.camera_temp_right_c = temperature(r.camera_temp_right_raw);
  if (counters != nullptr) {
    ++counters->parsed;
    if (!r.imu_valid) ++counters->imu_not_valid;
  }
  return r;
}

ZedReportMonitor::ZedReportMonitor(int64_t nominal_period_ns)
    : period_ns_(nominal_period_ns > 0 ? nominal_period_ns : 2'500'000) {}

ZedReportCheck ZedReportMonitor::observe(const ZedSensorReport& report) {
  ++counters_.reports;
  if (have_last_ && report.t_imu_ns == last_t_imu_ns_) {
    ++counters_.repeated;
    return ZedReportCheck::kRepeated;
  }
  if (report.frame_sync) ++counters_.sync_events;
  if (!have_last_) {
    have_last_ = true;
    last_t_imu_ns_ = report.t_imu_ns;
    last_sync_count_ = report.frame_sync_count;
    return ZedReportCheck::kNew;
  }
  ZedReportCheck result = ZedReportCheck::kNew;
  if (report.t_imu_ns < last_t_imu_ns_) {
    ++counters_.timestamp_restarts;
    result = ZedReportCheck::kRestarted;
  } else {
    // t > last, so the modular difference is the true step, even across the whole int64 range.
    const uint64_t step = static_cast<uint64_t>(report.t_imu_ns) - static_cast<uint64_t>(last_t_imu_ns_);
    const auto period = static_cast<uint64_t>(period_ns_);
    if (step > period + period / 2) {
      ++counters_.gaps;
      const uint64_t periods = step / period + (step % period >= period - period / 2 ? 1 : 0);  // rounded
      counters_.lost_reports_estimate += periods - 1;
    }
  }
  // frame_sync_count: +1 with each flagged report. Modular difference, so the 32-bit wrap (after
  // ~4.5 years at 30 fps) is an ordinary step; a "step" of more than 2^31 is the count going back.
  const uint32_t advance = report.frame_sync_count - last_sync_count_;
  if (result == ZedReportCheck::kRestarted || advance > 0x8000'0000u) {
    if (result != ZedReportCheck::kRestarted) ++counters_.sync_count_restarts;
  } else {
    const uint32_t flagged = report.frame_sync ? 1 : 0;
    if (advance > flagged) counters_.missed_sync_events += advance - flagged;
    if (report.frame_sync && advance == 0) ++counters_.sync_without_increment;
  }
  last_t_imu_ns_ = report.t_imu_ns;
  last_sync_count_ = report.frame_sync_count;
  return result;
}

hal::ImuSample to_imu_sample(const ZedSensorReport& report, int64_t t_ns) {
  hal::ImuSample s;
  s.t_ns = t_ns;
  s.gyro_radps = report.gyro_radps;
  s.accel_mps2 = report.accel_mps2;
  return s;
}

std::optional<hal::MagSample> to_mag_sample(const ZedSensorReport& report, int64_t t_ns) {
  if (report.mag_state != ZedReadingState::kNew) return std::nullopt;
  hal::MagSample m;
  m.t_ns = t_ns;
  m.field_uT = report.mag_uT;
  return m;
}

}  // namespace hwr::hal::hw
