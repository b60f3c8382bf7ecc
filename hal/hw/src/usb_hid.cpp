#include "hwr/hal/hw/usb_hid.hpp"

// libusb.h declares C99 flexible arrays (ZERO_SIZED_ARRAY), which -Wpedantic refuses in C++. The
// normal build includes it as a system header; the fuzz build's instrumented copy of this library
// (tests/fuzz/CMakeLists.txt) does not keep that, so the warning is silenced here for this header.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpedantic"
#include <libusb.h>
#pragma GCC diagnostic pop

#include <cstdio>
#include <string>

namespace hwr::hal::hw {

namespace {
constexpr bool same_code(int ours, int libusb) { return ours == libusb; }
}  // namespace
static_assert(same_code(kUsbErrorIo, LIBUSB_ERROR_IO) &&
                  same_code(kUsbErrorInvalidParam, LIBUSB_ERROR_INVALID_PARAM) &&
                  same_code(kUsbErrorAccess, LIBUSB_ERROR_ACCESS) &&
                  same_code(kUsbErrorNoDevice, LIBUSB_ERROR_NO_DEVICE) &&
                  same_code(kUsbErrorNotFound, LIBUSB_ERROR_NOT_FOUND) &&
                  same_code(kUsbErrorBusy, LIBUSB_ERROR_BUSY) &&
                  same_code(kUsbErrorTimeout, LIBUSB_ERROR_TIMEOUT) &&
                  same_code(kUsbErrorOverflow, LIBUSB_ERROR_OVERFLOW) &&
                  same_code(kUsbErrorPipe, LIBUSB_ERROR_PIPE) &&
                  same_code(kUsbErrorInterrupted, LIBUSB_ERROR_INTERRUPTED) &&
                  same_code(kUsbErrorNoMem, LIBUSB_ERROR_NO_MEM) &&
                  same_code(kUsbErrorNotSupported, LIBUSB_ERROR_NOT_SUPPORTED) &&
                  same_code(kUsbErrorOther, LIBUSB_ERROR_OTHER),
              "UsbError must mirror libusb.h enum libusb_error");

const char* usb_error_name(int code) {
  switch (code) {
    case kUsbSuccess:
      return "LIBUSB_SUCCESS";
    case kUsbErrorIo:
      return "LIBUSB_ERROR_IO";
    case kUsbErrorInvalidParam:
      return "LIBUSB_ERROR_INVALID_PARAM";
    case kUsbErrorAccess:
      return "LIBUSB_ERROR_ACCESS";
    case kUsbErrorNoDevice:
      return "LIBUSB_ERROR_NO_DEVICE";
    case kUsbErrorNotFound:
      return "LIBUSB_ERROR_NOT_FOUND";
    case kUsbErrorBusy:
      return "LIBUSB_ERROR_BUSY";
    case kUsbErrorTimeout:
      return "LIBUSB_ERROR_TIMEOUT";
    case kUsbErrorOverflow:
      return "LIBUSB_ERROR_OVERFLOW";
    case kUsbErrorPipe:
      return "LIBUSB_ERROR_PIPE";
    case kUsbErrorInterrupted:
      return "LIBUSB_ERROR_INTERRUPTED";
    case kUsbErrorNoMem:
      return "LIBUSB_ERROR_NO_MEM";
    case kUsbErrorNotSupported:
      return "LIBUSB_ERROR_NOT_SUPPORTED";
    case kUsbErrorOther:
      return "LIBUSB_ERROR_OTHER";
    default:
      return "LIBUSB_ERROR_<unknown>";
  }
}

namespace {

// ---- the real device: libusb-1.0 synchronous API ----

class LibusbHidOps final : public UsbHidOps {
 public:
  LibusbHidOps() = default;
  ~LibusbHidOps() override {
    close();
    if (ctx_ != nullptr) libusb_exit(ctx_);
  }
  LibusbHidOps(const LibusbHidOps&) = delete;
  LibusbHidOps& operator=(const LibusbHidOps&) = delete;

  int open(uint16_t vendor, uint16_t product) override {
    close();
    if (ctx_ == nullptr) {
      const int r = libusb_init(&ctx_);
      if (r != LIBUSB_SUCCESS) {
        ctx_ = nullptr;
        // No usbfs (a container without /dev/bus/usb): no device can be found this way.
        return r == LIBUSB_ERROR_ACCESS ? r : LIBUSB_ERROR_NOT_FOUND;
      }
    }
    libusb_device** list = nullptr;
    const ssize_t n = libusb_get_device_list(ctx_, &list);
    if (n < 0) return static_cast<int>(n);
    int result = LIBUSB_ERROR_NOT_FOUND;
    for (ssize_t i = 0; i < n; ++i) {
      libusb_device_descriptor desc{};
      if (libusb_get_device_descriptor(list[i], &desc) != LIBUSB_SUCCESS) continue;
      if (desc.idVendor != vendor || desc.idProduct != product) continue;
      result = libusb_open(list[i], &handle_);  // takes its own reference on the device
      if (result == LIBUSB_SUCCESS) {
        device_ = libusb_get_device(handle_);
        break;
      }
      handle_ = nullptr;  // e.g. ACCESS on this one: try another with the same id, keep the error
    }
    libusb_free_device_list(list, 1);
    return result;
  }

