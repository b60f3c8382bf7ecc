#pragma once
// What the serial sensor readers (A9 IMU, u-blox GNSS) read from: a byte stream that can be read
// with a timeout, written (configuration frames) and reopened after the device went away.
// SerialPort is the real one (termios); tests use in-memory streams and pseudo-terminals.

#include <cstddef>
#include <cstdint>
#include <string>

#include "hwr/core/status.hpp"

namespace hwr::hal::hw {

class ByteStream {
 public:
  virtual ~ByteStream() = default;
  // Up to cap bytes; 0 when nothing arrived within timeout_ms. Unavailable when the device is gone
  // (unplugged: reopen later), another error when it cannot be used at all.
  virtual core::Expected<size_t> read_some(uint8_t* buf, size_t cap, int timeout_ms) = 0;
  virtual core::Status write_all(const uint8_t* bytes, size_t n) = 0;
  // Closes and opens the device again (same path and settings).
  virtual core::Status reopen() = 0;
  // For messages: the device path, e.g. "/dev/hwr-a9".
  virtual const std::string& name() const = 0;
};

}  // namespace hwr::hal::hw
