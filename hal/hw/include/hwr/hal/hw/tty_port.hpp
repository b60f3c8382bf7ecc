#pragma once
// A serial device (USB serial adapter, CDC-ACM, UART) opened raw, 8N1, no flow control, at a fixed
// baud rate: the A9 IMU at 921600, the u-blox at its UART rate (a CDC-ACM port ignores the rate).
// Reads poll() with a timeout and never block longer. Errors name the device and say what to do:
// absent (plugged in? udev name?), permission (dialout group), gone (unplugged: reopen() later).

#include <memory>
#include <string>

#include "hwr/hal/hw/byte_stream.hpp"

namespace hwr::hal::hw {

class TtyPort final : public ByteStream {
 public:
  // Opens and configures path at baud (one of 9600, 19200, 38400, 57600, 115200, 230400, 460800,
  // 921600).
  static core::Expected<std::unique_ptr<TtyPort>> open(const std::string& path, int baud);
  ~TtyPort() override;
  TtyPort(const TtyPort&) = delete;
  TtyPort& operator=(const TtyPort&) = delete;

  core::Expected<size_t> read_some(uint8_t* buf, size_t cap, int timeout_ms) override;
  core::Status write_all(const uint8_t* bytes, size_t n) override;
  core::Status reopen() override;
  const std::string& name() const override { return path_; }
  int fd() const { return fd_; }

 private:
  TtyPort(std::string path, int baud) : path_(std::move(path)), baud_(baud) {}
  core::Status open_and_configure();
  void close_fd();

  std::string path_;
  int baud_;
  int fd_ = -1;
};

}  // namespace hwr::hal::hw
