#pragma once
// The Handsfree A9 IMU as a live stream: bytes from its serial port → A9Parser → hal::ImuSample on
// the host's CLOCK_MONOTONIC (the A9's own µs stamps, unwrapped and placed by ReceiptClockMap, so
// sample spacing keeps the device's precision) → the pipeline's IMU ring. The reader is the ring's
// only producer. A port that goes away (unplugged) is reopened with ReconnectBackoff; the parser and
// the clock map restart with it.
// step() does one read; run it in a loop on the reader's own thread (SensorThread), never in the
// scheduler's loop.

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>

#include "hwr/core/spsc_ring.hpp"
#include "hwr/core/status.hpp"
#include "hwr/hal/hw/a9_protocol.hpp"
#include "hwr/hal/hw/byte_stream.hpp"
#include "hwr/hal/hw/receipt_clock_map.hpp"
#include "hwr/hal/hw/reconnect_backoff.hpp"
#include "hwr/hal/imu_sample.hpp"

namespace hwr::hal::hw {

struct A9ReaderCounters {
  uint64_t samples = 0;      // IMU samples pushed
  uint64_t attitude = 0;     // attitude frames seen (the A9's own estimate; not used)
  uint64_t disconnects = 0;  // the port went away
  uint64_t reconnects = 0;   // ... and came back
  uint64_t crc_errors = 0;   // from the parser (over reconnects too)
  uint64_t bytes_discarded = 0;
};

class A9Reader {
 public:
  // imu_out: the ring this reader fills (one producer). Owns the port.
  A9Reader(std::unique_ptr<ByteStream> port, core::SpscRing<ImuSample>* imu_out);

  // One read of up to read_timeout_ms, then every completed frame is pushed. now_ns: the host's
  // CLOCK_MONOTONIC when called (the receipt time of what the read returns). An error Status only
  // for what a reconnect cannot fix; unplugging is counted and retried.
  core::Status step(int64_t now_ns, int read_timeout_ms = 20);

  A9ReaderCounters counters() const;
  bool connected() const { return connected_.load(std::memory_order_relaxed); }
  const std::string& device() const { return port_->name(); }

 private:
  std::unique_ptr<ByteStream> port_;
  core::SpscRing<ImuSample>* imu_out_;
  A9Parser parser_;
  A9TimestampUnwrapper unwrap_;
  ReceiptClockMap clock_;
  ReconnectBackoff backoff_;
  std::atomic<bool> connected_{true};
  std::array<uint8_t, 1024> buf_{};
  // Written by the reader thread, read by counters() from any thread.
  std::atomic<uint64_t> samples_{0}, attitude_{0}, disconnects_{0}, reconnects_{0};
  std::atomic<uint64_t> crc_errors_{0}, bytes_discarded_{0};
};

}  // namespace hwr::hal::hw
