// ReceiptClockMap against a synthetic device: known offset and drift, latency = a floor plus
// random extra delay; the mapped stamps must sit within the floor of the true host times.
#include "hwr/hal/hw/receipt_clock_map.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>

using hwr::hal::hw::ReceiptClockMap;

namespace {

struct SyntheticDevice {
  int64_t offset_ns;  // host = device·(1 + drift) + offset
  double drift;
  int64_t host_of(int64_t t_device_ns) const {
    return offset_ns + t_device_ns +
           static_cast<int64_t>(std::llround(drift * static_cast<double>(t_device_ns)));
  }
};

}  // namespace

TEST(ReceiptClockMap, GivenNoSampleThenNoOffset) {
  ReceiptClockMap m;
  EXPECT_FALSE(m.offset_ns().has_value());
}

TEST(ReceiptClockMap, GivenConstantLatencyThenTheOffsetIsHostMinusDeviceMinusNothingElse) {
  ReceiptClockMap m;
  const int64_t latency = 2'000'000;
  for (int i = 0; i < 100; ++i) {
    const int64_t dev = 5'000'000'000 + i * 6'666'667;
    const int64_t host = dev + 123'000'000'000;
    EXPECT_EQ(m.map(dev, host + latency), host + latency);  // latency is indistinguishable from offset
  }
}

TEST(ReceiptClockMap, GivenJitteryLatencyAndDriftThenStampsKeepTheFloorError) {
  // 150 Hz for 60 s, 50 ppm drift, latency 1 ms floor + exponential extra (mean 3 ms) with bursts.
  const SyntheticDevice dev{987'654'321'000, 50e-6};
  std::mt19937 rng(7);
  std::exponential_distribution<double> extra_ms(1.0 / 3.0);
  ReceiptClockMap m(10);
  double worst_after_warmup_ms = 0;
  double worst_interval_error_us = 0;
  int64_t prev_mapped = 0, prev_true = 0;
  for (int i = 0; i < 150 * 60; ++i) {
    const int64_t t_dev = 1'000'000'000 + i * 6'666'667LL;
    const int64_t t_true = dev.host_of(t_dev);
    const double lat_ms = 1.0 + extra_ms(rng) + ((i % 500) < 5 ? 40.0 : 0.0);  // a 40 ms stall now and then
    const int64_t t_rx = t_true + static_cast<int64_t>(lat_ms * 1e6);
    const int64_t mapped = m.map(t_dev, t_rx);
    if (i > 150 * 2) {
      // After 2 s the window has seen near-floor latencies: error = floor (1 ms) + what the minimum
      // over the window misses (a few tens of µs at 150 Hz) + drift over the 10 s window (0.5 ms).
      const double err_ms = static_cast<double>(mapped - t_true) * 1e-6;
      worst_after_warmup_ms = std::max(worst_after_warmup_ms, std::abs(err_ms - 1.0));
      const double interval_err_us =
          std::abs(static_cast<double>((mapped - prev_mapped) - (t_true - prev_true))) * 1e-3;
      worst_interval_error_us = std::max(worst_interval_error_us, interval_err_us);
    }
    prev_mapped = mapped;
    prev_true = t_true;
  }
  EXPECT_LT(worst_after_warmup_ms, 0.6);
  // Intervals: the device's own spacing except when the window's minimum moves (drift, bucket
  // expiry): bounded by the ~0.5 ms drift a window holds, far below the 40 ms arrival stalls.
  EXPECT_LT(worst_interval_error_us, 600.0);
}

TEST(ReceiptClockMap, GivenResetThenTheOldOffsetIsForgotten) {
  ReceiptClockMap m;
  m.map(0, 1'000'000);
  ASSERT_EQ(*m.offset_ns(), 1'000'000);
  m.reset();
  EXPECT_FALSE(m.offset_ns().has_value());
  m.map(0, 5'000'000);  // the device restarted its clock
  EXPECT_EQ(*m.offset_ns(), 5'000'000);
}

TEST(ReceiptClockMap, GivenALowerDelayLeavingTheWindowThenTheOffsetFollowsTheNewFloor) {
  ReceiptClockMap m(3);
  const int64_t s = 1'000'000'000;
  m.map(10 * s, 10 * s + 1'000'000);  // one fast sample at second 10
  for (int64_t k = 11; k <= 12; ++k) m.map(k * s, k * s + 5'000'000);
  EXPECT_EQ(*m.offset_ns(), 1'000'000);  // still inside the 3 s window
  m.map(13 * s, 13 * s + 5'000'000);     // second 10 leaves the window
  EXPECT_EQ(*m.offset_ns(), 5'000'000);
}
