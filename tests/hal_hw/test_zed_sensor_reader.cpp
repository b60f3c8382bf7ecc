// ZedSensorReader against a simulated ZED 2i sensor MCU behind the UsbHidOps seam. The MCU's clock
// runs at t_imu = offset + (1 + drift)·t_host; it samples every 64 ticks (2.5 ms, 400 Hz), each
// report reaching the host 1 ms + an exponential tail later (the fake clock is set to that arrival
// when interrupt_in returns it). Camera exposures every 40 ms (25 fps) coincide with every 16th
// sample, which is flagged frame_sync with an incremented count; their V4L2 stamps (± uniform jitter)
// reach the reader's frame-stamp ring a frame period later. Oracle: each sample's true host time,
// host_of_imu(t_imu).
#include "hwr/hal/hw/zed_sensor_reader.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <deque>
#include <random>
#include <string>
#include <vector>

namespace hwr::hal::hw {
namespace {

using Bytes = std::vector<uint8_t>;
constexpr int64_t kMs = 1'000'000;

void put(Bytes* b, size_t off, uint64_t v, int n) {
  for (int i = 0; i < n; ++i) (*b)[off + static_cast<size_t>(i)] = static_cast<uint8_t>(v >> (8 * i));
}
void put_i16(Bytes* b, size_t off, int16_t v) { put(b, off, static_cast<uint16_t>(v), 2); }

// A 64-byte input report (hardware.md "Sensors over HID" offsets).
Bytes report_bytes(uint64_t ticks, bool frame_sync, uint32_t sync_count, bool mag_new,
                   bool imu_valid = true) {
  Bytes b(64, 0);
  b[0] = 0x01;
  b[1] = imu_valid ? 0 : 1;
  put(&b, 2, ticks, 8);
  put_i16(&b, 10, 328);   // gyro x: 328 · 1000/32768 °/s ≈ 10.01 °/s
  put_i16(&b, 20, 4096);  // accel z: 4096 · 9.8189·8/32768 = 9.8189 m/s²
  b[22] = frame_sync ? 1 : 0;
  b[23] = 1;
  put(&b, 24, sync_count, 4);
  b[30] = mag_new ? 2 : 1;
  put_i16(&b, 31, 320);   // 20 µT
  put_i16(&b, 35, -640);  // -40 µT
  return b;
}

struct McuSim {
  double drift = 50e-6;
  int64_t imu_offset_ns = 5'000'000'000;
  int64_t t0_host_ns = 100'000'000'000;  // first sample
  int64_t frame_jitter_ns = 50'000;
  bool camera = true;
  uint32_t seed = 3;
};

// The simulated MCU (also the camera's frame-stamp producer and the test's clock).
class FakeZedMcu final : public UsbHidOps {
 public:
  explicit FakeZedMcu(const McuSim& sim, int64_t* clock_ns, core::SpscRing<CameraFrameStamp>* stamps)
      : sim_(sim), imu_offset_ns_(sim.imu_offset_ns), clock_ns_(clock_ns), stamps_(stamps), rng_(sim.seed) {
    next_ticks_ = ticks_of_imu(imu_of_host(sim.t0_host_ns));
  }

  // Knobs.
  int open_result = kUsbSuccess;
  int unplug_after_reports = -1;  // interrupt_in answers NO_DEVICE after this many (then stays gone)
  bool restart_clock_on_open = false;
  std::deque<Bytes> injected;  // delivered before the next simulated report
  int opens = 0, keep_alives = 0, enables = 0;

  int64_t imu_of_host(int64_t t_host_ns) const {
    return imu_offset_ns_ + t_host_ns + std::llround(sim_.drift * static_cast<double>(t_host_ns));
  }
  int64_t host_of_imu(int64_t t_imu_ns) const {
    return std::llround(static_cast<double>(t_imu_ns - imu_offset_ns_) / (1.0 + sim_.drift));
  }
  static uint64_t ticks_of_imu(int64_t t_imu_ns) { return static_cast<uint64_t>(t_imu_ns * 2 / 78125); }
  static int64_t imu_of_ticks(uint64_t ticks) { return static_cast<int64_t>(ticks * 78125 / 2); }
  uint64_t last_ticks() const { return next_ticks_ - 64; }

