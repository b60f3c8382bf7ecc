#pragma once
// The ZED 2i's sensor MCU (USB HID 2b03:f881, hardware.md "ZED 2i without the vendor SDK") read
// over libusb: claim its HID interface, enable the sensor stream with the feature report
// {0x32, 0x01}, keep it alive with {0x21, 0xF2} about once a second, and read its 64-byte input
// reports (id 0x01, 62 meaningful bytes, ~400 Hz) as raw bytes for the report parser.
//
// The USB calls go through UsbHidOps, so the tests replace the device with a fake; the real one
// (make_libusb_hid_ops) uses libusb-1.0's synchronous API. Codes follow libusb's numbering
// (enum libusb_error), so the real implementation passes them through unchanged.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "hwr/core/status.hpp"

namespace hwr::hal::hw {

// libusb.h enum libusb_error, value for value (checked against libusb.h in usb_hid.cpp).
enum UsbError : int {
  kUsbSuccess = 0,
  kUsbErrorIo = -1,
  kUsbErrorInvalidParam = -2,
  kUsbErrorAccess = -3,
  kUsbErrorNoDevice = -4,
  kUsbErrorNotFound = -5,
  kUsbErrorBusy = -6,
  kUsbErrorTimeout = -7,
  kUsbErrorOverflow = -8,
  kUsbErrorPipe = -9,
  kUsbErrorInterrupted = -10,
  kUsbErrorNoMem = -11,
  kUsbErrorNotSupported = -12,
  kUsbErrorOther = -99,
};

// "LIBUSB_ERROR_NO_DEVICE" etc.; "LIBUSB_SUCCESS" for 0 and "LIBUSB_ERROR_<n>" for codes it does not
// know.
const char* usb_error_name(int code);

// HID class requests (USB HID 1.11 §7.2): SET_REPORT on the interface, report type in wValue's high
// byte, report id in its low byte.
inline constexpr uint8_t kHidRequestTypeClassInterfaceOut = 0x21;  // host-to-device|class|interface
inline constexpr uint8_t kHidSetReport = 0x09;
inline constexpr uint16_t kHidReportTypeFeature = 3;

// One USB device with one HID interface, as the few synchronous calls ZedHidStream needs.
// Return values: >= 0 success (bytes for transfers), otherwise a negative UsbError.
class UsbHidOps {
 public:
  virtual ~UsbHidOps() = default;
  // Opens the first attached device with this vendor:product id; kUsbErrorNotFound when none is.
  virtual int open(uint16_t vendor, uint16_t product) = 0;
  // Claims the interface, detaching the kernel's usbhid driver while it is claimed (re-attached on
  // close), and finds its interrupt IN endpoint.
  virtual int claim_interface(int interface_number) = 0;
  // A control transfer from host to device (the setup packet's fields, then the data stage).
  virtual int control_out(uint8_t request_type, uint8_t request, uint16_t value, uint16_t index,
                          const uint8_t* data, uint16_t length, unsigned timeout_ms) = 0;
  // One interrupt IN transfer on the claimed interface's IN endpoint: bytes received, or
  // kUsbErrorTimeout when nothing arrived within timeout_ms (libusb: 0 = no limit).
  virtual int interrupt_in(uint8_t* buf, int length, unsigned timeout_ms) = 0;
  // Releases the interface and closes the device; harmless when nothing is open.
  virtual void close() = 0;
};

// The real UsbHidOps over libusb-1.0 (one libusb context per object).
std::unique_ptr<UsbHidOps> make_libusb_hid_ops();

struct ZedHidConfig {
  uint16_t vendor = 0x2b03;   // Stereolabs
  uint16_t product = 0xf881;  // ZED 2i sensor MCU (hardware.md)
  int interface_number = 0;
  int64_t keep_alive_period_ns = 1'000'000'000;  // "about once a second" (hardware.md)
  unsigned control_timeout_ms = 1000;
};

struct ZedHidCounters {
  uint64_t reports = 0;      // transfers with data returned by read_report()
  uint64_t timeouts = 0;     // read_report() calls that saw nothing within their timeout
  uint64_t keep_alives = 0;  // {0x21, 0xF2} reports sent
  uint64_t disconnects = 0;  // Unavailable errors (unplugged, stalled, I/O error)
  uint64_t reconnects = 0;   // start() that succeeded after a disconnect
};

class ZedHidStream {
 public:
  static constexpr size_t kReportBytes = 64;  // one interrupt transfer; byte 0 is the report id
  static constexpr uint8_t kSensorReportId = 0x01;
  // Feature reports (zed-open-capture sensorcapture_def.hpp: REP_ID_SENSOR_STREAM_STATUS = 0x32,
  // REP_ID_REQUEST_SET = 0x21 with RQ_CMD_PING = 0xF2).
  static constexpr uint8_t kStreamEnable[2] = {0x32, 0x01};
  static constexpr uint8_t kKeepAlive[2] = {0x21, 0xF2};

  explicit ZedHidStream(UsbHidOps& ops, ZedHidConfig config = {});
  ~ZedHidStream();  // stop()
  ZedHidStream(const ZedHidStream&) = delete;
  ZedHidStream& operator=(const ZedHidStream&) = delete;

  // Opens the device (closing it first if open), claims the interface and enables the sensor
  // stream; the first keep-alive is due keep_alive_period_ns after now_ns. Also the way back after
  // an Unavailable error (pace the retries with ReconnectBackoff). NotFound: not attached;
  // IoError naming toolchain/deploy/99-hwr.rules: no permission.
  core::Status start(int64_t now_ns);
  // Sends the keep-alive report when it is due at now_ns (the MCU stops streaming without it); call
  // it from the read loop. Unavailable when the device is gone.
  core::Status keep_alive(int64_t now_ns);
  // One input report into buf64 (kReportBytes), raw: its size, or 0 when none arrived within
  // timeout_ms (at least 1 ms: libusb reads 0 as "forever"). Unavailable: unplugged / endpoint
  // stalled / I/O error: start() again later. CorruptData: the device sent more than 64 bytes.
  core::Expected<size_t> read_report(uint8_t* buf64, int timeout_ms);
  // Closes the device (the kernel's usbhid driver takes it back).
  void stop();

  bool is_open() const { return open_; }
  const ZedHidCounters& counters() const { return counters_; }

 private:
  core::Status fail(int code, const char* what);
  core::Status send_feature(const uint8_t (&report)[2], const char* what);

  UsbHidOps& ops_;
  ZedHidConfig config_;
  bool open_ = false;
  bool lost_ = false;  // a disconnect was counted since the last successful start()
  int64_t next_keep_alive_ns_ = 0;
  ZedHidCounters counters_;
  std::string name_;  // "ZED 2i sensor MCU 2b03:f881", for messages
};

}  // namespace hwr::hal::hw
