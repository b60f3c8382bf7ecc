#pragma once
// One input report of the ZED 2i's sensor MCU (USB HID 2b03:f881, report id 0x01, 62 bytes, packed
// little-endian, ~400 Hz). Layout and scales from hardware.md "Sensors over HID" (from
// stereolabs/zed-open-capture); every field keeps its raw value and its SI conversion.
//   0 id | 1 imu_not_valid | 2 u64 timestamp | 10,12,14 i16 gyro xyz | 16,18,20 i16 accel xyz |
//   22 frame_sync | 23 sync_caps | 24 u32 frame_sync_count | 28 i16 imu_temp | 30 mag_valid |
//   31,33,35 i16 mag xyz | 37 moving | 38 u32 | 42 falling | 43 u32 | 47 env_valid | 48 i16 temp |
//   50 u32 pressure | 54 u32 humidity | 58,60 i16 camera temperatures (left, right)

#include <cstddef>
#include <cstdint>
#include <optional>

#include <Eigen/Core>

#include "hwr/core/status.hpp"
#include "hwr/hal/imu_sample.hpp"
#include "hwr/hal/mag_sample.hpp"

namespace hwr::hal::hw {

inline constexpr uint8_t kZedSensorReportId = 0x01;
inline constexpr size_t kZedSensorReportSize = 62;

// Scales (hardware.md): accel 9.8189·8/32768 m/s² per count (±8 g), gyro 1000/32768 °/s per count
// (±1000 °/s), magnetometer 1/16 µT, temperatures 0.01 °C, timestamp ns = raw × 39062.5.
inline constexpr double kZedAccelMps2PerCount = 9.8189 * 8.0 / 32768.0;
inline constexpr double kZedGyroDegpsPerCount = 1000.0 / 32768.0;
inline constexpr double kZedMagUtPerCount = 1.0 / 16.0;
inline constexpr double kZedTempCPerCount = 0.01;
inline constexpr int16_t kZedTempNotValid = -27315;  // −273.15 °C: the MCU's "no reading"

enum class ZedMagState : uint8_t { kNone = 0, kOld = 1, kNew = 2 };

struct ZedSensorReport {
  bool imu_valid = false;      // byte 1 == 0
  uint64_t timestamp_raw = 0;  // MCU ticks of 39062.5 ns (hardware.md)
  int64_t t_imu_ns = 0;        // timestamp_raw × 39062.5, floored to ns (the MCU's clock, not the host's)
  Eigen::Vector3d gyro_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_mps2 = Eigen::Vector3d::Zero();
  bool frame_sync = false;  // this sample was taken at a camera frame's exposure
  uint8_t sync_caps = 0;
  uint32_t frame_sync_count = 0;  // frames the MCU has seen, incremented with frame_sync
  std::optional<double> imu_temp_c;
  ZedMagState mag_state = ZedMagState::kNone;
  Eigen::Vector3d mag_uT = Eigen::Vector3d::Zero();  // meaningful when mag_state != kNone
  uint8_t moving = 0, falling = 0;
  uint32_t moving_raw = 0, falling_raw = 0;  // bytes 38 and 43: undocumented, kept raw
  uint8_t env_state = 0;                     // 0 none, 1 old, 2 new (as mag_valid)
  std::optional<double> env_temp_c;
  // Pressure and humidity scales depend on the MCU firmware (zed-open-capture: pressure 0.0001 hPa
  // per count and humidity 0.01 %rH from firmware 3.9 on, 0.01 hPa and 1/1024 %rH before): raw here,
  // converted by pressure_hpa / humidity_percent with the firmware the device reports.
  uint32_t pressure_raw = 0;
  uint32_t humidity_raw = 0;
  std::optional<double> camera_temp_left_c, camera_temp_right_c;

  double pressure_hpa(bool firmware_at_least_3_9) const {
    return pressure_raw * (firmware_at_least_3_9 ? 1e-4 : 1e-2);
  }
  double humidity_percent(bool firmware_at_least_3_9) const {
    return humidity_raw * (firmware_at_least_3_9 ? 1e-2 : 1.0 / 1024.0);
  }
};

// bytes: one report as read from the interrupt endpoint (n ≥ 62; the 64-byte transfer's padding
// is ignored). Errors: too short (kCorruptData), another report id (kParseError). Every other
// byte pattern is a representable reading (integers only), so nothing else is refused here.
core::Expected<ZedSensorReport> parse_zed_sensor_report(const uint8_t* bytes, size_t n);

// The report's IMU sample at t_ns (the caller's timeline; see camera_clock_sync). ZED 2i axes as
// sent (the MCU's IMU frame): T_imu_cam in config/hw.yaml relates them to the left camera.
hal::ImuSample to_imu_sample(const ZedSensorReport& report, int64_t t_ns);
// The magnetometer only when this report carries a new reading.
std::optional<hal::MagSample> to_mag_sample(const ZedSensorReport& report, int64_t t_ns);

}  // namespace hwr::hal::hw
