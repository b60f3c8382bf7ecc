// ZED 2i HID sensor report (hal/hw/zed_sensor_report.hpp). Oracles: a hand-built 62-byte report
// with known counts at every offset of hardware.md's layout → SI values computed by hand; a second,
// byte-by-byte decoder written from the layout table below (shifts and ORs, no memcpy) for random
// and bit-flipped reports; closed-form timestamps. Also: "not valid" temperatures, every truncation,
// every foreign report id, the counters.
#include "hwr/hal/hw/zed_sensor_report.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

namespace hwr::hal::hw {
namespace {

using Bytes = std::vector<uint8_t>;

void put(Bytes* b, size_t off, uint64_t v, int n) {
  for (int i = 0; i < n; ++i) (*b)[off + static_cast<size_t>(i)] = static_cast<uint8_t>(v >> (8 * i));
}
void put_i16(Bytes* b, size_t off, int16_t v) { put(b, off, static_cast<uint16_t>(v), 2); }

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

// hardware.md's layout as a table: offset, size in bytes, signed.
struct Field {
  const char* name;
  size_t offset;
  int size;
  bool is_signed;
};
const Field kLayout[] = {
    {"id", 0, 1, false},
    {"imu_not_valid", 1, 1, false},
    {"timestamp", 2, 8, false},
    {"gyro_x", 10, 2, true},
    {"gyro_y", 12, 2, true},
    {"gyro_z", 14, 2, true},
    {"accel_x", 16, 2, true},
    {"accel_y", 18, 2, true},
    {"accel_z", 20, 2, true},
    {"frame_sync", 22, 1, false},
    {"sync_caps", 23, 1, false},
    {"frame_sync_count", 24, 4, false},
    {"imu_temp", 28, 2, true},
    {"mag_valid", 30, 1, false},
    {"mag_x", 31, 2, true},
    {"mag_y", 33, 2, true},
    {"mag_z", 35, 2, true},
    {"moving", 37, 1, false},
    {"moving_count", 38, 4, false},
    {"falling", 42, 1, false},
    {"falling_count", 43, 4, false},
    {"env_valid", 47, 1, false},
    {"env_temp", 48, 2, true},
    {"pressure", 50, 4, false},
    {"humidity", 54, 4, false},
    {"cam_temp_left", 58, 2, true},
    {"cam_temp_right", 60, 2, true},
};

// The second decoder: one field's value from the bytes, assembled with shifts.
int64_t oracle_field(const uint8_t* b, const Field& f) {
  uint64_t u = 0;
  for (int i = f.size - 1; i >= 0; --i) u = (u << 8) | b[f.offset + static_cast<size_t>(i)];
  if (f.is_signed && f.size == 2) return static_cast<int16_t>(static_cast<uint16_t>(u));
  return static_cast<int64_t>(u);
}
uint64_t oracle_timestamp(const uint8_t* b) {
  uint64_t u = 0;
  for (int i = 7; i >= 0; --i) u = (u << 8) | b[2 + i];
  return u;
}

// The parsed report's value of one field (raw), for comparison with the oracle.
int64_t parsed_field(const ZedSensorReport& r, const std::string& name) {
  if (name == "imu_not_valid") return r.imu_not_valid_raw;
  if (name == "gyro_x") return r.gyro_raw[0];
  if (name == "gyro_y") return r.gyro_raw[1];
  if (name == "gyro_z") return r.gyro_raw[2];
  if (name == "accel_x") return r.accel_raw[0];
  if (name == "accel_y") return r.accel_raw[1];
  if (name == "accel_z") return r.accel_raw[2];
  if (name == "frame_sync") return r.frame_sync_raw;
  if (name == "sync_caps") return r.sync_caps;
  if (name == "frame_sync_count") return r.frame_sync_count;
  if (name == "imu_temp") return r.imu_temp_raw;
  if (name == "mag_valid") return r.mag_valid_raw;
  if (name == "mag_x") return r.mag_raw[0];
  if (name == "mag_y") return r.mag_raw[1];
  if (name == "mag_z") return r.mag_raw[2];
  if (name == "moving") return r.moving;
  if (name == "moving_count") return r.moving_count;
  if (name == "falling") return r.falling;
  if (name == "falling_count") return r.falling_count;
  if (name == "env_valid") return r.env_valid_raw;
  if (name == "env_temp") return r.env_temp_raw;
  if (name == "pressure") return r.pressure_raw;
  if (name == "humidity") return r.humidity_raw;
  if (name == "cam_temp_left") return r.camera_temp_left_raw;
  if (name == "cam_temp_right") return r.camera_temp_right_raw;
  ADD_FAILURE() << "no field " << name;
  return 0;
}

// Every raw field and every SI value of r against the oracle decoder and the documented scales.
void expect_matches_oracle(const uint8_t* b, const ZedSensorReport& r) {
  for (const Field& f : kLayout) {
    if (f.offset == 0 || f.offset == 2) continue;
    ASSERT_EQ(parsed_field(r, f.name), oracle_field(b, f)) << f.name;
  }
  const uint64_t ts = oracle_timestamp(b);
  ASSERT_EQ(r.timestamp_raw, ts);
  ASSERT_EQ(r.imu_valid, b[1] == 0);
  ASSERT_EQ(r.frame_sync, b[22] != 0);
  for (int i = 0; i < 3; ++i) {
    const Field& g = kLayout[3 + i];
    const Field& a = kLayout[6 + i];
    const Field& m = kLayout[14 + i];
    ASSERT_EQ(r.gyro_radps[i], oracle_field(b, g) * (1000.0 / 32768.0) * kDeg);
    ASSERT_EQ(r.accel_mps2[i], oracle_field(b, a) * (9.8189 * 8.0 / 32768.0));
    ASSERT_EQ(r.mag_uT[i], oracle_field(b, m) * (1.0 / 16.0));
  }
  const auto temp = [&](size_t off) -> std::optional<double> {
    const auto raw = static_cast<int16_t>(b[off] | (b[off + 1] << 8));
    if (raw == -27315) return std::nullopt;
    return raw * 0.01;
  };
  ASSERT_EQ(r.imu_temp_c, temp(28));
  ASSERT_EQ(r.env_temp_c, temp(48));
  ASSERT_EQ(r.camera_temp_left_c, temp(58));
  ASSERT_EQ(r.camera_temp_right_c, temp(60));
}

Bytes known_report() {
  Bytes b(64, 0xEE);  // a 64-byte transfer: the last two bytes are padding
  b[0] = 0x01;
  b[1] = 0;                      // IMU valid
  put(&b, 2, 2'560'000'001, 8);  // odd tick count
  put_i16(&b, 10, 3277);         // gyro x ≈ 100 °/s
  put_i16(&b, 12, -32768);       // gyro y: −1000 °/s, full scale
  put_i16(&b, 14, -1);
  put_i16(&b, 16, 0);
  put_i16(&b, 18, 100);
  put_i16(&b, 20, 4096);  // accel z = 1 g (8 g over 32768 counts)
  b[22] = 1;              // frame sync
  b[23] = 0x03;
  put(&b, 24, 123456, 4);
  put_i16(&b, 28, 3512);  // 35.12 °C
  b[30] = 2;              // new magnetometer reading
  put_i16(&b, 31, 400);   // 25 µT
  put_i16(&b, 33, -160);  // −10 µT
  put_i16(&b, 35, 16);    // 1 µT
  b[37] = 1;
  put(&b, 38, 77, 4);
  b[42] = 0;
  put(&b, 43, 88, 4);
  b[47] = 2;
  put_i16(&b, 48, -27315);     // environment temperature not valid
  put(&b, 50, 10'132'500, 4);  // 1013.25 hPa at 0.0001 hPa per count
  put(&b, 54, 4500, 4);        // 45 %rH at 0.01
  put_i16(&b, 58, 4000);
  put_i16(&b, 60, -520);  // −5.2 °C
  return b;
}

TEST(ZedSensorReport, GivenAKnownReportThenEveryFieldHasItsDocumentedScale) {
  const Bytes b = known_report();
  auto r = parse_zed_sensor_report(b.data(), b.size());
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_TRUE(r->imu_valid);
  EXPECT_EQ(r->timestamp_raw, 2'560'000'001u);
  EXPECT_EQ(r->t_imu_ns, 100'000'000'039'062LL);  // 2 560 000 001 × 39062.5 = 1e14 + 39062.5
  EXPECT_EQ(r->gyro_raw[0], 3277);
  EXPECT_DOUBLE_EQ(r->gyro_radps.x(), 3277 * 1000.0 / 32768.0 * kDeg);  // 100.006 °/s
  EXPECT_NEAR(r->gyro_radps.x(), 1.745435, 1e-6);
  EXPECT_DOUBLE_EQ(r->gyro_radps.y(), -1000.0 * kDeg);
  EXPECT_DOUBLE_EQ(r->gyro_radps.z(), -1000.0 / 32768.0 * kDeg);
  EXPECT_EQ(r->accel_mps2.x(), 0.0);
  EXPECT_DOUBLE_EQ(r->accel_mps2.y(), 100 * 9.8189 * 8.0 / 32768.0);
  EXPECT_DOUBLE_EQ(r->accel_mps2.z(), 9.8189);
  EXPECT_TRUE(r->frame_sync);
  EXPECT_EQ(r->sync_caps, 3);
  EXPECT_EQ(r->frame_sync_count, 123456u);
  EXPECT_EQ(r->imu_temp_raw, 3512);
  ASSERT_TRUE(r->imu_temp_c.has_value());
  EXPECT_DOUBLE_EQ(*r->imu_temp_c, 35.12);
  EXPECT_EQ(r->mag_state, ZedReadingState::kNew);
  EXPECT_EQ(r->mag_uT, Eigen::Vector3d(25.0, -10.0, 1.0));  // 1/16 µT steps are exact in binary
  EXPECT_EQ(r->moving, 1);
  EXPECT_EQ(r->moving_count, 77u);
  EXPECT_EQ(r->falling, 0);
  EXPECT_EQ(r->falling_count, 88u);
  EXPECT_EQ(r->env_state, ZedReadingState::kNew);
  EXPECT_EQ(r->env_temp_raw, -27315);
  EXPECT_FALSE(r->env_temp_c.has_value());
  EXPECT_EQ(r->pressure_raw, 10'132'500u);
  EXPECT_NEAR(r->pressure_hpa(true), 1013.25, 1e-9);
  EXPECT_NEAR(r->pressure_hpa(false), 101325.0, 1e-6);
  EXPECT_NEAR(r->humidity_percent(true), 45.0, 1e-12);
  EXPECT_NEAR(r->humidity_percent(false), 4500 / 1024.0, 1e-12);
  EXPECT_DOUBLE_EQ(*r->camera_temp_left_c, 40.0);
  EXPECT_DOUBLE_EQ(*r->camera_temp_right_c, -5.2);

  const ImuSample s = to_imu_sample(*r, 7);
  EXPECT_EQ(s.t_ns, 7);
  EXPECT_EQ(s.accel_mps2, r->accel_mps2);
  EXPECT_EQ(s.gyro_radps, r->gyro_radps);
  auto m = to_mag_sample(*r, 9);
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->t_ns, 9);
  EXPECT_EQ(m->field_uT, r->mag_uT);
}

TEST(ZedSensorReport, GivenALevelCameraAtRestThenTheImuSampleIsPlusGravityUp) {
  Bytes b = known_report();
  put_i16(&b, 10, 0);
  put_i16(&b, 12, 0);
  put_i16(&b, 14, 0);
  put_i16(&b, 16, 0);
  put_i16(&b, 18, 0);
  put_i16(&b, 20, 4097);  // 1.000244 g
  auto r = parse_zed_sensor_report(b.data(), 62);
  ASSERT_TRUE(r.ok());
  const ImuSample s = to_imu_sample(*r, r->t_imu_ns);
  EXPECT_EQ(s.t_ns, r->t_imu_ns);
  EXPECT_NEAR(s.accel_mps2.z(), 9.8189 * 4097 / 4096, 1e-12);
  EXPECT_EQ(s.gyro_radps, Eigen::Vector3d::Zero());
}

TEST(ZedSensorReport, GivenTimestampTicksThenNanosecondsAreTicksTimes39062Point5Floored) {
  EXPECT_EQ(zed_ticks_to_ns(0), 0);
  EXPECT_EQ(zed_ticks_to_ns(1), 39062);  // 39062.5, half ns dropped
  EXPECT_EQ(zed_ticks_to_ns(2), 78125);
  EXPECT_EQ(zed_ticks_to_ns(3), 117187);
  EXPECT_EQ(zed_ticks_to_ns(25'600), 1'000'000'000);                               // 25600 ticks per second
  EXPECT_EQ(zed_ticks_to_ns(25'600ull * 86'400 * 365), 31'536'000'000'000'000LL);  // a year
  // A second implementation, (t / 2)·78125 + (t mod 2)·39062, on random tick counts in range.
  std::mt19937_64 rng(11);
  for (int i = 0; i < 100000; ++i) {
    const uint64_t t = rng() >> (1 + i % 40);  // spread over magnitudes, all < 2^63
    const uint64_t half = t / 2;
    if (half > static_cast<uint64_t>(std::numeric_limits<int64_t>::max() / 78125 - 1)) continue;
    ASSERT_EQ(zed_ticks_to_ns(t), static_cast<int64_t>(half) * 78125 + static_cast<int64_t>(t % 2) * 39062)
        << t;
  }
}

TEST(ZedSensorReport, GivenTicksBeyondInt64NanosecondsThenTheyClampAtTheBoundaryWithoutWrapping) {
  // The largest t with floor(t · 78125 / 2) ≤ INT64_MAX: t = floor((2·INT64_MAX + 1) / 78125).
  const uint64_t t_max = (2 * static_cast<uint64_t>(std::numeric_limits<int64_t>::max()) + 1) / 78125;
  const int64_t at_max = zed_ticks_to_ns(t_max);
  EXPECT_EQ(at_max, static_cast<int64_t>(t_max / 2) * 78125 + static_cast<int64_t>(t_max % 2) * 39062);
  EXPECT_LE(std::numeric_limits<int64_t>::max() - at_max, 39063);  // within one tick of the top
  EXPECT_EQ(zed_ticks_to_ns(t_max + 1), std::numeric_limits<int64_t>::max());
  EXPECT_EQ(zed_ticks_to_ns(UINT64_MAX), std::numeric_limits<int64_t>::max());
  Bytes b = known_report();
  put(&b, 2, UINT64_MAX, 8);
  auto r = parse_zed_sensor_report(b.data(), b.size());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->timestamp_raw, UINT64_MAX);
  EXPECT_EQ(r->t_imu_ns, std::numeric_limits<int64_t>::max());
}

TEST(ZedSensorReport, GivenEachFieldSetAloneThenOnlyThatFieldChanges) {
  // Walks hardware.md's table: a distinct value in one field of an all-zero report must come back
  // in exactly that field (catches an offset off by one anywhere in the layout).
  for (const Field& f : kLayout) {
    if (f.offset == 0) continue;
    Bytes b(62, 0);
    b[0] = 0x01;
    for (int i = 0; i < f.size; ++i)
      b[f.offset + static_cast<size_t>(i)] = static_cast<uint8_t>(0x11 * (i + 1) + 1);
    auto r = parse_zed_sensor_report(b.data(), b.size());
    ASSERT_TRUE(r.ok());
    expect_matches_oracle(b.data(), *r);
    for (const Field& g : kLayout) {
      if (g.offset == 0 || g.offset == 2) continue;
      const int64_t v = parsed_field(*r, g.name);
      if (g.offset == f.offset) {
        EXPECT_NE(v, 0) << f.name;
      } else {
        EXPECT_EQ(v, 0) << g.name << " changed when only " << f.name << " was set";
      }
    }
    if (f.offset == 2) {
      EXPECT_EQ(r->timestamp_raw, 0x8978675645342312ull);
    } else {
      EXPECT_EQ(r->timestamp_raw, 0u) << f.name;
    }
  }
}

TEST(ZedSensorReport, GivenTheMagnetometerStateThenAMagSampleOnlyForANewReading) {
  Bytes b = known_report();
  for (int state = 0; state < 256; ++state) {
    b[30] = static_cast<uint8_t>(state);
    auto r = parse_zed_sensor_report(b.data(), b.size());
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r->mag_valid_raw, state);
    EXPECT_EQ(to_mag_sample(*r, 0).has_value(), state == 2) << state;
    const ZedReadingState expected = state == 0   ? ZedReadingState::kNone
                                     : state == 1 ? ZedReadingState::kOld
                                     : state == 2 ? ZedReadingState::kNew
                                                  : ZedReadingState::kUnknown;
    EXPECT_EQ(r->mag_state, expected) << state;
  }
}

TEST(ZedSensorReport, GivenTheImuFlaggedNotValidThenItSaysSoAndTheCountersCountIt) {
  Bytes b = known_report();
  b[1] = 1;
  ZedSensorReportCounters c;
  auto r = parse_zed_sensor_report(b.data(), b.size(), &c);
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r->imu_valid);
  EXPECT_EQ(r->imu_not_valid_raw, 1);
  EXPECT_EQ(c.parsed, 1u);
  EXPECT_EQ(c.imu_not_valid, 1u);
}

TEST(ZedSensorReport, GivenEveryTemperatureNotValidThenNoneOfThemHasAValue) {
  Bytes b = known_report();
  for (size_t off : {28u, 48u, 58u, 60u}) put_i16(&b, off, -27315);
  auto r = parse_zed_sensor_report(b.data(), b.size());
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r->imu_temp_c || r->env_temp_c || r->camera_temp_left_c || r->camera_temp_right_c);
  // One count above the marker is a real (if absurd) −273.14 °C.
  put_i16(&b, 28, -27314);
  r = parse_zed_sensor_report(b.data(), b.size());
  ASSERT_TRUE(r.ok() && r->imu_temp_c.has_value());
  EXPECT_DOUBLE_EQ(*r->imu_temp_c, -273.14);
}

TEST(ZedSensorReport, GivenEveryTruncationThenCorruptDataAndCounted) {
  const Bytes b = known_report();
  ZedSensorReportCounters c;
  for (size_t n = 0; n < kZedSensorReportSize; ++n) {
    // A buffer of exactly n bytes, so ASan would see a read past it.
    const Bytes cut(b.begin(), b.begin() + static_cast<std::ptrdiff_t>(n));
    auto r = parse_zed_sensor_report(cut.data(), cut.size(), &c);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), core::ErrorCode::kCorruptData);
    EXPECT_NE(r.status().message().find(std::to_string(n) + " bytes, need 62"), std::string::npos)
        << r.status().message();
  }
  EXPECT_EQ(c.too_short, kZedSensorReportSize);
  EXPECT_EQ(c.parsed, 0u);
  const Bytes exact(b.begin(), b.begin() + 62);
  EXPECT_TRUE(parse_zed_sensor_report(exact.data(), exact.size(), &c).ok());
  EXPECT_FALSE(parse_zed_sensor_report(nullptr, 62, &c).ok());
  EXPECT_EQ(c.too_short, kZedSensorReportSize + 1);
  EXPECT_EQ(c.parsed, 1u);
}