  int claim_interface(int interface_number) override {
    if (handle_ == nullptr) return LIBUSB_ERROR_NO_DEVICE;
    // usbhid owns the interface; libusb detaches it for the claim and re-attaches it on release.
    // NOT_SUPPORTED (no kernel-driver control on this platform) leaves the claim to decide.
    const int d = libusb_set_auto_detach_kernel_driver(handle_, 1);
    if (d != LIBUSB_SUCCESS && d != LIBUSB_ERROR_NOT_SUPPORTED) return d;
    const int r = libusb_claim_interface(handle_, interface_number);
    if (r != LIBUSB_SUCCESS) return r;
    claimed_ = interface_number;
    return find_interrupt_in(interface_number);
  }

  int control_out(uint8_t request_type, uint8_t request, uint16_t value, uint16_t index, const uint8_t* data,
                  uint16_t length, unsigned timeout_ms) override {
    if (handle_ == nullptr) return LIBUSB_ERROR_NO_DEVICE;
    // libusb takes a non-const buffer for both directions; an OUT transfer only reads it.
    return libusb_control_transfer(handle_, request_type, request, value, index, const_cast<uint8_t*>(data),
                                   length, timeout_ms);
  }

  int interrupt_in(uint8_t* buf, int length, unsigned timeout_ms) override {
    if (handle_ == nullptr || endpoint_in_ == 0) return LIBUSB_ERROR_NO_DEVICE;
    int transferred = 0;
    const int r = libusb_interrupt_transfer(handle_, endpoint_in_, buf, length, &transferred, timeout_ms);
    // A timeout may still have moved part of a report (libusb populates transferred).
    if (r == LIBUSB_SUCCESS || (r == LIBUSB_ERROR_TIMEOUT && transferred > 0)) return transferred;
    return r;
  }

  void close() override {
    if (handle_ == nullptr) return;
    if (claimed_ >= 0) libusb_release_interface(handle_, claimed_);  // fails harmlessly when unplugged
    libusb_close(handle_);
    handle_ = nullptr;
    device_ = nullptr;
    claimed_ = -1;
    endpoint_in_ = 0;
  }

 private:
  // The interface's first interrupt IN endpoint, from the active configuration descriptor
  // (USB 2.0 §9.6.6: bEndpointAddress bit 7 = IN, bmAttributes bits 1..0 = 3 interrupt).
  int find_interrupt_in(int interface_number) {
    libusb_config_descriptor* config = nullptr;
    const int r = libusb_get_active_config_descriptor(device_, &config);
    if (r != LIBUSB_SUCCESS) return r;
    int result = LIBUSB_ERROR_NOT_FOUND;
    for (int i = 0; i < config->bNumInterfaces && result != LIBUSB_SUCCESS; ++i) {
      const libusb_interface& itf = config->interface[i];
      for (int a = 0; a < itf.num_altsetting && result != LIBUSB_SUCCESS; ++a) {
        const libusb_interface_descriptor& alt = itf.altsetting[a];
        if (alt.bInterfaceNumber != interface_number || alt.bAlternateSetting != 0) continue;
        for (int e = 0; e < alt.bNumEndpoints; ++e) {
          const libusb_endpoint_descriptor& ep = alt.endpoint[e];
          if ((ep.bEndpointAddress & LIBUSB_ENDPOINT_DIR_MASK) == LIBUSB_ENDPOINT_IN &&
              (ep.bmAttributes & LIBUSB_TRANSFER_TYPE_MASK) == LIBUSB_TRANSFER_TYPE_INTERRUPT) {
            endpoint_in_ = ep.bEndpointAddress;
            result = LIBUSB_SUCCESS;
            break;
          }
        }
      }
    }
    libusb_free_config_descriptor(config);
    return result;
  }

  libusb_context* ctx_ = nullptr;
  libusb_device_handle* handle_ = nullptr;
  libusb_device* device_ = nullptr;  // owned by handle_
  int claimed_ = -1;
  uint8_t endpoint_in_ = 0;
};

std::string usb_id(uint16_t vendor, uint16_t product) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%04x:%04x", vendor, product);
  return buf;
}

}  // namespace

std::unique_ptr<UsbHidOps> make_libusb_hid_ops() { return std::make_unique<LibusbHidOps>(); }

// ---- ZedHidStream ----

ZedHidStream::ZedHidStream(UsbHidOps& ops, ZedHidConfig config)
    : ops_(ops), config_(config), name_("ZED 2i sensor MCU " + usb_id(config.vendor, config.product)) {}

