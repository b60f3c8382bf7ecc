#include "hwr/hal/hw/ubx_protocol.hpp"

#include <cassert>
#include <cstring>
#include <string>

namespace hwr::hal::hw {
namespace {

uint16_t read_u16_le(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }

uint32_t read_u32_le(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}

int32_t read_i32_le(const uint8_t* p) { return static_cast<int32_t>(read_u32_le(p)); }

bool is_hex_digit(uint8_t c) {
  return (c >= '0' && c <= '9') || (c >= 'A' && c <= 'F') || (c >= 'a' && c <= 'f');
}

uint8_t hex_value(uint8_t c) {
  if (c >= '0' && c <= '9') return static_cast<uint8_t>(c - '0');
  if (c >= 'A' && c <= 'F') return static_cast<uint8_t>(c - 'A' + 10);
  return static_cast<uint8_t>(c - 'a' + 10);
}

}  // namespace

UbxChecksum ubx_fletcher(const uint8_t* data, size_t size) {
  UbxChecksum ck;
  for (size_t i = 0; i < size; ++i) {
    ck.ck_a = static_cast<uint8_t>(ck.ck_a + data[i]);
    ck.ck_b = static_cast<uint8_t>(ck.ck_b + ck.ck_a);
  }
  return ck;
}

std::vector<uint8_t> make_ubx_frame(uint8_t cls, uint8_t id, const uint8_t* payload, size_t n) {
  assert(n <= 0xFFFF && "UBX length is a u16");
  assert((payload != nullptr || n == 0) && "payload bytes missing");
  std::vector<uint8_t> frame;
  frame.reserve(n + kUbxOverhead);
  frame.push_back(kUbxSync0);
  frame.push_back(kUbxSync1);
  frame.push_back(cls);
  frame.push_back(id);
  frame.push_back(static_cast<uint8_t>(n & 0xFFu));
  frame.push_back(static_cast<uint8_t>((n >> 8) & 0xFFu));
  if (n > 0) frame.insert(frame.end(), payload, payload + n);
  const UbxChecksum ck = ubx_fletcher(frame.data() + 2, frame.size() - 2);
  frame.push_back(ck.ck_a);
  frame.push_back(ck.ck_b);
  return frame;
}

std::vector<uint8_t> make_cfg_rate(uint16_t meas_ms) {
  // UBX-CFG-RATE payload: measRate u16 ms, navRate u16 (cycles per solution), timeRef u16 (1 = GPS).
  const uint8_t payload[6] = {
      static_cast<uint8_t>(meas_ms & 0xFFu), static_cast<uint8_t>(meas_ms >> 8), 1, 0, 1, 0};
  return make_ubx_frame(kUbxClassCfg, kUbxIdCfgRate, payload, sizeof payload);
}

std::vector<uint8_t> make_cfg_msg(uint8_t cls, uint8_t id, uint8_t rate) {
  // UBX-CFG-MSG, 3-byte form: msgClass, msgID, rate on the port this arrives on.
  const uint8_t payload[3] = {cls, id, rate};
  return make_ubx_frame(kUbxClassCfg, kUbxIdCfgMsg, payload, sizeof payload);
}

core::Expected<UbxAck> decode_ubx_ack(uint8_t cls, uint8_t id, const uint8_t* payload, size_t n) {
  if (cls != kUbxClassAck || (id != kUbxIdAckAck && id != kUbxIdAckNak)) {
    return core::InvalidArgument("UBX " + std::to_string(cls) + "/" + std::to_string(id) +
                                 " is not ACK-ACK (05 01) or ACK-NAK (05 00)");
  }
  if (n != 2 || payload == nullptr) {
    return core::CorruptData("UBX ACK payload must be 2 bytes (class, id of the acked message), got " +
                             std::to_string(n));
  }
  UbxAck ack;
  ack.acknowledged = id == kUbxIdAckAck;
  ack.acked_cls = payload[0];
  ack.acked_id = payload[1];
  return ack;
}

core::Expected<NavPvt> decode_nav_pvt(const uint8_t* payload, size_t n) {
  if (n != kNavPvtPayloadSize || payload == nullptr) {
    return core::CorruptData("NAV-PVT payload must be 92 bytes, got " + std::to_string(n));
  }
  const uint8_t* p = payload;
  NavPvt v;
  v.itow_ms = read_u32_le(p + 0);
  v.year = read_u16_le(p + 4);
  v.month = p[6];
  v.day = p[7];
  v.hour = p[8];
  v.minute = p[9];
  v.second = p[10];
  v.valid_flags = p[11];
  v.valid_date = (p[11] & 0x01u) != 0;
  v.valid_time = (p[11] & 0x02u) != 0;
  v.fully_resolved = (p[11] & 0x04u) != 0;
  v.fix_type = p[20];
  v.flags = p[21];
  v.gnss_fix_ok = (p[21] & 0x01u) != 0;
  v.num_sv = p[23];
  const int32_t lon_e7 = read_i32_le(p + 24);
  const int32_t lat_e7 = read_i32_le(p + 28);
  v.lon_deg = lon_e7 * 1e-7;
  v.lat_deg = lat_e7 * 1e-7;
  v.height_ellipsoid_m = read_i32_le(p + 32) * 1e-3;
  v.height_msl_m = read_i32_le(p + 36) * 1e-3;
  v.h_acc_m = read_u32_le(p + 40) * 1e-3;
  v.v_acc_m = read_u32_le(p + 44) * 1e-3;
  v.vel_north_mps = read_i32_le(p + 48) * 1e-3;
  v.vel_east_mps = read_i32_le(p + 52) * 1e-3;
  v.vel_down_mps = read_i32_le(p + 56) * 1e-3;
  v.ground_speed_mps = read_i32_le(p + 60) * 1e-3;
  v.heading_motion_deg = read_i32_le(p + 64) * 1e-5;
  v.pdop = read_u16_le(p + 76) * 0.01;
  // Integer comparisons: exact, no rounding at the ±90°/±180° borders.
  if (lat_e7 < -900000000 || lat_e7 > 900000000 || lon_e7 < -1800000000 || lon_e7 > 1800000000) {
    return core::OutOfRange("NAV-PVT lat/lon out of range: lat " + std::to_string(v.lat_deg) + " deg, lon " +
                            std::to_string(v.lon_deg) + " deg (corrupt payload?)");
  }
  if (v.fix_type > 5) {
    return core::OutOfRange("NAV-PVT fixType " + std::to_string(v.fix_type) +
                            " is not 0..5 (corrupt payload?)");
  }
  return v;
}

hal::GnssFix to_gnss_fix(const NavPvt& pvt, int64_t t_ns) {
  hal::GnssFix fix;
  fix.t_ns = t_ns;
  if (pvt.gnss_fix_ok) {
    switch (pvt.fix_type) {
      case 2:
        fix.fix_type = 2;
        break;
      case 3:
      case 4:
        fix.fix_type = 3;
        break;
      default:
        fix.fix_type = 0;
        break;  // 0 none, 1 dead reckoning only, 5 time only
    }
  }
  fix.num_sv = pvt.num_sv;
  fix.lat_deg = pvt.lat_deg;
  fix.lon_deg = pvt.lon_deg;
  fix.height_m = pvt.height_ellipsoid_m;
  fix.h_acc_m = pvt.h_acc_m;
  fix.v_acc_m = pvt.v_acc_m;
  return fix;
}

GnssStreamParser::GnssStreamParser(GnssStreamLimits limits) : limits_(limits) {
  if (limits_.max_nmea_chars < 8) limits_.max_nmea_chars = 8;  // "$" + "*hh" + CR LF and a little
  if (limits_.max_ubx_payload > 0xFFFF) limits_.max_ubx_payload = 0xFFFF;
  const size_t max_ubx = limits_.max_ubx_payload + kUbxOverhead;
  max_message_ = max_ubx > limits_.max_nmea_chars ? max_ubx : limits_.max_nmea_chars;
  // One longest message plus room for a typical read, so push() seldom goes round twice.
  buf_.resize(max_message_ + 512);
}

size_t GnssStreamParser::append(const uint8_t* bytes, size_t n) {
  if (head_ > 0) {
    // After extract() returned false fewer than max_message_ bytes remain, so there is room.
    const size_t kept = tail_ - head_;
    std::memmove(buf_.data(), buf_.data() + head_, kept);
    head_ = 0;
    tail_ = kept;
  }
  const size_t room = buf_.size() - tail_;
  const size_t used = n < room ? n : room;
  std::memcpy(buf_.data() + tail_, bytes, used);
  tail_ += used;
  counters_.bytes_received += used;
  return used;
}

void GnssStreamParser::discard(size_t n) {
  head_ += n;
  counters_.bytes_discarded += n;
}

void GnssStreamParser::accept(size_t n) {
  head_ += n;
  counters_.bytes_accepted += n;
}

void GnssStreamParser::reset() {
  counters_.bytes_discarded += tail_ - head_;
  head_ = tail_ = 0;
}

GnssStreamParser::Step GnssStreamParser::try_ubx(GnssMessage* out) {
  const uint8_t* p = buf_.data() + head_;
  const size_t avail = tail_ - head_;
  if (avail < 2) return Step::kNeedMore;
  if (p[1] != kUbxSync1) {
    discard(1);  // a lone B5 in text or noise
    return Step::kDiscarded;
  }
  if (avail < 6) return Step::kNeedMore;
  const size_t len = read_u16_le(p + 4);
  if (len > limits_.max_ubx_payload) {
    ++counters_.ubx_oversize;
    discard(1);
    return Step::kDiscarded;
  }
  const size_t frame_size = len + kUbxOverhead;
  if (avail < frame_size) return Step::kNeedMore;
  const UbxChecksum ck = ubx_fletcher(p + 2, len + 4);
  if (ck.ck_a != p[6 + len] || ck.ck_b != p[7 + len]) {
    ++counters_.ubx_checksum_errors;
    discard(1);  // a valid frame or sentence may start inside this candidate
    return Step::kDiscarded;
  }
  out->kind = GnssMessage::Kind::kUbx;
  out->ubx.cls = p[2];
  out->ubx.id = p[3];
  out->ubx.payload = p + 6;
  out->ubx.payload_size = len;
  out->nmea = {};
  ++counters_.ubx_frames;
  accept(frame_size);
  return Step::kEmit;
}

GnssStreamParser::Step GnssStreamParser::try_nmea(GnssMessage* out) {
  const uint8_t* p = buf_.data() + head_;
  const size_t avail = tail_ - head_;
  const size_t max = limits_.max_nmea_chars;
  size_t text_end = 0;  // index of the CR (or LF) that ends the text
  size_t line_end = 0;  // index of the LF
  size_t i = 1;
  for (; i < avail && i < max; ++i) {
    const uint8_t c = p[i];
    if (c == '\n') {
      text_end = line_end = i;
      break;
    }
    if (c == '\r') {
      if (i + 1 >= max) break;  // the LF would not fit: too long
      if (i + 1 == avail) return Step::kNeedMore;
      if (p[i + 1] != '\n') {
        ++counters_.nmea_malformed;
        discard(1);
        return Step::kDiscarded;
      }
      text_end = i;
      line_end = i + 1;
      break;
    }
    // NMEA 0183 text is printable ASCII; '$' starts a new sentence (this one broke off), and a
    // binary byte means a UBX frame interrupted it.
    if (c < 0x20 || c > 0x7E || c == '$') {
      ++counters_.nmea_malformed;
      discard(1);
      return Step::kDiscarded;
    }
  }
  if (line_end == 0) {
    if (i < max && i == avail) return Step::kNeedMore;
    ++counters_.nmea_malformed;  // no line end within max_nmea_chars
    discard(1);
    return Step::kDiscarded;
  }
  // "$<body>*hh": the checksum is the XOR of the body (between '$' and '*').
  if (text_end < 4 || p[text_end - 3] != '*' || !is_hex_digit(p[text_end - 2]) ||
      !is_hex_digit(p[text_end - 1])) {
    ++counters_.nmea_malformed;
    discard(1);
    return Step::kDiscarded;
  }
  uint8_t x = 0;
  for (size_t k = 1; k < text_end - 3; ++k) {
    if (p[k] == '*') {  // '*' is reserved for the checksum delimiter
      ++counters_.nmea_malformed;
      discard(1);
      return Step::kDiscarded;
    }
    x = static_cast<uint8_t>(x ^ p[k]);
  }
  const uint8_t sent = static_cast<uint8_t>((hex_value(p[text_end - 2]) << 4) | hex_value(p[text_end - 1]));
  if (x != sent) {
    ++counters_.nmea_checksum_errors;
    discard(1);
    return Step::kDiscarded;
  }
  out->kind = GnssMessage::Kind::kNmea;
  out->ubx = {};
  out->nmea = std::string_view(reinterpret_cast<const char*>(p), text_end);
  ++counters_.nmea_sentences;
  accept(line_end + 1);
  return Step::kEmit;
}

bool GnssStreamParser::extract(GnssMessage* out) {
  while (head_ < tail_) {
    const uint8_t first = buf_[head_];
    Step step;
    if (first == kUbxSync0) {
      step = try_ubx(out);
    } else if (first == '$') {
      step = try_nmea(out);
    } else {
      // Noise (or the tail of something that failed): skip to the next possible start.
      size_t k = head_ + 1;
      while (k < tail_ && buf_[k] != kUbxSync0 && buf_[k] != '$') ++k;
      discard(k - head_);
      continue;
    }
    if (step == Step::kEmit) return true;
    if (step == Step::kNeedMore) return false;
  }
  head_ = tail_ = 0;
  return false;
}

}  // namespace hwr::hal::hw
