// KeyframeSensorTags (recon/keyframe_sensor_tags.hpp): each stored keyframe gets the magnetometer
// sample and the 3D GNSS fix nearest its time, within the configured gaps, or none.

#include <gtest/gtest.h>

#include <cmath>

#include "hwr/core/alloc_counter.hpp"
#include "hwr/recon/keyframe_sensor_tags.hpp"

namespace hwr::recon {
namespace {

constexpr int64_t kMs = 1'000'000;

hal::MagSample mag_at(int64_t t_ns) {
  hal::MagSample m;
  m.t_ns = t_ns;
  m.field_uT = Eigen::Vector3d(static_cast<double>(t_ns / kMs), 1.0, -40.0);  // x encodes the time
  return m;
}

hal::GnssFix fix_at(int64_t t_ns, uint8_t fix_type = 3) {
  hal::GnssFix g;
  g.t_ns = t_ns;
  g.fix_type = fix_type;
  g.lat_deg = 47.0 + static_cast<double>(t_ns / kMs) * 1e-6;  // encodes the time
  g.lon_deg = 8.5;
  g.height_m = 400.0;
  return g;
}

StoredKeyframe tagged(const KeyframeSensorTags& tags, int64_t t_ns) {
  StoredKeyframe kf;
  kf.t_ns = t_ns;
  tags.tag(&kf);
  return kf;
}

TEST(KeyframeSensorTags, GivenSamplesAroundAKeyframeThenTheNearestWithinTheGapIsKept) {
  KeyframeSensorTags tags;
  for (int64_t t = 0; t <= 1000 * kMs; t += 20 * kMs) tags.add_mag(mag_at(t));    // 50 Hz
  for (int64_t t = 0; t <= 1000 * kMs; t += 200 * kMs) tags.add_gnss(fix_at(t));  // 5 Hz
  {
    core::AllocationScope scope;
    const StoredKeyframe kf = tagged(tags, 509 * kMs);
    EXPECT_EQ(scope.allocations(), 0u);
    ASSERT_TRUE(kf.mag_valid);
    EXPECT_EQ(kf.mag_imu_uT.x(), 500.0);  // 500 ms is 9 ms away, 520 ms 11 ms
    ASSERT_TRUE(kf.gnss_valid);
    EXPECT_NEAR(kf.lat_deg, 47.0 + 600e-6, 1e-12);  // 600 ms: 91 ms away, 400 ms: 109 ms
    EXPECT_EQ(kf.lon_deg, 8.5);
    EXPECT_EQ(kf.alt_m, 400.0);
  }
  // Exactly on a sample; before the first one; long after the last one (beyond both gaps).
  EXPECT_EQ(tagged(tags, 40 * kMs).mag_imu_uT.x(), 40.0);
  EXPECT_TRUE(tagged(tags, -30 * kMs).mag_valid);  // 30 ms before the first: inside 50 ms
  EXPECT_FALSE(tagged(tags, -60 * kMs).mag_valid);
  const StoredKeyframe late = tagged(tags, 1600 * kMs);
  EXPECT_FALSE(late.mag_valid);
  EXPECT_FALSE(late.gnss_valid);
  EXPECT_EQ(late.mag_imu_uT, Eigen::Vector3d::Zero());
  EXPECT_EQ(late.lat_deg, 0.0);
  EXPECT_TRUE(tagged(tags, 1400 * kMs).gnss_valid);  // 400 ms after the last fix: inside 0.5 s
}

TEST(KeyframeSensorTags, GivenBadOrOutOfOrderSamplesThenIgnoredAndCounted) {
  KeyframeSensorTags tags;
  tags.add_mag(mag_at(100 * kMs));
  tags.add_mag(mag_at(100 * kMs));  // same time
  tags.add_mag(mag_at(90 * kMs));   // older
  hal::MagSample nan = mag_at(120 * kMs);
  nan.field_uT.x() = NAN;
  tags.add_mag(nan);
  tags.add_gnss(fix_at(100 * kMs, 2));  // 2D fix
  hal::GnssFix bad = fix_at(110 * kMs);
  bad.lat_deg = NAN;
  tags.add_gnss(bad);
  EXPECT_EQ(tags.rejected(), 5u);
  const StoredKeyframe kf = tagged(tags, 100 * kMs);
  EXPECT_TRUE(kf.mag_valid);
  EXPECT_FALSE(kf.gnss_valid);
}

TEST(KeyframeSensorTags, GivenMoreSamplesThanTheRingHoldsThenTheNewestAreKept) {
  KeyframeSensorTagsConfig cfg;
  cfg.mag_capacity = 8;
  KeyframeSensorTags tags(cfg);
  for (int i = 0; i < 20; ++i) tags.add_mag(mag_at(i * 20 * kMs));
  EXPECT_FALSE(tagged(tags, 100 * kMs).mag_valid);           // overwritten
  EXPECT_EQ(tagged(tags, 245 * kMs).mag_imu_uT.x(), 240.0);  // oldest kept: 12 * 20 ms
  EXPECT_EQ(tagged(tags, 379 * kMs).mag_imu_uT.x(), 380.0);  // newest
}

// A keyframe remembered when it was made keeps its tags through a long stop: by the time the mapper
// stores it, newer samples have pushed its own out of the rings.
TEST(KeyframeSensorTags, GivenARememberedKeyframeThenALongStopDoesNotLoseItsTags) {
  KeyframeSensorTagsConfig cfg;
  cfg.mag_capacity = 16;
  cfg.gnss_capacity = 4;
  KeyframeSensorTags tags(cfg);
  for (int64_t t = 0; t <= 100 * kMs; t += 20 * kMs) tags.add_mag(mag_at(t));
  tags.add_gnss(fix_at(100 * kMs));
  tags.remember(7, 95 * kMs);
  for (int64_t t = 120 * kMs; t <= 30'000 * kMs; t += 20 * kMs) tags.add_mag(mag_at(t));  // 30 s stop
  for (int64_t t = 300 * kMs; t <= 30'000 * kMs; t += 200 * kMs) tags.add_gnss(fix_at(t));
  StoredKeyframe kf;
  kf.id = 7;
  kf.t_ns = 95 * kMs;
  tags.tag(&kf);
  ASSERT_TRUE(kf.mag_valid);
  EXPECT_EQ(kf.mag_imu_uT.x(), 100.0);
  ASSERT_TRUE(kf.gnss_valid);
  EXPECT_NEAR(kf.lat_deg, 47.0 + 100e-6, 1e-12);
  // Not remembered: the rings alone, which no longer reach back that far.
  kf.id = 8;
  tags.tag(&kf);
  EXPECT_FALSE(kf.mag_valid);
  EXPECT_FALSE(kf.gnss_valid);
}

// A sample far older than the newest is a restarted source: the rings start over instead of
// refusing every sample until time passes the old maximum.
TEST(KeyframeSensorTags, GivenASourceRestartThenTheRingsStartOver) {
  KeyframeSensorTags tags;
  for (int64_t t = 0; t <= 5000 * kMs; t += 20 * kMs) tags.add_mag(mag_at(t));
  tags.add_mag(mag_at(4990 * kMs));  // 10 ms older: out of order, ignored
  EXPECT_EQ(tags.rejected(), 1u);
  tags.add_mag(mag_at(100 * kMs));  // 4.9 s older: restart
  tags.add_mag(mag_at(120 * kMs));
  EXPECT_EQ(tags.rejected(), 1u);
  EXPECT_EQ(tagged(tags, 118 * kMs).mag_imu_uT.x(), 120.0);
  EXPECT_FALSE(tagged(tags, 3000 * kMs).mag_valid);  // the old samples are gone
}

}  // namespace
}  // namespace hwr::recon
