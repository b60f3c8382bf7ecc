#include "hwr/hal/hw/zed_sensor_report.hpp"

#include <cstdint>
#include <cstring>
#include <string>

namespace hwr::hal::hw {
namespace {

template <class T>
T read_le(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof v);  // the MCU and both targets (x86-64, aarch64) are little-endian
  return v;
}

std::optional<double> temperature(const uint8_t* p) {
  const int16_t raw = read_le<int16_t>(p);
  if (raw == kZedTempNotValid) return std::nullopt;
  return raw * kZedTempCPerCount;
}

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

}  // namespace

core::Expected<ZedSensorReport> parse_zed_sensor_report(const uint8_t* bytes, size_t n) {
  if (bytes == nullptr || n < kZedSensorReportSize) {
    return core::CorruptData("ZED sensor report: " + std::to_string(n) + " bytes, need " +
                             std::to_string(kZedSensorReportSize));
  }
  if (bytes[0] != kZedSensorReportId) {
    return core::ParseError("ZED sensor report: report id " + std::to_string(bytes[0]) + ", expected 1");
  }
  ZedSensorReport r;
  r.imu_valid = bytes[1] == 0;
  r.timestamp_raw = read_le<uint64_t>(bytes + 2);
  // raw × 39062.5 = (raw / 2) × 78125 + (raw % 2) × 39062 (the half nanosecond of an odd tick
  // dropped), saturated where it would not fit int64 (the 64-bit tick counter needs ~11 000 years).
  const uint64_t half = r.timestamp_raw / 2;
  r.t_imu_ns = half > static_cast<uint64_t>(INT64_MAX / 78125 - 1)
                   ? INT64_MAX
                   : static_cast<int64_t>(half) * 78125 + static_cast<int64_t>(r.timestamp_raw % 2) * 39062;
  for (int i = 0; i < 3; ++i) {
    r.gyro_radps[i] = read_le<int16_t>(bytes + 10 + 2 * i) * kZedGyroDegpsPerCount * kDegToRad;
    r.accel_mps2[i] = read_le<int16_t>(bytes + 16 + 2 * i) * kZedAccelMps2PerCount;
    r.mag_uT[i] = read_le<int16_t>(bytes + 31 + 2 * i) * kZedMagUtPerCount;
  }
  r.frame_sync = bytes[22] != 0;
  r.sync_caps = bytes[23];
  r.frame_sync_count = read_le<uint32_t>(bytes + 24);
  r.imu_temp_c = temperature(bytes + 28);
  r.mag_state = bytes[30] <= 2 ? static_cast<ZedMagState>(bytes[30]) : ZedMagState::kNone;
  r.moving = bytes[37];
  r.moving_raw = read_le<uint32_t>(bytes + 38);
  r.falling = bytes[42];
  r.falling_raw = read_le<uint32_t>(bytes + 43);
  r.env_state = bytes[47];
  r.env_temp_c = temperature(bytes + 48);
  r.pressure_raw = read_le<uint32_t>(bytes + 50);
  r.humidity_raw = read_le<uint32_t>(bytes + 54);
  r.camera_temp_left_c = temperature(bytes + 58);
  r.camera_temp_right_c = temperature(bytes + 60);
  return r;
}

hal::ImuSample to_imu_sample(const ZedSensorReport& report, int64_t t_ns) {
  hal::ImuSample s;
  s.t_ns = t_ns;
  s.gyro_radps = report.gyro_radps;
  s.accel_mps2 = report.accel_mps2;
  return s;
}

std::optional<hal::MagSample> to_mag_sample(const ZedSensorReport& report, int64_t t_ns) {
  if (report.mag_state != ZedMagState::kNew) return std::nullopt;
  hal::MagSample m;
  m.t_ns = t_ns;
  m.field_uT = report.mag_uT;
  return m;
}

}  // namespace hwr::hal::hw
