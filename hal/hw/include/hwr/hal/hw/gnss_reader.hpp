#pragma once
// The u-blox M8T as a live stream: bytes from its port → GnssStreamParser → NAV-PVT (or, when the
// receiver sends no NAV-PVT, NMEA GGA: the fallback) → hal::GnssFix → the pipeline's GNSS ring (this
// reader is its only producer). At start and after every reconnect it configures the receiver:
// CFG-RATE (measurement period) and CFG-MSG (NAV-PVT on the current port, once per solution), each
// resent until ACK-ACK or until max_config_tries; an ACK-NAK is an error that says which message the
// receiver refused. Fixes are stamped with the host's CLOCK_MONOTONIC at receipt: the solution's
// latency (tens of ms) is far below what a GNSS position prior needs.

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "hwr/core/spsc_ring.hpp"
#include "hwr/core/status.hpp"
#include "hwr/hal/gnss_fix.hpp"
#include "hwr/hal/hw/byte_stream.hpp"
#include "hwr/hal/hw/reconnect_backoff.hpp"
#include "hwr/hal/hw/ubx_protocol.hpp"

namespace hwr::hal::hw {

struct GnssReaderOptions {
  double rate_hz = 10;    // CFG-RATE
  bool configure = true;  // send CFG-RATE / CFG-MSG and wait for their ACKs
  int64_t ack_timeout_ns = 1'000'000'000;
  int max_config_tries = 3;  // per message
  // GGA is used only when no NAV-PVT arrived for this long (a receiver left in NMEA-only mode).
  int64_t nav_pvt_silence_ns = 2'000'000'000;
};

enum class GnssConfigState { kIdle, kWaitRateAck, kWaitMsgAck, kDone, kFailed };

struct GnssReaderCounters {
  uint64_t fixes = 0;  // pushed (NAV-PVT and GGA)
  uint64_t fixes_from_gga = 0;
  uint64_t nav_pvt = 0;
  uint64_t gga = 0;
  uint64_t acks = 0, naks = 0, config_timeouts = 0;
  uint64_t decode_errors = 0;  // a checksum-valid NAV-PVT or GGA whose fields were impossible
  uint64_t disconnects = 0, reconnects = 0;
  uint64_t ubx_checksum_errors = 0, nmea_checksum_errors = 0, bytes_discarded = 0;
};

class GnssReader {
 public:
  GnssReader(std::unique_ptr<ByteStream> port, core::SpscRing<GnssFix>* gnss_out,
             GnssReaderOptions options = {});

  // One read (up to read_timeout_ms) and what it completes; now_ns = host CLOCK_MONOTONIC. Returns
  // an error once when the receiver refused its configuration (NAK) or never acknowledged it (the
  // reader then goes on with what the receiver sends); unplugging is counted and retried.
  core::Status step(int64_t now_ns, int read_timeout_ms = 20);

  GnssReaderCounters counters() const;
  GnssConfigState config_state() const { return config_state_.load(std::memory_order_relaxed); }
  bool connected() const { return connected_.load(std::memory_order_relaxed); }
  const std::string& device() const { return port_->name(); }

 private:
  core::Status send_config(int64_t now_ns);
  core::Status on_ack(const UbxAck& ack, int64_t now_ns);
  void on_message(const GnssMessage& m, int64_t now_ns, core::Status* error);

  std::unique_ptr<ByteStream> port_;
  core::SpscRing<GnssFix>* gnss_out_;
  GnssReaderOptions options_;
  GnssStreamParser parser_;
  ReconnectBackoff backoff_;
  std::atomic<bool> connected_{true};
  std::atomic<GnssConfigState> config_state_{GnssConfigState::kIdle};
  int config_tries_ = 0;
  int64_t config_sent_ns_ = 0;
  int64_t last_nav_pvt_ns_ = INT64_MIN / 2;
  std::array<uint8_t, 1024> buf_{};
  std::atomic<uint64_t> fixes_{0}, fixes_from_gga_{0}, nav_pvt_{0}, gga_{0}, acks_{0}, naks_{0};
  std::atomic<uint64_t> config_timeouts_{0}, decode_errors_{0}, disconnects_{0}, reconnects_{0};
  std::atomic<uint64_t> ubx_checksum_errors_{0}, nmea_checksum_errors_{0}, bytes_discarded_{0};
};

}  // namespace hwr::hal::hw
