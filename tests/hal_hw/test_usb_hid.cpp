// ZedHidStream against a fake USB device (FakeHidDevice records every call with its setup packet):
// the stream-enable report goes out first with the exact HID SET_REPORT setup, keep-alives follow
// once a second of the caller's clock, reports pass through untouched, an unplugged device is
// Unavailable and start() re-enables the stream, permissions and timeouts are reported plainly. The
// real libusb implementation, on a machine without the device, says NotFound.
#include "hwr/hal/hw/usb_hid.hpp"

#include "hwr/hal/hw/reconnect_backoff.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <algorithm>
#include <cstring>
#include <deque>
#include <string>
#include <vector>

namespace hwr::hal::hw {
namespace {

struct Call {
  enum Kind { kOpen, kClaim, kControlOut, kInterruptIn, kClose };
  explicit Call(Kind k) : kind(k) {}
  Kind kind;
  uint16_t vendor = 0, product = 0;
  int interface_number = -1;
  uint8_t request_type = 0, request = 0;
  uint16_t value = 0, index = 0;
  std::vector<uint8_t> data;
  int length = 0;
  unsigned timeout_ms = 0;
};

// A device whose answers the test sets; every call is logged in order.
class FakeHidDevice final : public UsbHidOps {
 public:
  int open_result = kUsbSuccess;
  int claim_result = kUsbSuccess;
  int control_result = -1;  // < 0 and not an error code: "echo length"; else returned as is
  // What interrupt_in returns, one entry per call: a report, or an error code when empty.
  struct Read {
    std::vector<uint8_t> bytes;
    int code = 0;
  };
  std::deque<Read> reads;
  int idle_read_code = kUsbErrorTimeout;  // when reads is empty
  std::vector<Call> calls;
  bool is_open = false;

  int open(uint16_t vendor, uint16_t product) override {
    Call c(Call::kOpen);
    c.vendor = vendor;
    c.product = product;
    calls.push_back(c);
    if (open_result == kUsbSuccess) is_open = true;
    return open_result;
  }
  int claim_interface(int interface_number) override {
    Call c(Call::kClaim);
    c.interface_number = interface_number;
    calls.push_back(c);
    return is_open ? claim_result : kUsbErrorNoDevice;
  }
  int control_out(uint8_t request_type, uint8_t request, uint16_t value, uint16_t index, const uint8_t* data,
                  uint16_t length, unsigned timeout_ms) override {
    Call c(Call::kControlOut);
    c.request_type = request_type;
    c.request = request;
    c.value = value;
    c.index = index;
    c.data.assign(data, data + length);
    c.length = length;
    c.timeout_ms = timeout_ms;
    calls.push_back(c);
    if (!is_open) return kUsbErrorNoDevice;
    return control_result == -1 ? length : control_result;
  }
  int interrupt_in(uint8_t* buf, int length, unsigned timeout_ms) override {
    Call c(Call::kInterruptIn);
    c.length = length;
    c.timeout_ms = timeout_ms;
    calls.push_back(c);
    if (!is_open) return kUsbErrorNoDevice;
    if (reads.empty()) return idle_read_code;
    Read r = reads.front();
    reads.pop_front();
    if (r.bytes.empty()) return r.code;
    const int n = std::min(length, static_cast<int>(r.bytes.size()));
    std::memcpy(buf, r.bytes.data(), static_cast<size_t>(n));
    return n;
  }
  void close() override {
    calls.emplace_back(Call::kClose);
    is_open = false;
  }

