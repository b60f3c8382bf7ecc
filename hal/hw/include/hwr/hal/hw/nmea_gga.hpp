#pragma once
// NMEA 0183 GGA (fix data), the M8T's text fallback when NAV-PVT is not configured (hardware.md
// "NMEA fallback"). Any talker: $GPGGA, $GNGGA, $GLGGA, $GAGGA, $GBGGA …
//
//   $GNGGA,173002.00,6322.46840,N,01020.45757,E,1,05,7.83,167.0,M,40.1,M,,*45
//          time      lat        N/S lon       E/W q sv hdop alt  M sep  M age station*checksum
//
// Checksum: XOR of the bytes between '$' and '*', two hex digits. A receiver without a fix sends
// the sentence with empty position fields and quality 0 ("$GNGGA,173003.00,,,,,0,00,99.99,,,,,,*7E"):
// that parses, with has_position false.

#include <array>
#include <cstdint>
#include <optional>
#include <string_view>

#include "hwr/core/status.hpp"
#include "hwr/hal/gnss_fix.hpp"

namespace hwr::hal::hw {

struct GgaFix {
  std::array<char, 2> talker{};  // "GN", "GP", …

  std::optional<double> utc_time_of_day_s;  // field 1, hhmmss.ss → seconds since 00:00 UTC

  // Fields 2–5, ddmm.mmmm / dddmm.mmmm with hemisphere → signed degrees (north, east positive).
  bool has_position = false;
  double lat_deg = 0;
  double lon_deg = 0;

  // Field 6: 0 invalid, 1 GPS (SPS), 2 DGPS, 3 PPS, 4 RTK fixed, 5 RTK float, 6 dead reckoning,
  // 7 manual input, 8 simulation.
  uint8_t quality = 0;
  std::optional<int> num_sv;                 // field 7, satellites in use
  std::optional<double> hdop;                // field 8
  std::optional<double> altitude_msl_m;      // field 9 (unit field 10 must be M)
  std::optional<double> geoid_separation_m;  // field 11: ellipsoid − geoid (unit field 12 M)
  // altitude_msl_m + geoid_separation_m, present when both are.
  std::optional<double> height_ellipsoid_m;
};

// Parses one sentence, '$' through the checksum; a trailing CR LF is allowed. Errors
// (kParseError / kCorruptData for a checksum mismatch / kOutOfRange) name the field and the text.
core::Expected<GgaFix> parse_gga(std::string_view sentence);

// GGA carries no accuracy estimate, only HDOP. σ_h ≈ HDOP · σ_UERE with the user equivalent range
// error of an unaided single-frequency receiver taken as 3 m (a conservative 1σ; u-blox's own hAcc is
// usually below this for HDOP 1). Vertical: GGA has no VDOP; VDOP is typically 1.5–2 × HDOP, 2 used.
inline constexpr double kGgaUereM = 3.0;
inline constexpr double kGgaVdopPerHdop = 2.0;

// hal::GnssFix from GGA. fix_type: quality 1/2/4/5 (GPS, DGPS, RTK fixed, RTK float) → 3 when the
// ellipsoidal height is known, 2 when only the horizontal position is; every other quality → 0.
// height_m is the ellipsoidal height (MSL + separation), or the MSL altitude for a 2D fix (0 if
// none). h_acc_m = HDOP · kGgaUereM, v_acc_m = h_acc_m · kGgaVdopPerHdop; both +infinity (unknown)
// when HDOP is empty.
hal::GnssFix to_gnss_fix(const GgaFix& gga, int64_t t_ns);

}  // namespace hwr::hal::hw