TEST(ZedSensorReport, GivenPaddingBeyond62BytesThenItIsIgnored) {
  Bytes b = known_report();
  auto r62 = parse_zed_sensor_report(b.data(), 62);
  b.resize(1024, 0xA5);
  auto r_long = parse_zed_sensor_report(b.data(), b.size());
  ASSERT_TRUE(r62.ok() && r_long.ok());
  expect_matches_oracle(b.data(), *r_long);
  EXPECT_EQ(r62->timestamp_raw, r_long->timestamp_raw);
  EXPECT_EQ(r62->camera_temp_right_c, r_long->camera_temp_right_c);
}

TEST(ZedSensorReport, GivenAnyOtherReportIdThenParseErrorAndCounted) {
  Bytes b = known_report();
  ZedSensorReportCounters c;
  for (int id = 0; id < 256; ++id) {
    if (id == kZedSensorReportId) continue;
    b[0] = static_cast<uint8_t>(id);
    auto r = parse_zed_sensor_report(b.data(), b.size(), &c);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), core::ErrorCode::kParseError);
  }
  EXPECT_EQ(c.wrong_id, 255u);
  EXPECT_NE(parse_zed_sensor_report(b.data(), b.size()).status().message().find("report id 255"),
            std::string::npos);
}

TEST(ZedSensorReport, GivenEverySingleBitFlipThenTheReportDecodesAsTheOracleSays) {
  const Bytes good = known_report();
  for (size_t bit = 8; bit < 62 * 8; ++bit) {  // the id byte's flips are foreign ids (tested above)
    Bytes b(good.begin(), good.begin() + 62);
    b[bit / 8] = static_cast<uint8_t>(b[bit / 8] ^ (1u << (bit % 8)));
    auto r = parse_zed_sensor_report(b.data(), b.size());
    ASSERT_TRUE(r.ok()) << bit;
    expect_matches_oracle(b.data(), *r);
  }
}