ZedHidStream::~ZedHidStream() { stop(); }

void ZedHidStream::stop() {
  if (!open_) return;
  ops_.close();
  open_ = false;
}

core::Status ZedHidStream::fail(int code, const char* what) {
  const std::string detail = name_ + ": " + what + ": " + usb_error_name(code);
  switch (code) {
    case kUsbErrorNotFound:
      return core::NotFound(detail + " (not attached: is the ZED 2i plugged in? `lsusb -d " +
                            usb_id(config_.vendor, config_.product) + "` should list it)");
    case kUsbErrorAccess:
      return core::IoError(detail +
                           " (no permission on the USB device node: install "
                           "toolchain/deploy/99-hwr.rules and add the user to the plugdev "
                           "group, then replug)");
    case kUsbErrorBusy:
      return core::IoError(detail +
                           " (the HID interface is claimed by another program: another "
                           "hwr-robot or the ZED SDK?)");
    case kUsbErrorNoDevice:
    case kUsbErrorPipe:
    case kUsbErrorIo:
    case kUsbErrorTimeout:  // only a control transfer gets here: the MCU stopped answering
      // The handle is dead or the endpoint stalled: release it; start() again reopens and
      // re-enables the stream.
      if (!lost_) {
        ++counters_.disconnects;
        lost_ = true;
      }
      stop();
      return core::Unavailable(detail + " (unplugged or stalled: reconnect)");
    case kUsbErrorOverflow:  // the device sent more than the transfer's buffer: nothing to reopen
      return core::CorruptData(detail + " (a report longer than " + std::to_string(kReportBytes) +
                               " bytes: not the ZED sensor MCU's report format?)");
    default:
      return core::IoError(detail);
  }
}

core::Status ZedHidStream::send_feature(const uint8_t (&report)[2], const char* what) {
  // SET_REPORT(Feature, report id) on the interface; the data stage starts with the report id
  // (hidapi's hid_send_feature_report, as zed-open-capture sends these reports).
  const uint16_t value = static_cast<uint16_t>((kHidReportTypeFeature << 8) | report[0]);
  const int r = ops_.control_out(kHidRequestTypeClassInterfaceOut, kHidSetReport, value,
                                 static_cast<uint16_t>(config_.interface_number), report,
                                 static_cast<uint16_t>(sizeof report), config_.control_timeout_ms);
  if (r < 0) return fail(r, what);
  if (r != static_cast<int>(sizeof report)) {
    return fail(kUsbErrorIo, what);  // a short control write: the device did not take the report
  }
  return core::Status::Ok();
}

core::Status ZedHidStream::start(int64_t now_ns) {
  stop();
  int r = ops_.open(config_.vendor, config_.product);
  if (r < 0) {
    ops_.close();
    return fail(r, "open");
  }
  open_ = true;
  r = ops_.claim_interface(config_.interface_number);
  if (r < 0) {
    core::Status st = fail(r, "claim interface");
    stop();
    return st;
  }
  if (core::Status st = send_feature(kStreamEnable, "enable the sensor stream {0x32, 0x01}"); !st.ok()) {
    stop();
    return st;
  }
  next_keep_alive_ns_ = now_ns + config_.keep_alive_period_ns;
  if (lost_) ++counters_.reconnects;
  lost_ = false;
  return core::Status::Ok();
}

core::Status ZedHidStream::keep_alive(int64_t now_ns) {
  if (!open_) return core::Unavailable(name_ + ": not started (start() first)");
  if (now_ns < next_keep_alive_ns_) return core::Status::Ok();
  HWR_RETURN_IF_ERROR(send_feature(kKeepAlive, "keep-alive {0x21, 0xF2}"));
  ++counters_.keep_alives;
  // From now, not from the missed due time: a stalled loop sends one report, not a burst.
  next_keep_alive_ns_ = now_ns + config_.keep_alive_period_ns;
  return core::Status::Ok();
}

core::Expected<size_t> ZedHidStream::read_report(uint8_t* buf64, int timeout_ms) {
  if (!open_) return core::Unavailable(name_ + ": not started (start() first)");
  // libusb reads a timeout of 0 as "wait forever": poll with the shortest finite wait instead.
  const int r = ops_.interrupt_in(buf64, static_cast<int>(kReportBytes),
                                  static_cast<unsigned>(timeout_ms < 1 ? 1 : timeout_ms));
  // INTERRUPTED: the synchronous wait was cut short by a signal; like a timeout, try again.
  if (r == kUsbErrorTimeout || r == kUsbErrorInterrupted || r == 0) {
    ++counters_.timeouts;
    return size_t{0};
  }
  if (r < 0) return fail(r, "read input report");
  ++counters_.reports;
  return static_cast<size_t>(r);
}

}  // namespace hwr::hal::hw