  std::vector<Call> control_calls() const {
    std::vector<Call> out;
    for (const Call& c : calls) {
      if (c.kind == Call::kControlOut) out.push_back(c);
    }
    return out;
  }
  int count_reports(uint8_t id, uint8_t byte1) const {
    int n = 0;
    for (const Call& c : control_calls()) {
      if (c.data.size() == 2 && c.data[0] == id && c.data[1] == byte1) ++n;
    }
    return n;
  }
};

// A 64-byte input report as the MCU sends it: id 0x01, then recognisable bytes.
std::vector<uint8_t> sensor_report(uint8_t seed) {
  std::vector<uint8_t> r(64);
  r[0] = 0x01;
  for (size_t i = 1; i < r.size(); ++i) r[i] = static_cast<uint8_t>(seed + i * 7);
  return r;
}

constexpr int64_t kMs = 1'000'000;

TEST(ZedHidStream, GivenStartThenTheEnableReportGoesFirstWithTheExactSetupPacket) {
  FakeHidDevice dev;
  ZedHidStream zed(dev);
  ASSERT_TRUE(zed.start(0).ok());
  EXPECT_TRUE(zed.is_open());

  ASSERT_EQ(dev.calls.size(), 3u);
  EXPECT_EQ(dev.calls[0].kind, Call::kOpen);
  EXPECT_EQ(dev.calls[0].vendor, 0x2b03);  // hardware.md: sensor MCU 2b03:f881
  EXPECT_EQ(dev.calls[0].product, 0xf881);
  EXPECT_EQ(dev.calls[1].kind, Call::kClaim);
  EXPECT_EQ(dev.calls[1].interface_number, 0);
  const Call& enable = dev.calls[2];
  ASSERT_EQ(enable.kind, Call::kControlOut);
  EXPECT_EQ(enable.request_type, 0x21);  // host-to-device | class | interface
  EXPECT_EQ(enable.request, 0x09);       // SET_REPORT
  EXPECT_EQ(enable.value, 0x0332);       // (Feature = 3) << 8 | report id 0x32
  EXPECT_EQ(enable.index, 0);            // interface 0
  EXPECT_EQ(enable.data, (std::vector<uint8_t>{0x32, 0x01}));
  EXPECT_GT(enable.timeout_ms, 0u);  // 0 would be "wait forever" to libusb
}

TEST(ZedHidStream, GivenAFiveSecondReadLoopThenAboutFiveKeepAlivesWithTheExactSetup) {
  FakeHidDevice dev;
  ZedHidStream zed(dev);
  ASSERT_TRUE(zed.start(0).ok());
  uint8_t buf[64];
  size_t reports = 0;
  // 400 Hz reports for 5 s of the test's clock: keep_alive() then read_report() per loop turn.
  for (int64_t t_ns = 0; t_ns <= 5000 * kMs; t_ns += 2'500'000) {
    dev.reads.push_back({sensor_report(static_cast<uint8_t>(t_ns / kMs)), 0});
    ASSERT_TRUE(zed.keep_alive(t_ns).ok());
    auto n = zed.read_report(buf, 10);
    ASSERT_TRUE(n.ok()) << n.status().message();
    reports += n.value() > 0 ? 1 : 0;
  }
  const int keep_alives = dev.count_reports(0x21, 0xF2);
  EXPECT_NEAR(keep_alives, 5, 1);
  EXPECT_EQ(zed.counters().keep_alives, static_cast<uint64_t>(keep_alives));
  EXPECT_EQ(reports, 2001u);
  EXPECT_EQ(zed.counters().reports, 2001u);
  EXPECT_EQ(dev.count_reports(0x32, 0x01), 1);  // enabled once, not re-sent by the loop
  for (const Call& c : dev.control_calls()) {
    if (c.data[0] != 0x21) continue;
    EXPECT_EQ(c.request_type, 0x21);
    EXPECT_EQ(c.request, 0x09);
    EXPECT_EQ(c.value, 0x0321);  // Feature, report id 0x21 (REP_ID_REQUEST_SET)
    EXPECT_EQ(c.index, 0);
  }
}

TEST(ZedHidStream, GivenTheLoopStalledForTenSecondsThenOneKeepAliveNotABurst) {
  FakeHidDevice dev;
  ZedHidStream zed(dev);
  ASSERT_TRUE(zed.start(0).ok());
  ASSERT_TRUE(zed.keep_alive(999 * kMs).ok());
  EXPECT_EQ(dev.count_reports(0x21, 0xF2), 0);  // not due before 1 s
  ASSERT_TRUE(zed.keep_alive(10'000 * kMs).ok());
  ASSERT_TRUE(zed.keep_alive(10'001 * kMs).ok());
  EXPECT_EQ(dev.count_reports(0x21, 0xF2), 1);
  ASSERT_TRUE(zed.keep_alive(11'000 * kMs).ok());  // due again one period after the late one
  EXPECT_EQ(dev.count_reports(0x21, 0xF2), 2);
}

TEST(ZedHidStream, GivenAReportThenItsBytesPassThroughUntouched) {
  FakeHidDevice dev;
  ZedHidStream zed(dev);
  ASSERT_TRUE(zed.start(0).ok());
  const std::vector<uint8_t> report = sensor_report(3);
  dev.reads.push_back({report, 0});
  uint8_t buf[64] = {};
  auto n = zed.read_report(buf, 5);
  ASSERT_TRUE(n.ok());
  ASSERT_EQ(n.value(), 64u);
  EXPECT_EQ(0, std::memcmp(buf, report.data(), report.size()));
  EXPECT_EQ(dev.calls.back().length, 64);  // one 64-byte interrupt transfer
  EXPECT_EQ(dev.calls.back().timeout_ms, 5u);
}

TEST(ZedHidStream, GivenNothingArrivesThenZeroBytesAndTheStreamStaysOpen) {
  FakeHidDevice dev;
  ZedHidStream zed(dev);
  ASSERT_TRUE(zed.start(0).ok());
  uint8_t buf[64];
  auto n = zed.read_report(buf, 20);
  ASSERT_TRUE(n.ok()) << n.status().message();
  EXPECT_EQ(n.value(), 0u);
  auto zero_wait = zed.read_report(buf, 0);
  ASSERT_TRUE(zero_wait.ok());
  EXPECT_EQ(zero_wait.value(), 0u);
  EXPECT_GE(dev.calls.back().timeout_ms, 1u);  // never libusb's 0 = forever
  EXPECT_EQ(zed.counters().timeouts, 2u);
  EXPECT_EQ(zed.counters().disconnects, 0u);
  EXPECT_TRUE(zed.is_open());
}

TEST(ZedHidStream, GivenUnplugMidStreamThenUnavailableAndStartReEnablesTheStream) {
  FakeHidDevice dev;
  ZedHidStream zed(dev);
  ASSERT_TRUE(zed.start(0).ok());
  uint8_t buf[64];
  dev.reads.push_back({sensor_report(1), 0});
  dev.reads.push_back({{}, kUsbErrorNoDevice});
  ASSERT_TRUE(zed.read_report(buf, 10).ok());
  auto lost = zed.read_report(buf, 10);
  ASSERT_FALSE(lost.ok());
  EXPECT_EQ(lost.status().code(), core::ErrorCode::kUnavailable);
  EXPECT_NE(lost.status().message().find("2b03:f881"), std::string::npos) << lost.status().message();
  EXPECT_NE(lost.status().message().find("LIBUSB_ERROR_NO_DEVICE"), std::string::npos);
  EXPECT_FALSE(zed.is_open());
  EXPECT_FALSE(dev.is_open);  // the dead handle was released
  EXPECT_EQ(zed.counters().disconnects, 1u);
  EXPECT_EQ(zed.read_report(buf, 10).status().code(), core::ErrorCode::kUnavailable);
  EXPECT_EQ(zed.keep_alive(5000 * kMs).code(), core::ErrorCode::kUnavailable);

  // Still unplugged: the retry says so and is not counted as another disconnect.
  dev.open_result = kUsbErrorNotFound;
  core::Status absent = zed.start(100 * kMs);
  EXPECT_EQ(absent.code(), core::ErrorCode::kNotFound);
  EXPECT_EQ(zed.counters().disconnects, 1u);
  EXPECT_EQ(zed.counters().reconnects, 0u);

  // Replugged: a fresh open, claim and enable, in that order.
  dev.open_result = kUsbSuccess;
  dev.calls.clear();
  ASSERT_TRUE(zed.start(300 * kMs).ok());
  ASSERT_GE(dev.calls.size(), 3u);
  EXPECT_EQ(dev.calls[dev.calls.size() - 3].kind, Call::kOpen);
  EXPECT_EQ(dev.calls[dev.calls.size() - 2].kind, Call::kClaim);
  EXPECT_EQ(dev.calls.back().kind, Call::kControlOut);
  EXPECT_EQ(dev.calls.back().data, (std::vector<uint8_t>{0x32, 0x01}));
  EXPECT_EQ(zed.counters().reconnects, 1u);
  // The keep-alive clock restarted with the stream.
  ASSERT_TRUE(zed.keep_alive(1299 * kMs).ok());
  EXPECT_EQ(dev.count_reports(0x21, 0xF2), 0);
  ASSERT_TRUE(zed.keep_alive(1300 * kMs).ok());
  EXPECT_EQ(dev.count_reports(0x21, 0xF2), 1);
}

// The read loop a SensorSource runs: keep_alive + read_report, and on Unavailable start() again
// when ReconnectBackoff says so. Unplugged from 1 s to 4 s of the test's clock.
TEST(ZedHidStream, GivenAThreeSecondUnplugThenTheLoopRetriesSparinglyAndIsBackWithinTwoSeconds) {
  FakeHidDevice dev;
  ZedHidStream zed(dev);
  ReconnectBackoff backoff;
  ASSERT_TRUE(zed.start(0).ok());
  int open_attempts = 0;
  int64_t back_at_ns = -1;
  uint8_t buf[64];
  for (int64_t t_ns = 0; t_ns <= 8000 * kMs; t_ns += 2'500'000) {
    if (t_ns == 1000 * kMs) {  // unplug
      dev.is_open = false;
      dev.open_result = kUsbErrorNotFound;
    }
    if (t_ns == 4000 * kMs) dev.open_result = kUsbSuccess;  // replug
    if (!zed.is_open()) {
      if (!backoff.due(t_ns)) continue;
      ++open_attempts;
      if (zed.start(t_ns).ok()) {
        backoff.succeeded();
        if (back_at_ns < 0) back_at_ns = t_ns;
      } else {
        backoff.failed(t_ns);
      }
      continue;
    }
    dev.reads.push_back({sensor_report(1), 0});
    core::Status ka = zed.keep_alive(t_ns);
    auto n = ka.ok() ? zed.read_report(buf, 10) : core::Expected<size_t>(ka);
    if (!n.ok()) {
      ASSERT_EQ(n.status().code(), core::ErrorCode::kUnavailable) << n.status().message();
      backoff.failed(t_ns);
    }
  }
  // Retries at 1.1, 1.3, 1.7, 2.5 s (0.1 s doubling) fail, 4.1 s succeeds: ReconnectBackoff's
  // schedule, at most one attempt per 2 s once it has grown.
  EXPECT_EQ(open_attempts, 5);
  EXPECT_EQ(back_at_ns, 4100 * kMs);
  EXPECT_LE(back_at_ns, 4000 * kMs + ReconnectBackoff::kMaxNs);
  EXPECT_EQ(zed.counters().disconnects, 1u);
  EXPECT_EQ(zed.counters().reconnects, 1u);
  EXPECT_EQ(dev.count_reports(0x32, 0x01), 2);  // enabled at start and again after the replug
  EXPECT_TRUE(zed.is_open());
}

TEST(ZedHidStream, GivenAStallOrIoErrorThenUnavailableToo) {
  for (int code : {kUsbErrorPipe, kUsbErrorIo}) {
    FakeHidDevice dev;
    ZedHidStream zed(dev);
    ASSERT_TRUE(zed.start(0).ok());
    dev.reads.push_back({{}, code});
    uint8_t buf[64];
    auto n = zed.read_report(buf, 10);
    ASSERT_FALSE(n.ok());
    EXPECT_EQ(n.status().code(), core::ErrorCode::kUnavailable) << usb_error_name(code);
    EXPECT_NE(n.status().message().find(usb_error_name(code)), std::string::npos);
    EXPECT_EQ(zed.counters().disconnects, 1u);
  }
}

TEST(ZedHidStream, GivenAnOverlongReportThenCorruptDataAndTheStreamStaysOpen) {
  FakeHidDevice dev;
  ZedHidStream zed(dev);
  ASSERT_TRUE(zed.start(0).ok());
  dev.reads.push_back({{}, kUsbErrorOverflow});
  dev.reads.push_back({sensor_report(9), 0});
  uint8_t buf[64];
  auto n = zed.read_report(buf, 10);
  ASSERT_FALSE(n.ok());
  EXPECT_EQ(n.status().code(), core::ErrorCode::kCorruptData) << n.status().message();
  EXPECT_TRUE(zed.is_open());
  EXPECT_EQ(zed.counters().disconnects, 0u);
  auto next = zed.read_report(buf, 10);
  ASSERT_TRUE(next.ok());
  EXPECT_EQ(next.value(), 64u);
}

TEST(ZedHidStream, GivenTheDeviceGoneWhenAKeepAliveIsDueThenUnavailable) {
  FakeHidDevice dev;
  ZedHidStream zed(dev);
  ASSERT_TRUE(zed.start(0).ok());
  dev.control_result = kUsbErrorNoDevice;
  core::Status st = zed.keep_alive(1000 * kMs);
  EXPECT_EQ(st.code(), core::ErrorCode::kUnavailable);
  EXPECT_NE(st.message().find("keep-alive"), std::string::npos) << st.message();
  EXPECT_EQ(zed.counters().keep_alives, 0u);
  EXPECT_EQ(zed.counters().disconnects, 1u);
  EXPECT_FALSE(zed.is_open());
}

TEST(ZedHidStream, GivenAShortControlWriteThenTheEnableFailsAndTheDeviceIsReleased) {
  FakeHidDevice dev;
  dev.control_result = 1;  // took one of two bytes
  ZedHidStream zed(dev);
  core::Status st = zed.start(0);
  EXPECT_EQ(st.code(), core::ErrorCode::kUnavailable);
  EXPECT_NE(st.message().find("enable the sensor stream"), std::string::npos) << st.message();
  EXPECT_FALSE(zed.is_open());
  EXPECT_FALSE(dev.is_open);
}

TEST(ZedHidStream, GivenNoPermissionThenTheMessageNamesTheUdevRules) {
  FakeHidDevice dev;
  dev.open_result = kUsbErrorAccess;
  ZedHidStream zed(dev);
  core::Status st = zed.start(0);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.code(), core::ErrorCode::kIoError);
  EXPECT_NE(st.message().find("toolchain/deploy/99-hwr.rules"), std::string::npos) << st.message();
  EXPECT_NE(st.message().find("2b03:f881"), std::string::npos);
  EXPECT_FALSE(zed.is_open());
  EXPECT_EQ(dev.count_reports(0x32, 0x01), 0);
}

TEST(ZedHidStream, GivenTheInterfaceBusyThenItSaysAnotherProgramHoldsIt) {
  FakeHidDevice dev;
  dev.claim_result = kUsbErrorBusy;
  ZedHidStream zed(dev);
  core::Status st = zed.start(0);
  EXPECT_EQ(st.code(), core::ErrorCode::kIoError);
  EXPECT_NE(st.message().find("another program"), std::string::npos) << st.message();
  EXPECT_FALSE(zed.is_open());
  EXPECT_FALSE(dev.is_open);  // opened, then closed again
  EXPECT_EQ(dev.count_reports(0x32, 0x01), 0);
}

TEST(ZedHidStream, GivenADifferentInterfaceThenTheSetupAddressesIt) {
  FakeHidDevice dev;
  ZedHidConfig config;
  config.interface_number = 2;
  ZedHidStream zed(dev, config);
  ASSERT_TRUE(zed.start(0).ok());
  EXPECT_EQ(dev.calls[1].interface_number, 2);
  EXPECT_EQ(dev.control_calls().at(0).index, 2);
}

TEST(ZedHidStream, GivenStopThenTheDeviceIsClosedOnce) {
  FakeHidDevice dev;
  {
    ZedHidStream zed(dev);
    ASSERT_TRUE(zed.start(0).ok());
    zed.stop();
    EXPECT_FALSE(dev.is_open);
  }  // the destructor does not close again
  int closes = 0;
  for (const Call& c : dev.calls) closes += c.kind == Call::kClose ? 1 : 0;
  EXPECT_EQ(closes, 1);
}

TEST(UsbError, NamesFollowLibusb) {
  EXPECT_STREQ(usb_error_name(kUsbSuccess), "LIBUSB_SUCCESS");
  EXPECT_STREQ(usb_error_name(-4), "LIBUSB_ERROR_NO_DEVICE");
  EXPECT_STREQ(usb_error_name(-7), "LIBUSB_ERROR_TIMEOUT");
  EXPECT_STREQ(usb_error_name(-9), "LIBUSB_ERROR_PIPE");
  EXPECT_STREQ(usb_error_name(-99), "LIBUSB_ERROR_OTHER");
  EXPECT_STREQ(usb_error_name(-55), "LIBUSB_ERROR_<unknown>");
}

// The real libusb path on this machine: an id no device has (ffff:fffe) is NotFound with a message
// that names it, whether or not the machine has usbfs at all.
TEST(LibusbHidOps, GivenNoSuchDeviceThenNotFoundNamesTheId) {
  std::unique_ptr<UsbHidOps> ops = make_libusb_hid_ops();
  uint8_t buf[64];
  EXPECT_EQ(ops->interrupt_in(buf, 64, 1), kUsbErrorNoDevice);  // nothing open yet
  ZedHidConfig config;
  config.vendor = 0xffff;
  config.product = 0xfffe;
  ZedHidStream zed(*ops, config);
  core::Status st = zed.start(0);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.code(), core::ErrorCode::kNotFound) << st.message();
  EXPECT_NE(st.message().find("ffff:fffe"), std::string::npos) << st.message();
  EXPECT_NE(st.message().find("plugged in"), std::string::npos) << st.message();
  ops->close();  // harmless with nothing open
}

}  // namespace
}  // namespace hwr::hal::hw