TEST(ZedSensorReport, GivenRandomReportsThenTheyMatchTheOracleAndStayWithinFullScale) {
  std::mt19937 rng(3);
  Bytes b(62);
  for (int i = 0; i < 20000; ++i) {
    for (auto& x : b) x = static_cast<uint8_t>(rng());
    b[0] = 0x01;
    auto r = parse_zed_sensor_report(b.data(), b.size());
    ASSERT_TRUE(r.ok());
    expect_matches_oracle(b.data(), *r);
    ASSERT_TRUE(r->gyro_radps.allFinite() && r->accel_mps2.allFinite() && r->mag_uT.allFinite());
    ASSERT_LE(r->accel_mps2.cwiseAbs().maxCoeff(), 8 * 9.8189 + 1e-9);
    ASSERT_LE(r->gyro_radps.cwiseAbs().maxCoeff(), 1000.0 * kDeg + 1e-9);
    ASSERT_LE(r->mag_uT.cwiseAbs().maxCoeff(), 2048.0);
    ASSERT_GE(r->t_imu_ns, 0);
  }
}

// ---- ZedReportMonitor --------------------------------------------------------------------------

// A report as the MCU would send it at tick `tick` (64 ticks = 2.5 ms: 400 Hz exactly).
ZedSensorReport report_at(uint64_t tick, bool sync, uint32_t count) {
  Bytes b(62, 0);
  b[0] = 0x01;
  put(&b, 2, tick, 8);
  b[22] = sync ? 1 : 0;
  put(&b, 24, count, 4);
  return *parse_zed_sensor_report(b.data(), b.size());
}

