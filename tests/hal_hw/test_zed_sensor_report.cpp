// ZED 2i HID sensor report (hal/hw/zed_sensor_report.hpp): a hand-built 62-byte report with known
// counts at every offset of hardware.md's layout → exact SI values; "not valid" temperatures; short
// and foreign reports refused; every truncation refused; random bytes never crash.
#include "hwr/hal/hw/zed_sensor_report.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace hwr::hal::hw {
namespace {

using Bytes = std::vector<uint8_t>;

void put(Bytes* b, size_t off, uint64_t v, int n) {
  for (int i = 0; i < n; ++i) (*b)[off + static_cast<size_t>(i)] = static_cast<uint8_t>(v >> (8 * i));
}
void put_i16(Bytes* b, size_t off, int16_t v) { put(b, off, static_cast<uint16_t>(v), 2); }

Bytes known_report() {
  Bytes b(64, 0xEE);  // a 64-byte transfer: the last two bytes are padding
  b[0] = 0x01;
  b[1] = 0;                      // IMU valid
  put(&b, 2, 2'560'000'001, 8);  // odd tick count
  put_i16(&b, 10, 3277);         // gyro x ≈ 100 °/s
  put_i16(&b, 12, -32768);       // gyro y full scale
  put_i16(&b, 14, 0);
  put_i16(&b, 16, 0);
  put_i16(&b, 18, 100);
  put_i16(&b, 20, 4096);  // accel z = 1 g (8 g over 32768)
  b[22] = 1;              // frame sync
  b[23] = 0x03;
  put(&b, 24, 123456, 4);
  put_i16(&b, 28, 3512);  // 35.12 °C
  b[30] = 2;              // new magnetometer reading
  put_i16(&b, 31, 400);   // 25 µT
  put_i16(&b, 33, -160);
  put_i16(&b, 35, 16);
  b[37] = 1;
  put(&b, 38, 77, 4);
  b[42] = 0;
  put(&b, 43, 88, 4);
  b[47] = 2;
  put_i16(&b, 48, -27315);     // environment temperature not valid
  put(&b, 50, 10'132'500, 4);  // 1013.25 hPa at 0.0001 hPa per count
  put(&b, 54, 4500, 4);        // 45 %rH at 0.01
  put_i16(&b, 58, 4000);
  put_i16(&b, 60, 4100);
  return b;
}

TEST(ZedSensorReport, GivenAKnownReportThenEveryFieldHasItsDocumentedScale) {
  const Bytes b = known_report();
  auto r = parse_zed_sensor_report(b.data(), b.size());
  ASSERT_TRUE(r.ok()) << r.status().message();
  const double deg = M_PI / 180.0;
  EXPECT_TRUE(r->imu_valid);
  EXPECT_EQ(r->timestamp_raw, 2'560'000'001u);
  EXPECT_EQ(r->t_imu_ns, 100'000'000'039'062LL);  // 2 560 000 001 × 39062.5, half ns dropped
  EXPECT_DOUBLE_EQ(r->gyro_radps.x(), 3277 * 1000.0 / 32768.0 * deg);
  EXPECT_DOUBLE_EQ(r->gyro_radps.y(), -1000.0 * deg);
  EXPECT_DOUBLE_EQ(r->accel_mps2.y(), 100 * 9.8189 * 8.0 / 32768.0);
  EXPECT_DOUBLE_EQ(r->accel_mps2.z(), 9.8189);
  EXPECT_TRUE(r->frame_sync);
  EXPECT_EQ(r->sync_caps, 3);
  EXPECT_EQ(r->frame_sync_count, 123456u);
  ASSERT_TRUE(r->imu_temp_c.has_value());
  EXPECT_DOUBLE_EQ(*r->imu_temp_c, 35.12);
  EXPECT_EQ(r->mag_state, ZedMagState::kNew);
  EXPECT_TRUE(r->mag_uT.isApprox(Eigen::Vector3d(25.0, -10.0, 1.0)));
  EXPECT_EQ(r->moving, 1);
  EXPECT_EQ(r->moving_raw, 77u);
  EXPECT_EQ(r->falling_raw, 88u);
  EXPECT_EQ(r->env_state, 2);
  EXPECT_FALSE(r->env_temp_c.has_value());
  EXPECT_NEAR(r->pressure_hpa(true), 1013.25, 1e-9);
  EXPECT_NEAR(r->humidity_percent(true), 45.0, 1e-12);
  EXPECT_NEAR(r->humidity_percent(false), 4500 / 1024.0, 1e-12);
  EXPECT_DOUBLE_EQ(*r->camera_temp_left_c, 40.0);
  EXPECT_DOUBLE_EQ(*r->camera_temp_right_c, 41.0);

  const ImuSample s = to_imu_sample(*r, 7);
  EXPECT_EQ(s.t_ns, 7);
  EXPECT_EQ(s.accel_mps2, r->accel_mps2);
  auto m = to_mag_sample(*r, 7);
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->field_uT, r->mag_uT);
}

TEST(ZedSensorReport, GivenAnOldOrNoMagnetometerReadingThenNoMagSample) {
  Bytes b = known_report();
  for (uint8_t state : {0, 1, 7}) {
    b[30] = state;
    auto r = parse_zed_sensor_report(b.data(), b.size());
    ASSERT_TRUE(r.ok());
    EXPECT_FALSE(to_mag_sample(*r, 0).has_value()) << int(state);
  }
}

TEST(ZedSensorReport, GivenTheImuFlaggedNotValidThenItSaysSo) {
  Bytes b = known_report();
  b[1] = 1;
  auto r = parse_zed_sensor_report(b.data(), b.size());
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r->imu_valid);
}

TEST(ZedSensorReport, GivenEveryTruncationThenCorruptData) {
  const Bytes b = known_report();
  for (size_t n = 0; n < kZedSensorReportSize; ++n) {
    auto r = parse_zed_sensor_report(b.data(), n);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), core::ErrorCode::kCorruptData);
  }
  EXPECT_TRUE(parse_zed_sensor_report(b.data(), kZedSensorReportSize).ok());
  EXPECT_FALSE(parse_zed_sensor_report(nullptr, 62).ok());
}