  int open(uint16_t, uint16_t) override {
    ++opens;
    if (open_result != kUsbSuccess) return open_result;
    if (gone_) {
      gone_ = false;
      if (restart_clock_on_open) {  // a replugged MCU boots: its clock and count start from zero
        next_ticks_ = 64;
        sync_count_ = 0;
        k_ = 0;
        const int64_t t_host_next = *clock_ns_ + kMs;
        imu_offset_ns_ =
            imu_of_ticks(64) - t_host_next - std::llround(sim_.drift * static_cast<double>(t_host_next));
      }
    }
    open_ = true;
    return kUsbSuccess;
  }
  int claim_interface(int) override { return open_ ? kUsbSuccess : kUsbErrorNoDevice; }
  int control_out(uint8_t, uint8_t, uint16_t, uint16_t, const uint8_t* data, uint16_t length,
                  unsigned) override {
    if (!open_) return kUsbErrorNoDevice;
    if (length == 2 && data[0] == 0x32 && data[1] == 0x01) ++enables;
    if (length == 2 && data[0] == 0x21 && data[1] == 0xF2) ++keep_alives;
    return length;
  }
  int interrupt_in(uint8_t* buf, int length, unsigned) override {
    if (!open_ || gone_) return kUsbErrorNoDevice;
    if (!injected.empty()) {
      const Bytes b = injected.front();
      injected.pop_front();
      const size_t n = std::min<size_t>(b.size(), static_cast<size_t>(length));
      std::memcpy(buf, b.data(), n);
      *clock_ns_ += 100'000;
      return static_cast<int>(n);
    }
    if (unplug_after_reports >= 0 && delivered_ >= unplug_after_reports) {
      gone_ = true;
      unplug_after_reports = -1;
      return kUsbErrorNoDevice;
    }
    const uint64_t ticks = next_ticks_;
    const int64_t t_host = host_of_imu(imu_of_ticks(ticks));
    const bool sync = sim_.camera && k_ % 16 == 0;
    if (sync) ++sync_count_;
    const Bytes b = report_bytes(ticks, sync, sync_count_, k_ % 8 == 0);
    std::memcpy(buf, b.data(), 64);
    const int64_t arrival = t_host + kMs + static_cast<int64_t>(latency_tail_ms_(rng_) * 1e6);
    *clock_ns_ = std::max(*clock_ns_ + 1, arrival);
    if (sync) {  // the camera's frame of this exposure: stamped at the exposure, dequeued 40 ms later
      const auto jitter =
          static_cast<int64_t>((2 * u01_(rng_) - 1) * static_cast<double>(sim_.frame_jitter_ns));
      pending_frames_.push_back({t_host + jitter, sequence_++});
    }
    while (stamps_ != nullptr && !pending_frames_.empty() &&
           pending_frames_.front().t_host_ns + 40 * kMs <= arrival) {
      stamps_->try_push(pending_frames_.front());
      pending_frames_.pop_front();
    }
    truth_host_ns.push_back(t_host);
    next_ticks_ += 64;  // 64 ticks of 39062.5 ns: 2.5 ms
    ++k_;
    ++delivered_;
    return 64;
  }
  void close() override { open_ = false; }

  std::vector<int64_t> truth_host_ns;  // per delivered report, in order

 private:
  McuSim sim_;
  int64_t imu_offset_ns_;
  int64_t* clock_ns_;
  core::SpscRing<CameraFrameStamp>* stamps_;
  std::mt19937_64 rng_;
  std::exponential_distribution<double> latency_tail_ms_{1.0 / 0.3};
  std::uniform_real_distribution<double> u01_{0.0, 1.0};
  uint64_t next_ticks_ = 0;
  uint32_t sync_count_ = 1000;
  uint32_t sequence_ = 0;
  int k_ = 0, delivered_ = 0;
  bool open_ = false, gone_ = false;
  std::deque<CameraFrameStamp> pending_frames_;
};

struct Rig {
  explicit Rig(const McuSim& sim = {}, bool with_stamps = true)
      : imu(4096), mag(1024), stamps(64), clock_ns(sim.t0_host_ns - 10 * kMs) {
    auto dev = std::make_unique<FakeZedMcu>(sim, &clock_ns, with_stamps ? &stamps : nullptr);
    mcu = dev.get();
    ZedSensorOutputs out;
    out.imu = &imu;
    out.mag = &mag;
    out.frame_stamps = with_stamps ? &stamps : nullptr;
    reader = std::make_unique<ZedSensorReader>(std::move(dev), out, ZedHidConfig{}, CameraClockSyncConfig{},
                                               [this]() { return clock_ns; });
  }
  // Steps until n reports were delivered (or a step fails).
  void run_reports(int n) {
    const size_t target = mcu->truth_host_ns.size() + static_cast<size_t>(n);
    for (int guard = 0; mcu->truth_host_ns.size() < target && guard < 4 * n; ++guard) {
      ASSERT_TRUE(reader->step(clock_ns, 0).ok());
    }
  }
  std::vector<ImuSample> drain_imu() {
    std::vector<ImuSample> v;
    ImuSample s;
    while (imu.try_pop(s)) v.push_back(s);
    return v;
  }