TEST(ZedReportMonitor, GivenASimulatedStreamWithDropsThenLostReportsAndMissedSyncsAreCountedExactly) {
  // 400 Hz reports, a frame every 13 or 14 reports (≈ 30 fps); the host loses some reports at random,
  // flagged ones included. Oracle: the simulation's own tally.
  std::mt19937 rng(21);
  ZedReportMonitor monitor;
  uint32_t count = 1000;
  uint64_t lost = 0, lost_flagged = 0, delivered_flagged = 0, gaps = 0;
  bool lost_previous = false;
  for (uint64_t i = 0; i < 40000; ++i) {
    const bool sync = i % 40 == 0 || i % 40 == 13 || i % 40 == 27;
    if (sync) ++count;
    const bool drop = i > 0 && rng() % 50 == 0;
    if (drop) {
      ++lost;
      lost_flagged += sync ? 1 : 0;
      if (!lost_previous) ++gaps;
      lost_previous = true;
      continue;
    }
    lost_previous = false;
    delivered_flagged += sync ? 1 : 0;
    ASSERT_EQ(monitor.observe(report_at(1'000'000 + 64 * i, sync, count)), ZedReportCheck::kNew);
  }
  const ZedReportMonitorCounters& c = monitor.counters();
  EXPECT_GT(lost, 500u);
  EXPECT_EQ(c.lost_reports_estimate, lost);
  EXPECT_EQ(c.gaps, gaps);
  EXPECT_EQ(c.sync_events, delivered_flagged);
  EXPECT_EQ(c.missed_sync_events, lost_flagged);
  EXPECT_EQ(c.repeated + c.timestamp_restarts + c.sync_count_restarts + c.sync_without_increment, 0u);
}

