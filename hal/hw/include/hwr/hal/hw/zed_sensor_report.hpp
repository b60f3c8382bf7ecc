#pragma once
// One input report of the ZED 2i's sensor MCU (USB HID 2b03:f881, report id 0x01, 62 bytes, packed
// little-endian, ~400 Hz). Layout and scales from hardware.md "Sensors over HID", which follows
// stereolabs/zed-open-capture include/sensorcapture_def.hpp (struct SensData, #pragma pack(1)):
//   0 id | 1 imu_not_valid | 2 u64 timestamp | 10,12,14 i16 gyro xyz | 16,18,20 i16 accel xyz |
//   22 frame_sync | 23 sync_caps | 24 u32 frame_sync_count | 28 i16 imu_temp | 30 mag_valid |
//   31,33,35 i16 mag xyz | 37 moving | 38 u32 moving count | 42 falling | 43 u32 falling count |
//   47 env_valid | 48 i16 temp | 50 u32 pressure | 54 u32 humidity | 58,60 i16 camera temperatures
// Every field keeps its raw value next to its SI conversion, so nothing the MCU sent is lost.

#include <array>
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

// Scales (hardware.md; zed-open-capture ACC_SCALE, GYRO_SCALE, MAG_SCALE, TEMP_SCALE, TS_SCALE):
// accel 9.8189·8/32768 m/s² per count (±8 g), gyro 1000/32768 °/s per count (±1000 °/s),
// magnetometer 1/16 µT per count, temperatures 0.01 °C per count, timestamp 39062.5 ns per tick.
inline constexpr double kZedAccelMps2PerCount = 9.8189 * 8.0 / 32768.0;
inline constexpr double kZedGyroDegpsPerCount = 1000.0 / 32768.0;
inline constexpr double kZedMagUtPerCount = 1.0 / 16.0;
inline constexpr double kZedTempCPerCount = 0.01;
// zed-open-capture TEMP_NOT_VALID: −273.15 °C, the MCU's "no reading" for every temperature field.
inline constexpr int16_t kZedTempNotValid = -27315;

// mag_valid and env_valid (zed-open-capture: 0 no sensor / no data, 1 the previous reading
// repeated, 2 a new reading). Bytes outside 0..2 are reported as kUnknown (raw kept).
enum class ZedReadingState : uint8_t { kNone = 0, kOld = 1, kNew = 2, kUnknown = 255 };
using ZedMagState = ZedReadingState;  // the name the first drivers used

struct ZedSensorReport {
  // Byte 1, imu_not_valid: 0 = the IMU fields hold a fresh reading.
  uint8_t imu_not_valid_raw = 0;
  bool imu_valid = false;  // imu_not_valid_raw == 0

  // Byte 2, MCU ticks of 39062.5 ns (zed-open-capture: "usec/39"); the MCU's clock, not the host's.
  uint64_t timestamp_raw = 0;
  // timestamp_raw × 39062.5 = floor(raw · 78125 / 2) ns, exact integer arithmetic (128-bit product),
  // saturated at INT64_MAX (~292 years of MCU uptime: only corrupt bytes get there). The half
  // nanosecond of an odd tick is dropped.
  int64_t t_imu_ns = 0;

  std::array<int16_t, 3> gyro_raw{};                     // bytes 10,12,14: counts of 1000/32768 °/s
  std::array<int16_t, 3> accel_raw{};                    // bytes 16,18,20: counts of 9.8189·8/32768 m/s²
  Eigen::Vector3d gyro_radps = Eigen::Vector3d::Zero();  // rad/s (the MCU sends degrees/s)
  // Specific force, m/s² (at rest ≈ +9.8 along the axis pointing up).
  Eigen::Vector3d accel_mps2 = Eigen::Vector3d::Zero();

  // Byte 22: 1 = this IMU sample was taken at a camera frame's exposure (hardware.md "Frame/IMU sync").
  uint8_t frame_sync_raw = 0;
  bool frame_sync = false;        // frame_sync_raw != 0
  uint8_t sync_caps = 0;          // byte 23, sync_capabilities: nonzero when frame sync is active (raw)
  uint32_t frame_sync_count = 0;  // byte 24: frames the MCU has seen, incremented with frame_sync

  int16_t imu_temp_raw = 0;          // byte 28: counts of 0.01 °C
  std::optional<double> imu_temp_c;  // °C; none when raw == kZedTempNotValid

  uint8_t mag_valid_raw = 0;  // byte 30
  ZedReadingState mag_state = ZedReadingState::kNone;
  std::array<int16_t, 3> mag_raw{};                  // bytes 31,33,35: counts of 1/16 µT
  Eigen::Vector3d mag_uT = Eigen::Vector3d::Zero();  // µT; meaningful when mag_state is kOld or kNew

  // Bytes 37..46: the IMU's motion and free-fall interrupts (zed-open-capture camera_moving,
  // camera_moving_count, camera_falling, camera_falling_count); flags and counts, no unit.
  uint8_t moving = 0;
  uint32_t moving_count = 0;
  uint8_t falling = 0;
  uint32_t falling_count = 0;

