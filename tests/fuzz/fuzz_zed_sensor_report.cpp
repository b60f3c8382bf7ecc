// libFuzzer target: the ZED 2i HID sensor report (hal/hw/zed_sensor_report.hpp) and ZedReportMonitor.
// The whole input is one report buffer (parse_zed_sensor_report with counters); then the input is
// cut into 62-byte reports, as the interrupt endpoint would deliver them, and every parsed one is fed
// to a ZedReportMonitor. Oracle: a second decoder in this file, written from hardware.md's layout
// with shifts (no memcpy), must agree with every raw field; the SI values must equal raw × the
// documented scale and stay within the full scales; outcomes must follow the size and id rules and
// be counted once; the monitor's counters must account for every report.
// Seeds: make_zed_report_seeds.cpp.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <optional>

#include "hwr/hal/hw/zed_sensor_report.hpp"

namespace {

using hwr::hal::hw::ZedSensorReport;

uint64_t le(const uint8_t* p, int n) {
  uint64_t v = 0;
  for (int i = n - 1; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
int16_t le16s(const uint8_t* p) { return static_cast<int16_t>(static_cast<uint16_t>(le(p, 2))); }

void check(bool ok) {
  if (!ok) std::abort();
}

std::optional<double> temp(const uint8_t* p) {
  const int16_t raw = le16s(p);
  if (raw == -27315) return std::nullopt;
  return raw * 0.01;
}

// Every field against the second decoder.
void check_against_oracle(const uint8_t* b, const ZedSensorReport& r) {
  constexpr double kDeg = 3.14159265358979323846 / 180.0;
  check(r.imu_not_valid_raw == b[1] && r.imu_valid == (b[1] == 0));
  check(r.timestamp_raw == le(b + 2, 8));
  check(r.t_imu_ns >= 0);
  // floor(raw · 39062.5) where it fits int64: (raw / 2) · 78125 + (raw mod 2) · 39062.
  const uint64_t raw = r.timestamp_raw;
  if (raw / 2 <= static_cast<uint64_t>(INT64_MAX / 78125 - 1)) {
    check(r.t_imu_ns == static_cast<int64_t>(raw / 2) * 78125 + static_cast<int64_t>(raw % 2) * 39062);
  } else {
    check(r.t_imu_ns >= INT64_MAX - 78125);
  }
  for (int i = 0; i < 3; ++i) {
    const int16_t g = le16s(b + 10 + 2 * i), a = le16s(b + 16 + 2 * i), m = le16s(b + 31 + 2 * i);
    check(r.gyro_raw[static_cast<size_t>(i)] == g && r.accel_raw[static_cast<size_t>(i)] == a &&
          r.mag_raw[static_cast<size_t>(i)] == m);
    check(r.gyro_radps[i] == g * (1000.0 / 32768.0) * kDeg);
    check(r.accel_mps2[i] == a * (9.8189 * 8.0 / 32768.0));
    check(r.mag_uT[i] == m * (1.0 / 16.0));
    check(std::fabs(r.gyro_radps[i]) <= 1000.0 * kDeg + 1e-9);
    check(std::fabs(r.accel_mps2[i]) <= 8 * 9.8189 + 1e-9);
  }
  check(r.frame_sync_raw == b[22] && r.frame_sync == (b[22] != 0) && r.sync_caps == b[23]);
  check(r.frame_sync_count == le(b + 24, 4));
  check(r.imu_temp_raw == le16s(b + 28) && r.imu_temp_c == temp(b + 28));
  check(r.mag_valid_raw == b[30]);
  check(static_cast<uint8_t>(r.mag_state) == (b[30] <= 2 ? b[30] : 255));
  check(r.moving == b[37] && r.moving_count == le(b + 38, 4));
  check(r.falling == b[42] && r.falling_count == le(b + 43, 4));
  check(r.env_valid_raw == b[47] && static_cast<uint8_t>(r.env_state) == (b[47] <= 2 ? b[47] : 255));
  check(r.env_temp_raw == le16s(b + 48) && r.env_temp_c == temp(b + 48));
  check(r.pressure_raw == le(b + 50, 4) && r.humidity_raw == le(b + 54, 4));
  check(r.camera_temp_left_c == temp(b + 58) && r.camera_temp_right_c == temp(b + 60));

  const hwr::hal::ImuSample s = hwr::hal::hw::to_imu_sample(r, r.t_imu_ns);
  check(s.t_ns == r.t_imu_ns && s.gyro_radps == r.gyro_radps && s.accel_mps2 == r.accel_mps2);
  const auto mag = hwr::hal::hw::to_mag_sample(r, 1);
  check(mag.has_value() == (b[30] == 2));
  if (mag) check(mag->field_uT == r.mag_uT && mag->t_ns == 1);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace hwr::hal::hw;
  // 1. The whole input as one report buffer.
  ZedSensorReportCounters counters;
  auto r = parse_zed_sensor_report(data, size, &counters);
  if (size < kZedSensorReportSize) {
    check(!r.ok() && r.status().code() == hwr::core::ErrorCode::kCorruptData && counters.too_short == 1);
  } else if (data[0] != kZedSensorReportId) {
    check(!r.ok() && r.status().code() == hwr::core::ErrorCode::kParseError && counters.wrong_id == 1);
  } else {
    check(r.ok() && counters.parsed == 1 && counters.imu_not_valid == (data[1] != 0 ? 1u : 0u));
    check_against_oracle(data, *r);
  }
  check(counters.parsed + counters.too_short + counters.wrong_id == 1);
  if (!r.ok()) check(!r.status().message().empty());

  // 2. The input as a stream of 62-byte reports through the monitor.
  ZedReportMonitor monitor;
  uint64_t observed = 0, repeated = 0, restarted = 0;
  for (size_t off = 0; off + kZedSensorReportSize <= size; off += kZedSensorReportSize) {
    auto one = parse_zed_sensor_report(data + off, kZedSensorReportSize);
    if (!one.ok()) continue;
    check_against_oracle(data + off, *one);
    ++observed;
    const ZedReportCheck c = monitor.observe(*one);
    repeated += c == ZedReportCheck::kRepeated ? 1 : 0;
    restarted += c == ZedReportCheck::kRestarted ? 1 : 0;
  }
  const ZedReportMonitorCounters& m = monitor.counters();
  check(m.reports == observed && m.repeated == repeated && m.timestamp_restarts == restarted);
  check(m.sync_events <= observed - m.repeated);
  check(m.gaps <= observed && m.lost_reports_estimate >= m.gaps);
  check(m.sync_without_increment <= m.sync_events);
  return 0;
}
