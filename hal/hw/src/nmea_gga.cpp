#include "hwr/hal/hw/nmea_gga.hpp"

#include <array>
#include <cstdint>
#include <limits>
#include <string>

namespace hwr::hal::hw {
namespace {

constexpr size_t kGgaTokens = 15;  // address + 14 fields

// The sentence for an error message, shortened so a garbage line cannot make it huge.
std::string quoted(std::string_view s) {
  constexpr size_t kMax = 100;
  std::string out = "'";
  out.append(s.substr(0, kMax));
  if (s.size() > kMax) out += "...";
  out += "'";
  return out;
}

bool is_digit(char c) { return c >= '0' && c <= '9'; }

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

// Strict decimal "[-]digits[.digits]" (at least one digit, at most 15 significant), independent of
// the C locale. mantissa / 10^k is correctly rounded: both are exact doubles below 2^53 / 10^22.
bool parse_decimal(std::string_view s, double* out) {
  size_t i = 0;
  bool negative = false;
  if (i < s.size() && (s[i] == '-' || s[i] == '+')) {
    negative = s[i] == '-';
    ++i;
  }
  uint64_t mantissa = 0;
  int digits = 0;
  int fraction_digits = 0;
  bool seen_point = false;
  for (; i < s.size(); ++i) {
    const char c = s[i];
    if (c == '.' && !seen_point) {
      seen_point = true;
      continue;
    }
    if (!is_digit(c)) return false;
    if (++digits > 15) return false;
    mantissa = mantissa * 10 + static_cast<uint64_t>(c - '0');
    if (seen_point) ++fraction_digits;
  }
  if (digits == 0) return false;
  static constexpr double kPow10[16] = {1e0, 1e1, 1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                        1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15};
  const double v = static_cast<double>(mantissa) / kPow10[fraction_digits];
  *out = negative ? -v : v;
  return true;
}

bool parse_uint(std::string_view s, int max_value, int* out) {
  if (s.empty() || s.size() > 6) return false;
  int v = 0;
  for (char c : s) {
    if (!is_digit(c)) return false;
    v = v * 10 + (c - '0');
  }
  if (v > max_value) return false;
  *out = v;
  return true;
}

// "ddmm.mmmm" (deg_digits = 2) or "dddmm.mmmm" (3): degrees, then minutes with a fraction. Takes the
// degree digits textually (all integer digits but the last two) so no rounding creeps in.
core::Status parse_angle(std::string_view text, char hemisphere, const char* what, double max_deg,
                         std::string_view sentence, double* out_deg) {
  for (char c : text) {
    if (!is_digit(c) && c != '.') {
      return core::ParseError(std::string("GGA ") + what + " '" + std::string(text) +
                              "' is not (d)ddmm.mmmm in " + quoted(sentence));
    }
  }
  const size_t point = text.find('.');
  const size_t int_digits = point == std::string_view::npos ? text.size() : point;
  if (int_digits < 3 || int_digits > 5) {
    return core::ParseError(std::string("GGA ") + what + " '" + std::string(text) +
                            "' is not (d)ddmm.mmmm in " + quoted(sentence));
  }
  int degrees = 0;
  double minutes = 0;
  if (!parse_uint(text.substr(0, int_digits - 2), 999, &degrees) ||
      !parse_decimal(text.substr(int_digits - 2), &minutes)) {
    return core::ParseError(std::string("GGA ") + what + " '" + std::string(text) +
                            "' is not (d)ddmm.mmmm in " + quoted(sentence));
  }
  const double deg = degrees + minutes / 60.0;
  if (minutes >= 60.0 || deg > max_deg) {
    return core::OutOfRange(std::string("GGA ") + what + " '" + std::string(text) + "' is beyond " +
                            std::to_string(static_cast<int>(max_deg)) + " deg or has minutes >= 60 in " +
                            quoted(sentence));
  }
  const bool positive = hemisphere == 'N' || hemisphere == 'E';
  *out_deg = positive ? deg : -deg;
  return {};
}

// An optional number with a unit field that must say M when the number is present.
core::Status parse_metres(std::string_view value, std::string_view unit, const char* what,
                          std::string_view sentence, std::optional<double>* out) {
  if (value.empty()) {
    out->reset();
    return {};
  }
  double v = 0;
  if (!parse_decimal(value, &v)) {
    return core::ParseError(std::string("GGA ") + what + " '" + std::string(value) + "' is not a number in " +
                            quoted(sentence));
  }
  if (unit != "M") {
    return core::ParseError(std::string("GGA ") + what + " unit '" + std::string(unit) +
                            "' is not M (metres) in " + quoted(sentence));
  }
  *out = v;
  return {};
}

}  // namespace

core::Expected<GgaFix> parse_gga(std::string_view sentence) {
  while (!sentence.empty() && (sentence.back() == '\n' || sentence.back() == '\r')) sentence.remove_suffix(1);
  if (sentence.empty() || sentence.front() != '$') {
    return core::ParseError("NMEA sentence must start with '$': " + quoted(sentence));
  }
  const size_t star = sentence.find('*');
  if (star == std::string_view::npos || star + 3 != sentence.size()) {
    return core::ParseError("NMEA sentence must end with '*' and two hex checksum digits: " +
                            quoted(sentence));
  }
  const int hi = hex_value(sentence[star + 1]);
  const int lo = hex_value(sentence[star + 2]);
  if (hi < 0 || lo < 0) {
    return core::ParseError("NMEA checksum '" + std::string(sentence.substr(star + 1)) +
                            "' is not two hex digits: " + quoted(sentence));
  }
  const std::string_view body = sentence.substr(1, star - 1);
  uint8_t x = 0;
  for (char c : body) x = static_cast<uint8_t>(x ^ static_cast<uint8_t>(c));
  const int sent = hi * 16 + lo;
  if (x != sent) {
    static constexpr char kHex[] = "0123456789ABCDEF";
    return core::CorruptData(std::string("NMEA checksum mismatch: sentence says ") + kHex[sent >> 4] +
                             kHex[sent & 15] + ", bytes give " + kHex[x >> 4] + kHex[x & 15] + " in " +
                             quoted(sentence));
  }

  std::array<std::string_view, kGgaTokens> f;
  size_t count = 0;
  size_t start = 0;
  while (true) {
    const size_t comma = body.find(',', start);
    const std::string_view tok =
        body.substr(start, comma == std::string_view::npos ? body.npos : comma - start);
    if (count == kGgaTokens) {
      ++count;  // too many; counted only to say so
      break;
    }
    f[count++] = tok;
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  const std::string_view address = f[0];
  if (address.size() != 5 || address.substr(2) != "GGA" || address[0] < 'A' || address[0] > 'Z' ||
      address[1] < 'A' || address[1] > 'Z') {
    return core::ParseError("not a GGA sentence (address '" + std::string(address.substr(0, 16)) +
                            "', expected <talker>GGA such as GNGGA): " + quoted(sentence));
  }
  if (count != kGgaTokens) {
    return core::ParseError("GGA must have 14 fields after the address, got " +
                            (count > kGgaTokens ? std::string("more") : std::to_string(count - 1)) + ": " +
                            quoted(sentence));
  }

  GgaFix g;
  g.talker = {address[0], address[1]};

  // Field 1: hhmmss.ss UTC.
  if (!f[1].empty()) {
    const std::string_view t = f[1];
    int hh = 0, mm = 0;
    double ss = 0;
    const bool shaped = t.size() >= 6 && (t.size() == 6 || t[6] == '.');
    if (!shaped || !parse_uint(t.substr(0, 2), 23, &hh) || !parse_uint(t.substr(2, 2), 59, &mm) ||
        !parse_decimal(t.substr(4), &ss) || !is_digit(t[4]) || ss >= 61.0) {
      return core::ParseError("GGA UTC time '" + std::string(t) + "' is not hhmmss.ss in " +
                              quoted(sentence));
    }
    g.utc_time_of_day_s = hh * 3600.0 + mm * 60.0 + ss;
  }

  // Fields 2–5: all empty (no fix) or all present.
  const bool any_pos = !f[2].empty() || !f[3].empty() || !f[4].empty() || !f[5].empty();
  if (any_pos) {
    if (f[2].empty() || f[4].empty() || (f[3] != "N" && f[3] != "S") || (f[5] != "E" && f[5] != "W")) {
      return core::ParseError("GGA position needs latitude, N|S, longitude, E|W (or all four empty), got '" +
                              std::string(f[2]) + "," + std::string(f[3]) + "," + std::string(f[4]) + "," +
                              std::string(f[5]) + "' in " + quoted(sentence));
    }
    HWR_RETURN_IF_ERROR(parse_angle(f[2], f[3][0], "latitude", 90.0, sentence, &g.lat_deg));
    HWR_RETURN_IF_ERROR(parse_angle(f[4], f[5][0], "longitude", 180.0, sentence, &g.lon_deg));
    g.has_position = true;
  }

  int quality = 0;
  if (f[6].size() != 1 || !parse_uint(f[6], 8, &quality)) {
    return core::ParseError("GGA fix quality '" + std::string(f[6]) + "' is not a digit 0..8 in " +
                            quoted(sentence));
  }
  g.quality = static_cast<uint8_t>(quality);
  if (quality != 0 && !g.has_position) {
    return core::CorruptData("GGA fix quality " + std::to_string(quality) + " but the position is empty in " +
                             quoted(sentence));
  }

  if (!f[7].empty()) {
    int sv = 0;
    if (!parse_uint(f[7], 999, &sv)) {
      return core::ParseError("GGA satellite count '" + std::string(f[7]) + "' is not a number in " +
                              quoted(sentence));
    }
    g.num_sv = sv;
  }
  if (!f[8].empty()) {
    double hdop = 0;
    if (!parse_decimal(f[8], &hdop) || hdop < 0) {
      return core::ParseError("GGA HDOP '" + std::string(f[8]) + "' is not a non-negative number in " +
                              quoted(sentence));
    }
    g.hdop = hdop;
  }
  HWR_RETURN_IF_ERROR(parse_metres(f[9], f[10], "altitude", sentence, &g.altitude_msl_m));
  HWR_RETURN_IF_ERROR(parse_metres(f[11], f[12], "geoid separation", sentence, &g.geoid_separation_m));
  if (g.altitude_msl_m && g.geoid_separation_m)
    g.height_ellipsoid_m = *g.altitude_msl_m + *g.geoid_separation_m;
  // Fields 13 (age of differential corrections) and 14 (station id) are not used.
  return g;
}

hal::GnssFix to_gnss_fix(const GgaFix& gga, int64_t t_ns) {
  hal::GnssFix fix;
  fix.t_ns = t_ns;
  const bool position_fix =
      gga.has_position && (gga.quality == 1 || gga.quality == 2 || gga.quality == 4 || gga.quality == 5);
  if (position_fix) fix.fix_type = gga.height_ellipsoid_m ? 3 : 2;
  fix.num_sv = static_cast<uint8_t>(gga.num_sv ? (*gga.num_sv > 255 ? 255 : *gga.num_sv) : 0);
  fix.lat_deg = gga.lat_deg;
  fix.lon_deg = gga.lon_deg;
  if (gga.height_ellipsoid_m) {
    fix.height_m = *gga.height_ellipsoid_m;
  } else if (gga.altitude_msl_m) {
    fix.height_m = *gga.altitude_msl_m;
  }
  if (gga.hdop) {
    fix.h_acc_m = *gga.hdop * kGgaUereM;
    fix.v_acc_m = fix.h_acc_m * kGgaVdopPerHdop;
  } else {
    fix.h_acc_m = fix.v_acc_m = std::numeric_limits<double>::infinity();
  }
  return fix;
}

}  // namespace hwr::hal::hw
