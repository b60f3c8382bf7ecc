#include "hwr/hal/hw/gnss_reader.hpp"

#include <cmath>
#include <string_view>
#include <vector>

#include "hwr/core/log.hpp"
#include "hwr/hal/hw/nmea_gga.hpp"

namespace hwr::hal::hw {
namespace {

constexpr uint8_t kClsCfg = 0x06, kIdCfgRate = 0x08, kIdCfgMsg = 0x01;
constexpr uint8_t kClsNav = 0x01, kIdNavPvt = 0x07;
constexpr uint8_t kClsAck = 0x05;

bool is_unplug(const core::Status& st) {
  return st.code() == core::ErrorCode::kUnavailable || st.code() == core::ErrorCode::kIoError ||
         st.code() == core::ErrorCode::kNotFound;
}

// "$GNGGA,..." → true for any talker's GGA.
bool is_gga(std::string_view s) { return s.size() > 6 && s[0] == '$' && s.substr(3, 4) == "GGA,"; }

}  // namespace

GnssReader::GnssReader(std::unique_ptr<ByteStream> port, core::SpscRing<GnssFix>* gnss_out,
                       GnssReaderOptions options)
    : port_(std::move(port)), gnss_out_(gnss_out), options_(options) {
  if (!options_.configure) config_state_.store(GnssConfigState::kDone);
}

core::Status GnssReader::send_config(int64_t now_ns) {
  const GnssConfigState s = config_state_.load(std::memory_order_relaxed);
  std::vector<uint8_t> frame;  // config time only (start, reconnect, a retry)
  if (s == GnssConfigState::kWaitRateAck) {
    frame = make_cfg_rate(static_cast<uint16_t>(std::lround(1000.0 / options_.rate_hz)));
  } else if (s == GnssConfigState::kWaitMsgAck) {
    frame = make_cfg_msg(kClsNav, kIdNavPvt, 1);
  } else {
    return core::Status::Ok();
  }
  config_sent_ns_ = now_ns;
  ++config_tries_;
  return port_->write_all(frame.data(), frame.size());
}

core::Status GnssReader::on_ack(const UbxAck& ack, int64_t now_ns) {
  const GnssConfigState s = config_state_.load(std::memory_order_relaxed);
  const uint8_t want_id = s == GnssConfigState::kWaitRateAck ? kIdCfgRate : kIdCfgMsg;
  if ((s != GnssConfigState::kWaitRateAck && s != GnssConfigState::kWaitMsgAck) || ack.acked_cls != kClsCfg ||
      ack.acked_id != want_id) {
    return core::Status::Ok();  // an answer to something else (or late): not ours
  }
  if (!ack.acknowledged) {
    naks_.fetch_add(1, std::memory_order_relaxed);
    config_state_.store(GnssConfigState::kFailed, std::memory_order_relaxed);
    return core::Unavailable(
        port_->name() + ": the u-blox receiver refused " +
        (want_id == kIdCfgRate ? "CFG-RATE (rate_hz " + std::to_string(options_.rate_hz) + ")"
                               : std::string("CFG-MSG (NAV-PVT on)")) +
        " with ACK-NAK: check gnss.rate_hz, or set gnss.configure: false and configure it "
        "with u-center");
  }
  acks_.fetch_add(1, std::memory_order_relaxed);
  config_tries_ = 0;
  config_state_.store(
      s == GnssConfigState::kWaitRateAck ? GnssConfigState::kWaitMsgAck : GnssConfigState::kDone,
      std::memory_order_relaxed);
  return send_config(now_ns);
}

void GnssReader::on_message(const GnssMessage& m, int64_t now_ns, core::Status* error) {
  if (m.kind == GnssMessage::Kind::kUbx) {
    const UbxFrameView& f = m.ubx;
    if (f.cls == kClsAck) {
      auto ack = decode_ubx_ack(f.cls, f.id, f.payload, f.payload_size);
      if (!ack.ok()) {
        decode_errors_.fetch_add(1, std::memory_order_relaxed);
      } else if (core::Status st = on_ack(ack.value(), now_ns); !st.ok() && error->ok()) {
        *error = st;
      }
    } else if (f.cls == kClsNav && f.id == kIdNavPvt) {
      auto pvt = decode_nav_pvt(f.payload, f.payload_size);
      if (!pvt.ok()) {
        decode_errors_.fetch_add(1, std::memory_order_relaxed);
        return;
      }
      nav_pvt_.fetch_add(1, std::memory_order_relaxed);
      last_nav_pvt_ns_ = now_ns;
      gnss_out_->push_drop_oldest(to_gnss_fix(pvt.value(), now_ns));
      fixes_.fetch_add(1, std::memory_order_relaxed);
    }
    return;
  }
  if (!is_gga(m.nmea)) return;
  gga_.fetch_add(1, std::memory_order_relaxed);
  if (now_ns - last_nav_pvt_ns_ < options_.nav_pvt_silence_ns) return;  // NAV-PVT is flowing: it wins
  auto gga = parse_gga(m.nmea);
  if (!gga.ok()) {
    decode_errors_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  gnss_out_->push_drop_oldest(to_gnss_fix(gga.value(), now_ns));
  fixes_.fetch_add(1, std::memory_order_relaxed);
  fixes_from_gga_.fetch_add(1, std::memory_order_relaxed);
}

core::Status GnssReader::step(int64_t now_ns, int read_timeout_ms) {
  if (!connected_.load(std::memory_order_relaxed)) {
    if (!backoff_.due(now_ns)) {
      backoff_.wait_until_due(now_ns, read_timeout_ms);
      return core::Status::Ok();
    }
    if (core::Status st = port_->reopen(); !st.ok()) {
      backoff_.failed(now_ns);
      return is_unplug(st) ? core::Status::Ok() : st;
    }
    backoff_.succeeded();
    parser_.reset();
    connected_.store(true, std::memory_order_relaxed);
    reconnects_.fetch_add(1, std::memory_order_relaxed);
    // A replugged receiver may have lost a configuration that was not saved to its flash.
    if (options_.configure) config_state_.store(GnssConfigState::kIdle, std::memory_order_relaxed);
    HWR_LOG_INFO("gnss", "%s: reconnected", port_->name().c_str());
  }
  // A failed configuration is said once (the returned Status); the reader goes on with whatever the
  // receiver sends (NAV-PVT if it was already on, else GGA).
  const GnssConfigState s = config_state_.load(std::memory_order_relaxed);
  if (s == GnssConfigState::kIdle) {
    config_tries_ = 0;
    config_state_.store(GnssConfigState::kWaitRateAck, std::memory_order_relaxed);
    if (core::Status st = send_config(now_ns); !st.ok() && !is_unplug(st)) return st;
  } else if ((s == GnssConfigState::kWaitRateAck || s == GnssConfigState::kWaitMsgAck) &&
             now_ns - config_sent_ns_ > options_.ack_timeout_ns) {
    config_timeouts_.fetch_add(1, std::memory_order_relaxed);
    if (config_tries_ >= options_.max_config_tries) {
      config_state_.store(GnssConfigState::kFailed, std::memory_order_relaxed);
      return core::Status(
          core::ErrorCode::kTimeout,
          port_->name() + ": the u-blox receiver did not acknowledge " +
              (s == GnssConfigState::kWaitRateAck ? "CFG-RATE" : "CFG-MSG") + " after " +
              std::to_string(config_tries_) +
              " tries: is this a u-blox receiver, at gnss.baud on a UART? (gnss.configure: false "
              "skips configuration)");
    }
    if (core::Status st = send_config(now_ns); !st.ok() && !is_unplug(st)) return st;
  }

  auto n = port_->read_some(buf_.data(), buf_.size(), read_timeout_ms);
  if (!n.ok()) {
    if (!is_unplug(n.status())) return n.status();
    connected_.store(false, std::memory_order_relaxed);
    disconnects_.fetch_add(1, std::memory_order_relaxed);
    backoff_.failed(now_ns);
    HWR_LOG_WARN("gnss", "%s: %s; reconnecting", port_->name().c_str(), n.status().message().c_str());
    return core::Status::Ok();
  }
  core::Status error;
  parser_.push(buf_.data(), n.value(), [&](const GnssMessage& m) { on_message(m, now_ns, &error); });
  const GnssStreamCounters& pc = parser_.counters();
  ubx_checksum_errors_.store(pc.ubx_checksum_errors, std::memory_order_relaxed);
  nmea_checksum_errors_.store(pc.nmea_checksum_errors, std::memory_order_relaxed);
  bytes_discarded_.store(pc.bytes_discarded, std::memory_order_relaxed);
  return error;
}

GnssReaderCounters GnssReader::counters() const {
  GnssReaderCounters c;
  c.fixes = fixes_.load(std::memory_order_relaxed);
  c.fixes_from_gga = fixes_from_gga_.load(std::memory_order_relaxed);
  c.nav_pvt = nav_pvt_.load(std::memory_order_relaxed);
  c.gga = gga_.load(std::memory_order_relaxed);
  c.acks = acks_.load(std::memory_order_relaxed);
  c.naks = naks_.load(std::memory_order_relaxed);
  c.config_timeouts = config_timeouts_.load(std::memory_order_relaxed);
  c.decode_errors = decode_errors_.load(std::memory_order_relaxed);
  c.disconnects = disconnects_.load(std::memory_order_relaxed);
  c.reconnects = reconnects_.load(std::memory_order_relaxed);
  c.ubx_checksum_errors = ubx_checksum_errors_.load(std::memory_order_relaxed);
  c.nmea_checksum_errors = nmea_checksum_errors_.load(std::memory_order_relaxed);
  c.bytes_discarded = bytes_discarded_.load(std::memory_order_relaxed);
  return c;
}

}  // namespace hwr::hal::hw