TEST(ZedReportMonitor, GivenARepeatedReportThenItIsFlaggedAndNotCountedTwice) {
  ZedReportMonitor monitor;
  EXPECT_EQ(monitor.observe(report_at(64, true, 5)), ZedReportCheck::kNew);
  EXPECT_EQ(monitor.observe(report_at(64, true, 5)), ZedReportCheck::kRepeated);
  EXPECT_EQ(monitor.observe(report_at(128, false, 5)), ZedReportCheck::kNew);
  EXPECT_EQ(monitor.counters().reports, 3u);
  EXPECT_EQ(monitor.counters().repeated, 1u);
  EXPECT_EQ(monitor.counters().sync_events, 1u);
  EXPECT_EQ(monitor.counters().missed_sync_events, 0u);
  EXPECT_EQ(monitor.counters().gaps, 0u);
}

TEST(ZedReportMonitor, GivenTheTimestampGoingBackThenRestartedAndTheCountResetIsNotAMiss) {
  ZedReportMonitor monitor;
  EXPECT_EQ(monitor.observe(report_at(1'000'000, false, 900)), ZedReportCheck::kNew);
  EXPECT_EQ(monitor.observe(report_at(1'000'064, true, 901)), ZedReportCheck::kNew);
  EXPECT_EQ(monitor.observe(report_at(10, false, 0)), ZedReportCheck::kRestarted);  // MCU reset
  EXPECT_EQ(monitor.observe(report_at(74, true, 1)), ZedReportCheck::kNew);
  const ZedReportMonitorCounters& c = monitor.counters();
  EXPECT_EQ(c.timestamp_restarts, 1u);
  EXPECT_EQ(c.sync_count_restarts, 0u);
  EXPECT_EQ(c.missed_sync_events, 0u);
  EXPECT_EQ(c.gaps, 0u);
}

