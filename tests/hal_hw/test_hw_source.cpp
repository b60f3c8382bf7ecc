// HwSource end to end on pseudo-terminals: an A9 and a u-blox (no camera) written by the test, their
// samples arrive in the pipeline's rings on the host clock from the source's own threads; a port
// that hangs up is counted, not fatal; an absent device is named at open; the ZED 2i's IMU and
// magnetometer (a fake sensor MCU behind the USB seam) reach the IMU and magnetometer rings.
#include "hwr/hal/hw/hw_source.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include <fcntl.h>
#include <unistd.h>

#include "a9_frames.hpp"
#include "hwr/hal/hw/ubx_protocol.hpp"
#include "hwr/hal/hw/usb_hid.hpp"

namespace hwr::hal::hw {
namespace {

using Bytes = std::vector<uint8_t>;

struct Pty {
  int master = -1;
  std::string slave;
  Pty() {
    master = ::posix_openpt(O_RDWR | O_NOCTTY);
    if (master >= 0 && ::grantpt(master) == 0 && ::unlockpt(master) == 0) slave = ::ptsname(master);
  }
  ~Pty() { close(); }
  void close() {
    if (master >= 0) ::close(master);
    master = -1;
  }
  void write(const Bytes& b) {
    ASSERT_EQ(::write(master, b.data(), b.size()), static_cast<ssize_t>(b.size()));
  }
};

Bytes a9_imu_frame(uint32_t t_us) {
  return test::make_a9_imu_frame(t_us, {0, 0, 0.5f}, {0, 0, -1.0f}, {0, 0, 0});
}

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

HwConfig serial_only(const std::string& a9, const std::string& gnss) {
  HwConfig c;
  c.camera.enabled = false;
  c.zed_sensors = false;
  c.imu = ImuKind::kA9;
  c.a9_enabled = true;
  c.a9_device = a9;
  c.gnss_enabled = true;
  c.gnss_device = gnss;
  c.gnss_configure = false;
  return c;
}

TEST(HwSource, GivenAnA9AndAGnssOnPtysThenTheirSamplesReachTheRingsFromTheSourceThreads) {
  Pty a9, gnss;
  ASSERT_FALSE(a9.slave.empty());
  ASSERT_FALSE(gnss.slave.empty());
  const int64_t t_open = now_ns();
  auto src = HwSource::open(serial_only(a9.slave, gnss.slave), "hw:test", t_open);
  ASSERT_TRUE(src.ok()) << src.status().message();
  EXPECT_TRUE((*src)->info().has_imu);
  EXPECT_TRUE((*src)->info().has_gnss);
  EXPECT_EQ((*src)->info().first_t_ns, t_open);
  SensorStreamsConfig sc;
  SensorStreams streams(sc);
  ASSERT_TRUE((*src)->start(&streams).ok());

  // Written at the A9's own pace: a sample cannot arrive before it was taken, which is what the
  // receipt-time clock map relies on.
  for (int i = 0; i < 30; ++i) {
    a9.write(a9_imu_frame(1'000'000 + static_cast<uint32_t>(i) * 6667));
    std::this_thread::sleep_for(std::chrono::microseconds(6667));
  }
  gnss.write(Bytes{'$', 'G', 'N'});  // a sentence split across writes
  const std::string gga = "GGA,173002.00,6322.46840,N,01020.45757,E,1,05,7.83,167.0,M,40.1,M,,*45\r\n";
  gnss.write(Bytes(gga.begin(), gga.end()));

  std::vector<ImuSample> imu;
  std::vector<GnssFix> fixes;
  for (int wait = 0; wait < 200 && (imu.size() < 30 || fixes.empty()); ++wait) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    ImuSample s;
    while (streams.imu.try_pop(s)) imu.push_back(s);
    GnssFix f;
    while (streams.gnss.try_pop(f)) fixes.push_back(f);
  }
  ASSERT_EQ(imu.size(), 30u);
  ASSERT_EQ(fixes.size(), 1u);
  EXPECT_TRUE((*src)->poll(now_ns(), &streams).ok());
  // On the host clock, after the source opened, with the A9's own 6667 µs spacing except where the
  // minimum receipt delay improved (by the writer's scheduling jitter, a few ms at most here).
  EXPECT_GE(imu.front().t_ns, t_open);
  EXPECT_LE(imu.back().t_ns, now_ns());
  int exact = 0;
  for (size_t i = 1; i < imu.size(); ++i) {
    const int64_t dt = imu[i].t_ns - imu[i - 1].t_ns;
    EXPECT_GT(dt, 0);
    EXPECT_LE(dt, 6'667'000);  // the offset only ever shrinks within the window
    exact += dt == 6'667'000;
  }
  EXPECT_GE(exact, 10);
  EXPECT_NEAR(imu[0].accel_mps2.z(), 9.80665, 1e-4);
  EXPECT_NEAR(fixes[0].lat_deg, 63.374473, 1e-6);
  EXPECT_EQ((*src)->counters().imu, 30u);
  EXPECT_EQ((*src)->counters().gnss, 1u);