TEST(ZedSensorReport, GivenAnotherReportIdThenParseError) {
  Bytes b = known_report();
  b[0] = 0x02;
  auto r = parse_zed_sensor_report(b.data(), b.size());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), core::ErrorCode::kParseError);
}

TEST(ZedSensorReport, GivenTheLargestTimestampThenItSaturatesInsteadOfWrapping) {
  Bytes b = known_report();
  put(&b, 2, UINT64_MAX, 8);
  auto r = parse_zed_sensor_report(b.data(), b.size());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->t_imu_ns, INT64_MAX);
}

TEST(ZedSensorReport, GivenRandomReportsThenAllValuesAreFiniteAndWithinFullScale) {
  std::mt19937 rng(3);
  Bytes b(62);
  for (int i = 0; i < 20000; ++i) {
    for (auto& x : b) x = static_cast<uint8_t>(rng());
    b[0] = 0x01;
    auto r = parse_zed_sensor_report(b.data(), b.size());
    ASSERT_TRUE(r.ok());
    ASSERT_TRUE(r->gyro_radps.allFinite() && r->accel_mps2.allFinite() && r->mag_uT.allFinite());
    ASSERT_LE(r->accel_mps2.cwiseAbs().maxCoeff(), 8 * 9.8189 + 1e-9);
    ASSERT_LE(r->gyro_radps.cwiseAbs().maxCoeff(), 1000.0 * M_PI / 180.0 + 1e-9);
    ASSERT_GE(r->t_imu_ns, 0);
  }
}

}  // namespace
}  // namespace hwr::hal::hw
