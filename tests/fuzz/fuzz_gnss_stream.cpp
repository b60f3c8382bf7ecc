// libFuzzer target: arbitrary bytes into hwr::hal::hw::GnssStreamParser (issue #8), the u-blox M8T's
// interleaved UBX/NMEA stream, pushed in chunks the first input byte picks, through two parsers (the
// default limits and small ones, so the oversize and too-long paths are reached). Everything a
// parser yields goes on to decode_nav_pvt / decode_ubx_ack / parse_gga, and parse_gga also gets the
// raw input as text. Findings: a yielded message that is not really at its stream position, a UBX
// checksum or NMEA checksum that does not verify when recomputed here, a view outside the limits,
// byte accounting that does not close, a rejection without a message, a decoded value outside its
// documented range, a crash or a sanitizer report.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string_view>

#include "hwr/hal/hw/nmea_gga.hpp"
#include "hwr/hal/hw/ubx_protocol.hpp"

namespace {

using hwr::hal::hw::GnssMessage;
using hwr::hal::hw::GnssStreamCounters;
using hwr::hal::hw::GnssStreamLimits;
using hwr::hal::hw::GnssStreamParser;

void check(bool ok) {
  if (!ok) std::abort();
}

void check_accounting(const GnssStreamParser& p) {
  const GnssStreamCounters& c = p.counters();
  check(c.bytes_received == c.bytes_accepted + c.bytes_discarded + p.bytes_buffered());
  check(p.bytes_buffered() <= p.limits().max_ubx_payload + 8 ||
        p.bytes_buffered() <= p.limits().max_nmea_chars);
}

void check_fix(const hwr::hal::GnssFix& fix) {
  check(fix.fix_type == 0 || fix.fix_type == 2 || fix.fix_type == 3);
  check(std::isfinite(fix.lat_deg) && std::fabs(fix.lat_deg) <= 90.0);
  check(std::isfinite(fix.lon_deg) && std::fabs(fix.lon_deg) <= 180.0);
  check(std::isfinite(fix.height_m));
  check(!(fix.h_acc_m < 0) && !(fix.v_acc_m < 0));
}

void check_gga(std::string_view text) {
  auto g = hwr::hal::hw::parse_gga(text);
  if (!g.ok()) {
    check(!g.status().message().empty());
    return;
  }
  check(!g->has_position || (std::fabs(g->lat_deg) <= 90.0 && std::fabs(g->lon_deg) <= 180.0));
  check(g->quality <= 8);
  check(g->quality == 0 || g->has_position);
  if (g->utc_time_of_day_s) check(*g->utc_time_of_day_s >= 0 && *g->utc_time_of_day_s < 86401.0);
  if (g->hdop) check(*g->hdop >= 0);
  check(g->height_ellipsoid_m.has_value() == (g->altitude_msl_m && g->geoid_separation_m));
  check_fix(hwr::hal::hw::to_gnss_fix(*g, 0));
}

void check_ubx_payload(uint8_t cls, uint8_t id, const uint8_t* payload, size_t n) {
  auto pvt = hwr::hal::hw::decode_nav_pvt(payload, n);  // on every payload: most are rejected by size
  if (pvt.ok()) {
    check(n == 92);
    check(pvt->fix_type <= 5 && std::fabs(pvt->lat_deg) <= 90.0 && std::fabs(pvt->lon_deg) <= 180.0);
    check(pvt->h_acc_m >= 0 && pvt->v_acc_m >= 0 && pvt->pdop >= 0);
    const hwr::hal::GnssFix fix = hwr::hal::hw::to_gnss_fix(*pvt, 0);
    check_fix(fix);
    if (!pvt->gnss_fix_ok) check(fix.fix_type == 0);
  } else {
    check(!pvt.status().message().empty());
  }
  auto ack = hwr::hal::hw::decode_ubx_ack(cls, id, payload, n);
  if (ack.ok()) {
    check(cls == 0x05 && (id == 0x00 || id == 0x01) && n == 2);
    check(ack->acknowledged == (id == 0x01) && ack->acked_cls == payload[0] && ack->acked_id == payload[1]);
  } else {
    check(!ack.status().message().empty());
  }
}

void run(const uint8_t* stream, size_t n, uint8_t chunking, GnssStreamLimits limits) {
  GnssStreamParser parser(limits);
  uint32_t lcg = chunking;
  auto sink = [&](const GnssMessage& m) {
    const GnssStreamCounters& c = parser.counters();
    const size_t end = static_cast<size_t>(c.bytes_received) - parser.bytes_buffered();
    if (m.kind == GnssMessage::Kind::kUbx) {
      const size_t len = m.ubx.payload_size;
      check(len <= limits.max_ubx_payload && end >= len + 8);
      const uint8_t* f = stream + end - (len + 8);
      check(f[0] == 0xB5 && f[1] == 0x62 && f[2] == m.ubx.cls && f[3] == m.ubx.id);
      check(static_cast<size_t>(f[4] | (f[5] << 8)) == len);
      check(len == 0 || std::memcmp(f + 6, m.ubx.payload, len) == 0);
      unsigned a = 0, b = 0;  // 8-bit Fletcher, recomputed here
      for (size_t i = 2; i < 6 + len; ++i) {
        a = (a + f[i]) & 0xFF;
        b = (b + a) & 0xFF;
      }
      check(f[6 + len] == a && f[7 + len] == b);
      check(m.nmea.empty());
      check_ubx_payload(m.ubx.cls, m.ubx.id, m.ubx.payload, len);
    } else {
      const std::string_view s = m.nmea;
      // The sentence and its line end (LF or CR LF) are the last bytes consumed.
      check(s.size() >= 4 && s.front() == '$' && s[s.size() - 3] == '*');
      const bool crlf = end >= 2 && stream[end - 1] == '\n' && stream[end - 2] == '\r' &&
                        end >= s.size() + 2 &&
                        std::memcmp(stream + end - 2 - s.size(), s.data(), s.size()) == 0;
      const bool lf = end >= 1 && stream[end - 1] == '\n' && end >= s.size() + 1 &&
                      std::memcmp(stream + end - 1 - s.size(), s.data(), s.size()) == 0;
      check(crlf || lf);
      check(s.size() + (crlf ? 2 : 1) <= limits.max_nmea_chars);
      uint8_t x = 0;
      for (size_t i = 1; i + 3 < s.size(); ++i) {
        check(s[i] >= 0x20 && s[i] <= 0x7E && s[i] != '$' && s[i] != '*');
        x = static_cast<uint8_t>(x ^ static_cast<uint8_t>(s[i]));
      }
      auto hex = [](char ch) { return ch <= '9' ? ch - '0' : (ch | 0x20) - 'a' + 10; };
      check(x == hex(s[s.size() - 2]) * 16 + hex(s[s.size() - 1]));
      check(m.ubx.payload == nullptr && m.ubx.payload_size == 0);
      check_gga(s);
    }
  };
  size_t pos = 0;
  while (pos < n) {
    size_t chunk = n - pos;
    if (chunking != 0) {
      lcg = lcg * 1103515245u + 12345u;
      chunk = std::min<size_t>(chunk, 1 + (lcg >> 16) % 300);
    }
    parser.push(stream + pos, chunk, sink);
    pos += chunk;
    check_accounting(parser);
  }
  const GnssStreamCounters& c = parser.counters();
  check(c.bytes_received == n);
  parser.reset();
  check(parser.bytes_buffered() == 0 && c.bytes_received == c.bytes_accepted + c.bytes_discarded);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const uint8_t chunking = data[0];
  const uint8_t* stream = data + 1;
  const size_t n = size - 1;
  run(stream, n, chunking, GnssStreamLimits{});
  GnssStreamLimits small;
  small.max_ubx_payload = 96;  // NAV-PVT (92) still fits
  small.max_nmea_chars = 40;
  run(stream, n, static_cast<uint8_t>(chunking ^ 0x5A), small);
  // The text decoder on its own, on the raw input.
  check_gga(std::string_view(reinterpret_cast<const char*>(stream), n));
  return 0;
}