  uint8_t env_valid_raw = 0;  // byte 47
  ZedReadingState env_state = ZedReadingState::kNone;
  int16_t env_temp_raw = 0;          // byte 48: counts of 0.01 °C
  std::optional<double> env_temp_c;  // °C; none when raw == kZedTempNotValid
  // Bytes 50 and 54. Their scales depend on the MCU firmware (zed-open-capture PRESS_SCALE_NEW/OLD,
  // HUMID_SCALE_NEW/OLD: pressure 0.0001 hPa and humidity 0.01 %rH per count from firmware 3.9 on,
  // 0.01 hPa and 1/1024 %rH before), so the report keeps raw counts; pressure_hpa and
  // humidity_percent convert them given the firmware the device reports.
  uint32_t pressure_raw = 0;
  uint32_t humidity_raw = 0;

  int16_t camera_temp_left_raw = 0, camera_temp_right_raw = 0;    // bytes 58, 60: counts of 0.01 °C
  std::optional<double> camera_temp_left_c, camera_temp_right_c;  // °C; none when not valid

  double pressure_hpa(bool firmware_at_least_3_9) const {
    return pressure_raw * (firmware_at_least_3_9 ? 1e-4 : 1e-2);
  }
  double humidity_percent(bool firmware_at_least_3_9) const {
    return humidity_raw * (firmware_at_least_3_9 ? 1e-2 : 1.0 / 1024.0);
  }
};

// What a reader discarded (plain counters, owned by the caller).
struct ZedSensorReportCounters {
  uint64_t parsed = 0;
  uint64_t too_short = 0;      // fewer than 62 bytes (or no buffer)
  uint64_t wrong_id = 0;       // another report id (a feature or command report)
  uint64_t imu_not_valid = 0;  // parsed, but the IMU fields are flagged stale
};

// bytes: one report as read from the interrupt endpoint or hidraw (n ≥ 62; bytes past 62, e.g. a
// 64-byte transfer's padding, are ignored). Errors: too short (kCorruptData), another report id
// (kParseError). Every other byte pattern is a representable reading (integers only, bounded by the
// full scales), so nothing else is refused here. Reads with memcpy; no allocation on success.
core::Expected<ZedSensorReport> parse_zed_sensor_report(const uint8_t* bytes, size_t n);
// The same, counting the outcome into *counters (may be null).
core::Expected<ZedSensorReport> parse_zed_sensor_report(const uint8_t* bytes, size_t n,
                                                        ZedSensorReportCounters* counters);

// Stream health of consecutive reports from one device (not a parser: it looks at parsed reports).
// The MCU sends ~400 Hz; a report re-sent by the host stack repeats its timestamp, a lost one shows
// as a timestamp step of several periods, and a lost frame_sync report as frame_sync_count advancing
// without a flagged report (hardware.md "Frame/IMU sync": the sample at a frame's exposure has
// frame_sync = 1 and the incremented count).
struct ZedReportMonitorCounters {
  uint64_t reports = 0;                 // observed, repeats included
  uint64_t repeated = 0;                // same timestamp as the previous report: drop it
  uint64_t timestamp_restarts = 0;      // timestamp went back (MCU reset / device reopened)
  uint64_t gaps = 0;                    // steps longer than 1.5 nominal periods
  uint64_t lost_reports_estimate = 0;   // Σ over gaps of round(step / period) − 1
  uint64_t sync_events = 0;             // reports with frame_sync set
  uint64_t missed_sync_events = 0;      // frame_sync_count advanced by more than the flagged reports
  uint64_t sync_without_increment = 0;  // frame_sync set but the count did not advance
  uint64_t sync_count_restarts = 0;     // frame_sync_count went back (not a 32-bit wrap)
};

enum class ZedReportCheck : uint8_t {
  kNew,        // use it
  kRepeated,   // a copy of the previous report: drop it
  kRestarted,  // the MCU's clock went back: downstream time bases must be reset; the report is usable
};

class ZedReportMonitor {
 public:
  // nominal_period_ns: the MCU's report period (400 Hz: 2.5 ms); must be > 0.
  explicit ZedReportMonitor(int64_t nominal_period_ns = 2'500'000);

  ZedReportCheck observe(const ZedSensorReport& report);
  const ZedReportMonitorCounters& counters() const { return counters_; }
  // Forgets the previous report (device reopened); counters are kept.
  void reset() { have_last_ = false; }

 private:
  int64_t period_ns_;
  bool have_last_ = false;
  int64_t last_t_imu_ns_ = 0;
  uint32_t last_sync_count_ = 0;
  ZedReportMonitorCounters counters_;
};

// timestamp ticks → ns: floor(raw · 39062.5), saturated at INT64_MAX.
int64_t zed_ticks_to_ns(uint64_t ticks);

// The report's IMU sample at t_ns (the caller's timeline, e.g. the report's t_imu_ns or that time put
// on the host clock by CameraClockSync). ZED 2i axes as sent (the MCU's IMU frame): T_imu_cam in
// config/hw.yaml relates them to the left camera.
hal::ImuSample to_imu_sample(const ZedSensorReport& report, int64_t t_ns);
// The magnetometer only when this report carries a new reading (mag_valid == 2).
std::optional<hal::MagSample> to_mag_sample(const ZedSensorReport& report, int64_t t_ns);

}  // namespace hwr::hal::hw