  core::SpscRing<ImuSample> imu;
  core::SpscRing<MagSample> mag;
  core::SpscRing<CameraFrameStamp> stamps;
  int64_t clock_ns;
  FakeZedMcu* mcu = nullptr;
  std::unique_ptr<ZedSensorReader> reader;
};

TEST(ZedSensorReader, GivenNoCameraThenSamplesAreOnTheHostClockWithinTheUsbLatencyFloor) {
  McuSim sim;
  sim.camera = false;
  Rig rig(sim, false);
  ASSERT_TRUE(rig.reader->open(rig.clock_ns).ok());
  EXPECT_EQ(rig.mcu->enables, 1);
  rig.run_reports(2000);  // 5 s
  const std::vector<ImuSample> s = rig.drain_imu();
  ASSERT_EQ(s.size(), 2000u);
  for (size_t i = 0; i < s.size(); ++i) {
    // The receipt map's offset is the smallest latency seen: at least the true time, and within
    // the 1 ms floor plus the tail's low end once a few reports have come in.
    const double err_ms = static_cast<double>(s[i].t_ns - rig.mcu->truth_host_ns[i]) / 1e6;
    EXPECT_GE(err_ms, 0.0) << i;
    EXPECT_LT(err_ms, i < 10 ? 3.0 : 1.2) << i;
    if (i > 0) {
      EXPECT_GT(s[i].t_ns, s[i - 1].t_ns);
    }
  }
  EXPECT_NEAR(s[0].accel_mps2.z(), 9.8189, 1e-9);
  EXPECT_NEAR(s[0].gyro_radps.x(), 328 * 1000.0 / 32768.0 * M_PI / 180.0, 1e-12);
  // The magnetometer's new readings only (every 8th report), in µT.
  EXPECT_EQ(rig.mag.size(), 250u);
  MagSample m;
  ASSERT_TRUE(rig.mag.try_pop(m));
  EXPECT_EQ(m.t_ns, s[0].t_ns);
  EXPECT_DOUBLE_EQ(m.field_uT.x(), 20.0);
  EXPECT_DOUBLE_EQ(m.field_uT.z(), -40.0);
  const ZedSensorReaderCounters c = rig.reader->counters();
  EXPECT_EQ(c.imu_samples, 2000u);
  EXPECT_EQ(c.mag_samples, 250u);
  EXPECT_EQ(c.synced_samples, 0u);
  EXPECT_FALSE(c.sync_locked);
  // Keep-alives once a second of the (fake) clock: 5 s of reports.
  EXPECT_GE(rig.mcu->keep_alives, 4);
  EXPECT_LE(rig.mcu->keep_alives, 5);
  EXPECT_EQ(c.keep_alives, static_cast<uint64_t>(rig.mcu->keep_alives));
}

TEST(ZedSensorReader, GivenFrameStampsThenTheFrameSyncLocksAndSamplesShareTheFramesTimeline) {
  Rig rig;
  ASSERT_TRUE(rig.reader->open(rig.clock_ns).ok());
  rig.run_reports(4000);  // 10 s, 250 frames
  const std::vector<ImuSample> s = rig.drain_imu();
  const ZedSensorReaderCounters c = rig.reader->counters();
  ASSERT_TRUE(c.sync_locked);
  EXPECT_NEAR(c.sync_drift_ppm, 50.0, 5.0);
  EXPECT_GT(c.frame_stamps, 200u);
  EXPECT_GT(c.synced_samples, 2000u);  // locked within the first few seconds
  EXPECT_EQ(c.imu_samples, s.size() + 0u);
  EXPECT_EQ(c.imu_samples + c.out_of_order, 4000u);
  EXPECT_LT(c.out_of_order, 3u);  // the step from receipt times to the sync is within the 1 ms floor
  // Once synced, a sample's time is its true host time to within the frame stamps' jitter (±50 µs)
  // and the fit's error (camera_clock_sync.hpp's bound at 16 pairs is ~108 µs): far inside the
  // receipt map's ~1 ms.
  const size_t synced_from = s.size() - c.synced_samples;
  double worst_ns = 0;
  for (size_t i = synced_from; i < s.size(); ++i) {
    const size_t report = i + c.out_of_order;  // the dropped ones came before the sync took over
    worst_ns = std::max(worst_ns, std::fabs(static_cast<double>(s[i].t_ns - rig.mcu->truth_host_ns[report])));
  }
  EXPECT_LT(worst_ns, 108'000.0);
  for (size_t i = 1; i < s.size(); ++i) ASSERT_GT(s[i].t_ns, s[i - 1].t_ns) << i;
}

TEST(ZedSensorReader, GivenRepeatedInvalidForeignAndShortReportsThenEachIsCountedAndSkipped) {
  McuSim sim;
  sim.camera = false;
  Rig rig(sim, false);
  ASSERT_TRUE(rig.reader->open(rig.clock_ns).ok());
  rig.run_reports(4);
  const uint64_t ticks = rig.mcu->last_ticks();
  rig.mcu->injected.push_back(report_bytes(ticks, false, 1000, false));  // the last report again
  Bytes invalid = report_bytes(ticks + 32, false, 1000, false, /*imu_valid=*/false);
  rig.mcu->injected.push_back(invalid);
  Bytes foreign = report_bytes(ticks + 40, false, 1000, false);
  foreign[0] = 0x02;
  rig.mcu->injected.push_back(foreign);
  const Bytes whole = report_bytes(ticks + 48, false, 1000, false);
  rig.mcu->injected.push_back(Bytes(whole.begin(), whole.begin() + 40));
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(rig.reader->step(rig.clock_ns, 0).ok());
  rig.run_reports(4);
  const ZedSensorReaderCounters c = rig.reader->counters();
  EXPECT_EQ(c.repeated, 1u);
  EXPECT_EQ(c.imu_not_valid, 1u);
  EXPECT_EQ(c.parse_errors, 2u);  // the foreign id and the 40-byte report
  EXPECT_EQ(c.imu_samples, 8u);
  EXPECT_EQ(rig.drain_imu().size(), 8u);
}

TEST(ZedSensorReader, GivenTheMcuUnpluggedThenItReconnectsAfterTheBackoffAndRestartsItsClocks) {
  McuSim sim;
  sim.camera = false;
  Rig rig(sim, false);
  rig.mcu->restart_clock_on_open = true;
  ASSERT_TRUE(rig.reader->open(rig.clock_ns).ok());
  rig.mcu->unplug_after_reports = 400;
  rig.run_reports(400);
  ASSERT_TRUE(rig.reader->step(rig.clock_ns, 0).ok());  // NO_DEVICE: counted, not an error
  EXPECT_FALSE(rig.reader->connected());
  EXPECT_EQ(rig.reader->counters().disconnects, 1u);
  const int opens = rig.mcu->opens;
  ASSERT_TRUE(rig.reader->step(rig.clock_ns + 50 * kMs, 0).ok());  // before the 0.1 s backoff
  EXPECT_EQ(rig.mcu->opens, opens);
  rig.clock_ns += 150 * kMs;
  ASSERT_TRUE(rig.reader->step(rig.clock_ns, 0).ok());  // reopened, re-enabled, one report read
  EXPECT_TRUE(rig.reader->connected());
  EXPECT_EQ(rig.mcu->opens, opens + 1);
  EXPECT_EQ(rig.mcu->enables, 2);
  EXPECT_EQ(rig.reader->counters().reconnects, 1u);
  rig.run_reports(400);
  const std::vector<ImuSample> s = rig.drain_imu();
  // The rebooted MCU's clock starts near zero; its samples still land on the host clock.
  ASSERT_EQ(s.size(), 801u);
  for (size_t i = 400; i < s.size(); ++i) {
    const double err_ms = static_cast<double>(s[i].t_ns - rig.mcu->truth_host_ns[i]) / 1e6;
    EXPECT_GE(err_ms, -0.001) << i;
    EXPECT_LT(err_ms, 3.0) << i;
  }
}

TEST(ZedSensorReader, GivenNoDeviceOrNoPermissionAtOpenThenTheErrorSaysWhatToDo) {
  {
    Rig rig;
    rig.mcu->open_result = kUsbErrorNotFound;
    const core::Status st = rig.reader->open(rig.clock_ns);
    EXPECT_EQ(st.code(), core::ErrorCode::kNotFound);
    EXPECT_NE(st.message().find("2b03:f881"), std::string::npos) << st.message();
    EXPECT_NE(st.message().find("lsusb"), std::string::npos) << st.message();
  }
  {
    Rig rig;
    rig.mcu->open_result = kUsbErrorAccess;
    const core::Status st = rig.reader->open(rig.clock_ns);
    EXPECT_EQ(st.code(), core::ErrorCode::kIoError);
    EXPECT_NE(st.message().find("99-hwr.rules"), std::string::npos) << st.message();
  }
}

}  // namespace
}  // namespace hwr::hal::hw
