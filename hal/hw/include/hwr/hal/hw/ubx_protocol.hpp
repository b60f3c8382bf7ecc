#pragma once
// u-blox M8T: UBX binary framing, the config frames the driver sends, ACK/NAK and NAV-PVT decoding,
// and GnssStreamParser, which splits the receiver's one byte stream of interleaved UBX frames and
// NMEA sentences (hardware.md "u-blox M8T"):
//
//   B5 62 | class | id | u16 LE length | payload | CK_A CK_B
//
// CK_A/CK_B: 8-bit Fletcher over class … end of payload.

#include <cstddef>
#include <cstdint>
#include <string_view>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/hal/gnss_fix.hpp"

namespace hwr::hal::hw {

inline constexpr uint8_t kUbxSync0 = 0xB5;
inline constexpr uint8_t kUbxSync1 = 0x62;
inline constexpr size_t kUbxOverhead = 8;  // sync 2 + class 1 + id 1 + length 2 + checksum 2

inline constexpr uint8_t kUbxClassNav = 0x01;
inline constexpr uint8_t kUbxClassAck = 0x05;
inline constexpr uint8_t kUbxClassCfg = 0x06;
inline constexpr uint8_t kUbxIdNavPvt = 0x07;
inline constexpr uint8_t kUbxIdAckNak = 0x00;
inline constexpr uint8_t kUbxIdAckAck = 0x01;
inline constexpr uint8_t kUbxIdCfgMsg = 0x01;
inline constexpr uint8_t kUbxIdCfgRate = 0x08;
inline constexpr size_t kNavPvtPayloadSize = 92;

struct UbxChecksum {
  uint8_t ck_a = 0;
  uint8_t ck_b = 0;
};

// 8-bit Fletcher (RFC 1145) as UBX uses it: for each byte, ck_a += byte; ck_b += ck_a (mod 256).
// Pass the bytes from class to the end of the payload.
UbxChecksum ubx_fletcher(const uint8_t* data, size_t size);

// A whole frame, sync to checksum. Config time only (allocates). payload may be null when n == 0;
// n must fit the u16 length field (asserted).
std::vector<uint8_t> make_ubx_frame(uint8_t cls, uint8_t id, const uint8_t* payload, size_t n);

// CFG-RATE (06 08): measurement period meas_ms, one navigation solution per measurement
// (navRate 1), aligned to GPS time (timeRef 1). make_cfg_rate(100) is hardware.md's 10 Hz frame
// B5 62 06 08 06 00 64 00 01 00 01 00 7A 12.
std::vector<uint8_t> make_cfg_rate(uint16_t meas_ms);

// CFG-MSG (06 01), short form: message cls/id on the current port every `rate` solutions (0 off).
// make_cfg_msg(0x01, 0x07, 1) is hardware.md's B5 62 06 01 03 00 01 07 01 13 51.
std::vector<uint8_t> make_cfg_msg(uint8_t cls, uint8_t id, uint8_t rate);

// One received UBX frame; payload points into the parser's buffer (valid during the sink call).
struct UbxFrameView {
  uint8_t cls = 0;
  uint8_t id = 0;
  const uint8_t* payload = nullptr;
  size_t payload_size = 0;
};

// ACK-ACK (05 01) or ACK-NAK (05 00); the payload names the configuration message it answers.
struct UbxAck {
  bool acknowledged = false;  // true for ACK-ACK, false for ACK-NAK (the receiver refused it)
  uint8_t acked_cls = 0;
  uint8_t acked_id = 0;
};

// Error when cls/id is not 05 01 / 05 00 (kInvalidArgument) or the payload is not 2 bytes
// (kCorruptData).
core::Expected<UbxAck> decode_ubx_ack(uint8_t cls, uint8_t id, const uint8_t* payload, size_t n);

// NAV-PVT (01 07), the fields hardware.md documents, in SI units / degrees. Offsets are bytes
// into the 92-byte payload.
struct NavPvt {
  uint32_t itow_ms = 0;  // @0 GPS time of week of the navigation epoch
  uint16_t year = 0;     // @4..10 UTC date and time (meaningful when valid_date / valid_time)
  uint8_t month = 0;
  uint8_t day = 0;
  uint8_t hour = 0;
  uint8_t minute = 0;
  uint8_t second = 0;
  uint8_t valid_flags = 0;        // @11 raw; bits per the u-blox M8 protocol description:
  bool valid_date = false;        //   bit0 validDate
  bool valid_time = false;        //   bit1 validTime
  bool fully_resolved = false;    //   bit2 fullyResolved (no seconds ambiguity)
  uint8_t fix_type = 0;           // @20 0 none, 1 dead reckoning only, 2 2D, 3 3D, 4 GNSS+DR, 5 time only
  uint8_t flags = 0;              // @21 raw
  bool gnss_fix_ok = false;       //   bit0 gnssFixOK: the fix is within the configured DOP/accuracy masks
  uint8_t num_sv = 0;             // @23 satellites used in the solution
  double lon_deg = 0;             // @24 i32, 1e-7 deg
  double lat_deg = 0;             // @28 i32, 1e-7 deg
  double height_ellipsoid_m = 0;  // @32 i32 mm, above the WGS-84 ellipsoid
  double height_msl_m = 0;        // @36 i32 mm, above mean sea level
  double h_acc_m = 0;             // @40 u32 mm, horizontal accuracy estimate
  double v_acc_m = 0;             // @44 u32 mm, vertical accuracy estimate
  double vel_north_mps = 0;       // @48 i32 mm/s
  double vel_east_mps = 0;        // @52 i32 mm/s
  double vel_down_mps = 0;        // @56 i32 mm/s
  double ground_speed_mps = 0;    // @60 i32 mm/s, 2D
  double heading_motion_deg = 0;  // @64 i32, 1e-5 deg
  double pdop = 0;                // @76 u16, 0.01
};

// Error (kCorruptData) unless n == 92, and (kOutOfRange) when lat/lon are outside ±90°/±180° or
// fixType > 5: values no receiver sends.
core::Expected<NavPvt> decode_nav_pvt(const uint8_t* payload, size_t n);

// hal::GnssFix from NAV-PVT. fix_type: 0 when gnssFixOK is clear; else NAV-PVT 2 → 2, 3 and 4
// (GNSS + dead reckoning: still a 3D GNSS position) → 3, and 1 (dead reckoning only) / 5 (time
// only: the M8T's timing mode, no position solved) → 0. height_m is the ellipsoidal height.
hal::GnssFix to_gnss_fix(const NavPvt& pvt, int64_t t_ns);

// Sizes of GnssStreamParser's buffer (fixed at construction). The constructor raises
// max_nmea_chars below 8 to 8 and caps max_ubx_payload at 65535 (the u16 length field).
struct GnssStreamLimits {
  // Longest UBX payload accepted; a length field above it is taken as a lie (discard + resync).
  // 1024 covers NAV-PVT (92), NAV-SAT with 60 SVs (728) and ACKs; raise it for RXM-RAWX with more
  // than 31 measurements (16 + 32·n bytes).
  size_t max_ubx_payload = 1024;
  // Longest NMEA sentence, '$' through the line feed. NMEA 0183 allows 82; u-blox can exceed it
  // with high-precision or proprietary (PUBX) sentences, hence the margin.
  size_t max_nmea_chars = 128;
};

// What the stream parser saw. bytes_received == bytes_accepted + bytes_discarded + bytes_buffered().
struct GnssStreamCounters {
  uint64_t bytes_received = 0;
  uint64_t bytes_accepted = 0;  // in emitted UBX frames and NMEA sentences (with their CR LF)
  uint64_t bytes_discarded = 0;
  uint64_t ubx_frames = 0;
  uint64_t nmea_sentences = 0;
  uint64_t ubx_checksum_errors = 0;
  uint64_t ubx_oversize = 0;          // length field > max_ubx_payload
  uint64_t nmea_checksum_errors = 0;  // well-formed "…*hh" whose hh does not match
  uint64_t nmea_malformed = 0;        // no "*hh" before the line end, a non-printable byte, or too long
};

// One item of the stream: a UBX frame or an NMEA sentence. Views into the parser's buffer, valid
// during the sink call only.
struct GnssMessage {
  enum class Kind { kUbx, kNmea };
  Kind kind = Kind::kUbx;
  UbxFrameView ubx;       // kUbx: checksum verified
  std::string_view nmea;  // kNmea: '$' through the two checksum digits (no CR LF); checksum verified
};

// Splits the M8T's byte stream. Frames and sentences are emitted only after their checksum
// verifies; after any failure (bad checksum, a length above the limit, a sentence that breaks off)
// the first byte of the failed candidate is dropped and the search restarts at the byte after it,
// over the bytes already buffered, so nothing valid inside the failed candidate is lost. A UBX
// length that lies upwards holds later messages back until that many bytes arrived (at most
// max_ubx_payload + 8), then they are found again. Allocates only in the constructor.
class GnssStreamParser {
 public:
  explicit GnssStreamParser(GnssStreamLimits limits = {});

  // Feeds n bytes (any split) and calls sink(const GnssMessage&) for each complete message.
  template <class Sink>
  void push(const uint8_t* bytes, size_t n, Sink&& sink) {
    GnssMessage message;
    while (n > 0) {
      const size_t used = append(bytes, n);
      bytes += used;
      n -= used;
      while (extract(&message)) sink(static_cast<const GnssMessage&>(message));
    }
  }

  const GnssStreamCounters& counters() const { return counters_; }
  const GnssStreamLimits& limits() const { return limits_; }
  size_t bytes_buffered() const { return tail_ - head_; }
  void reset();

 private:
  enum class Step { kEmit, kNeedMore, kDiscarded };
  size_t append(const uint8_t* bytes, size_t n);
  bool extract(GnssMessage* out);
  Step try_ubx(GnssMessage* out);
  Step try_nmea(GnssMessage* out);
  void discard(size_t n);
  void accept(size_t n);

  GnssStreamLimits limits_;
  size_t max_message_ = 0;    // longest candidate: max(UBX frame, NMEA sentence)
  std::vector<uint8_t> buf_;  // sized once in the constructor
  size_t head_ = 0;
  size_t tail_ = 0;
  GnssStreamCounters counters_;
};

}  // namespace hwr::hal::hw