  a9.close();  // unplugged: counted and retried, the source goes on
  for (int wait = 0; wait < 200 && (*src)->hw_counters().a9_disconnects == 0; ++wait) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ((*src)->hw_counters().a9_disconnects, 1u);
  EXPECT_FALSE((*src)->finished());
  EXPECT_TRUE((*src)->poll(now_ns(), &streams).ok());
  (*src)->stop();
}

TEST(HwSource, GivenAnAbsentDeviceThenOpenNamesIt) {
  Pty gnss;
  auto src = HwSource::open(serial_only("/dev/hwr-test-no-a9", gnss.slave), "hw:test", 0);
  ASSERT_FALSE(src.ok());
  EXPECT_EQ(src.status().code(), core::ErrorCode::kNotFound);
  EXPECT_NE(src.status().message().find("a9: /dev/hwr-test-no-a9"), std::string::npos)
      << src.status().message();
}

// A ZED 2i sensor MCU that streams reports at about its own pace (a 2.5 ms tick step per report,
// 1 ms sleep per read so the test does not spin), a new magnetometer reading in every 8th.
class PacedZedMcu final : public UsbHidOps {
 public:
  int open_result = kUsbSuccess;
  int open(uint16_t, uint16_t) override { return open_result; }
  int claim_interface(int) override { return kUsbSuccess; }
  int control_out(uint8_t, uint8_t, uint16_t, uint16_t, const uint8_t*, uint16_t length, unsigned) override {
    return length;
  }
  int interrupt_in(uint8_t* buf, int length, unsigned) override {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    if (length < 64) return kUsbErrorOverflow;
    std::memset(buf, 0, 64);
    buf[0] = 0x01;
    const uint64_t ticks = 1'000'000 + 64 * k_;  // 39062.5 ns ticks: 2.5 ms apart
    for (int i = 0; i < 8; ++i) buf[2 + i] = static_cast<uint8_t>(ticks >> (8 * i));
    buf[21] = 0x10;  // accel z = 4096 counts = 9.8189 m/s² (little-endian 0x1000)
    buf[30] = k_ % 8 == 0 ? 2 : 1;
    buf[31] = 0x40;  // mag x = 0x0140 = 320 counts = 20 µT
    buf[32] = 0x01;
    ++k_;
    return 64;
  }
  void close() override {}

 private:
  uint64_t k_ = 0;
};

TEST(HwSource, GivenTheZedSensorMcuThenItsImuAndMagnetometerReachTheRingsOnTheHostClock) {
  HwConfig c;
  c.camera.enabled = false;  // no frames: the samples are timed by their receipt
  const int64_t t_open = now_ns();
  auto src = HwSource::open(c, "hw:test", t_open, std::make_unique<PacedZedMcu>());
  ASSERT_TRUE(src.ok()) << src.status().message();
  EXPECT_TRUE((*src)->info().has_imu);
  EXPECT_TRUE((*src)->info().has_mag);
  EXPECT_DOUBLE_EQ((*src)->info().imu_rate_hz, 400.0);
  SensorStreamsConfig sc;
  SensorStreams streams(sc);
  ASSERT_TRUE((*src)->start(&streams).ok());
  for (int wait = 0; wait < 500 && streams.imu.size() < 100; ++wait) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  (*src)->stop();
  ASSERT_GE(streams.imu.size(), 100u);
  ImuSample prev, s;
  ASSERT_TRUE(streams.imu.try_pop(prev));
  EXPECT_GE(prev.t_ns, t_open);  // on the host's CLOCK_MONOTONIC, after the source opened
  EXPECT_LE(prev.t_ns, now_ns());
  EXPECT_NEAR(prev.accel_mps2.z(), 9.8189, 1e-9);
  while (streams.imu.try_pop(s)) {
    EXPECT_GT(s.t_ns, prev.t_ns);
    prev = s;
  }
  EXPECT_GE(streams.mag.size(), 10u);
  MagSample m;
  ASSERT_TRUE(streams.mag.try_pop(m));
  EXPECT_DOUBLE_EQ(m.field_uT.x(), 20.0);
  EXPECT_GE((*src)->counters().imu, 100u);
  EXPECT_GE((*src)->counters().mag, 10u);
  EXPECT_FALSE((*src)->hw_counters().zed_clock_synced);  // no camera, no frame sync
  EXPECT_FALSE((*src)->finished());
}

TEST(HwSource, GivenTheZedSensorMcuAbsentThenOpenNamesIt) {
  HwConfig c;
  c.camera.enabled = false;
  auto mcu = std::make_unique<PacedZedMcu>();
  mcu->open_result = kUsbErrorNotFound;
  auto src = HwSource::open(c, "hw:test", 0, std::move(mcu));
  ASSERT_FALSE(src.ok());
  EXPECT_EQ(src.status().code(), core::ErrorCode::kNotFound);
  EXPECT_NE(src.status().message().find("zed_sensors: ZED 2i sensor MCU 2b03:f881"), std::string::npos)
      << src.status().message();
}

TEST(HwSource, GivenAMissingCalibrationFileThenOpenSaysWhereToGetIt) {
  HwConfig c;
  c.zed_sensors = false;
  c.camera.calibration = "/nonexistent/SN1.conf";
  auto src = HwSource::open(c, "hw:test", 0);
  ASSERT_FALSE(src.ok());
  EXPECT_NE(src.status().message().find("camera: "), std::string::npos);
  EXPECT_NE(src.status().message().find("calib.stereolabs.com"), std::string::npos) << src.status().message();
}

}  // namespace
}  // namespace hwr::hal::hw