TEST(ZedReportMonitor, GivenTheCountGoingBackAloneOrWrappingThenRestartOrOrdinaryStep) {
  ZedReportMonitor monitor;
  EXPECT_EQ(monitor.observe(report_at(64, false, 500)), ZedReportCheck::kNew);
  EXPECT_EQ(monitor.observe(report_at(128, false, 3)), ZedReportCheck::kNew);  // camera stream restarted
  EXPECT_EQ(monitor.counters().sync_count_restarts, 1u);
  EXPECT_EQ(monitor.counters().missed_sync_events, 0u);
  EXPECT_EQ(monitor.observe(report_at(192, false, 0xFFFF'FFFFu)), ZedReportCheck::kNew);
  EXPECT_EQ(monitor.counters().sync_count_restarts, 2u);  // 3 → 2^32 − 1 is going back too
  EXPECT_EQ(monitor.observe(report_at(256, true, 0)), ZedReportCheck::kNew);   // the 32-bit wrap
  EXPECT_EQ(monitor.observe(report_at(320, false, 2)), ZedReportCheck::kNew);  // one flagged report lost
  EXPECT_EQ(monitor.observe(report_at(384, true, 2)), ZedReportCheck::kNew);   // flag without increment
  const ZedReportMonitorCounters& c = monitor.counters();
  EXPECT_EQ(c.sync_count_restarts, 2u);
  EXPECT_EQ(c.missed_sync_events, 2u);
  EXPECT_EQ(c.sync_without_increment, 1u);
}

TEST(ZedReportMonitor, GivenResetThenTheNextReportStartsAfreshButCountersStay) {
  ZedReportMonitor monitor(2'500'000);
  EXPECT_EQ(monitor.observe(report_at(64'000, false, 10)), ZedReportCheck::kNew);
  monitor.reset();
  EXPECT_EQ(monitor.observe(report_at(64, false, 0)), ZedReportCheck::kNew);  // not a restart after reset
  EXPECT_EQ(monitor.counters().reports, 2u);
  EXPECT_EQ(monitor.counters().timestamp_restarts, 0u);
  // A long outage: 1 s without reports is ~399 lost reports, one gap.
  EXPECT_EQ(monitor.observe(report_at(64 + 25'600, false, 30)), ZedReportCheck::kNew);
  EXPECT_EQ(monitor.counters().gaps, 1u);
  EXPECT_EQ(monitor.counters().lost_reports_estimate, 399u);
  EXPECT_EQ(monitor.counters().missed_sync_events, 30u);
}

}  // namespace
}  // namespace hwr::hal::hw
