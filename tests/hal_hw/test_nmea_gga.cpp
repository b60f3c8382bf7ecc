// NMEA GGA (hal/hw/nmea_gga.hpp): hardware.md's $GNGGA sentence, other talkers and hemispheres,
// the receiver's no-fix form, and the errors a corrupted or foreign line must give.
#include "hwr/hal/hw/nmea_gga.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "hwr/hal/hw/ubx_protocol.hpp"

namespace hwr::hal::hw {
namespace {

const std::string kGga =
    "$GNGGA,173002.00,6322.46840,N,01020.45757,E,1,05,7.83,167.0,M,40.1,M,,*45";  // hardware.md

// Oracle checksum from the definition: XOR of the bytes between '$' and '*'.
std::string with_checksum(const std::string& body) {
  uint8_t x = 0;
  for (char c : body) x ^= static_cast<uint8_t>(c);
  char hex[3];
  std::snprintf(hex, sizeof hex, "%02X", x);
  return "$" + body + "*" + hex;
}

void expect_error(const std::string& sentence, core::ErrorCode code, const std::string& mentions) {
  auto r = parse_gga(sentence);
  ASSERT_FALSE(r.ok()) << sentence;
  EXPECT_EQ(r.status().code(), code) << r.status().to_string();
  EXPECT_NE(r.status().message().find(mentions), std::string::npos) << r.status().message();
  EXPECT_EQ(r.status().message().find('\n'), std::string::npos) << "one line";
}

TEST(NmeaGga, GivenHardwareMdSentence_WhenParsed_ThenEveryField) {
  auto g = parse_gga(kGga);
  ASSERT_TRUE(g.ok()) << g.status().to_string();
  EXPECT_EQ(g->talker[0], 'G');
  EXPECT_EQ(g->talker[1], 'N');
  ASSERT_TRUE(g->utc_time_of_day_s);
  EXPECT_DOUBLE_EQ(*g->utc_time_of_day_s, 17 * 3600 + 30 * 60 + 2);
  ASSERT_TRUE(g->has_position);
  EXPECT_NEAR(g->lat_deg, 63.374473, 1e-6);  // hardware.md's rounding of 63° 22.46840'
  EXPECT_NEAR(g->lon_deg, 10.340960, 1e-6);  // and of 10° 20.45757'
  EXPECT_DOUBLE_EQ(g->lat_deg, 63 + 22.4684 / 60);
  EXPECT_DOUBLE_EQ(g->lon_deg, 10 + 20.45757 / 60);
  EXPECT_EQ(g->quality, 1);
  EXPECT_EQ(g->num_sv, 5);
  EXPECT_DOUBLE_EQ(*g->hdop, 7.83);
  EXPECT_DOUBLE_EQ(*g->altitude_msl_m, 167.0);
  EXPECT_DOUBLE_EQ(*g->geoid_separation_m, 40.1);
  EXPECT_DOUBLE_EQ(*g->height_ellipsoid_m, 167.0 + 40.1);

  const hal::GnssFix fix = to_gnss_fix(*g, 5000);
  EXPECT_EQ(fix.t_ns, 5000);
  EXPECT_EQ(fix.fix_type, 3);
  EXPECT_EQ(fix.num_sv, 5);
  EXPECT_DOUBLE_EQ(fix.lat_deg, g->lat_deg);
  EXPECT_DOUBLE_EQ(fix.height_m, 207.1);
  EXPECT_DOUBLE_EQ(fix.h_acc_m, 7.83 * kGgaUereM);
  EXPECT_DOUBLE_EQ(fix.v_acc_m, 7.83 * kGgaUereM * kGgaVdopPerHdop);
}

TEST(NmeaGga, GivenLineEndingsAndLowercaseChecksum_WhenParsed_ThenSameFix) {
  EXPECT_TRUE(parse_gga(kGga + "\r\n").ok());
  EXPECT_TRUE(parse_gga(kGga + "\n").ok());
  const std::string body = "GPGGA,000000.00,0000.00000,N,00000.00000,E,1,04,1.00,0.0,M,0.0,M,,";
  std::string s = with_checksum(body);
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  s = "$" + body + s.substr(s.size() - 3);
  EXPECT_TRUE(parse_gga(s).ok()) << s;
}

TEST(NmeaGga, GivenOtherTalkersAndSouthWest_WhenParsed_ThenSignedDegrees) {
  for (const char* talker : {"GP", "GL", "GA", "GB", "GN"}) {
    const std::string s = with_checksum(
        std::string(talker) + "GGA,235959.99,3351.12345,S,15112.54321,W,2,12,0.9,-12.5,M,-30.0,M,1.2,0042");
    auto g = parse_gga(s);
    ASSERT_TRUE(g.ok()) << s << ": " << g.status().to_string();
    EXPECT_EQ(g->talker[1], talker[1]);
    EXPECT_DOUBLE_EQ(*g->utc_time_of_day_s, 23 * 3600 + 59 * 60 + 59.99);
    EXPECT_DOUBLE_EQ(g->lat_deg, -(33 + 51.12345 / 60));
    EXPECT_DOUBLE_EQ(g->lon_deg, -(151 + 12.54321 / 60));
    EXPECT_EQ(g->quality, 2);
    EXPECT_DOUBLE_EQ(*g->height_ellipsoid_m, -42.5);
  }
}

TEST(NmeaGga, GivenNoFixSentence_WhenParsed_ThenNoPositionAndFixType0) {
  auto g = parse_gga("$GNGGA,173003.00,,,,,0,00,99.99,,,,,,*7E");
  ASSERT_TRUE(g.ok()) << g.status().to_string();
  EXPECT_FALSE(g->has_position);
  EXPECT_EQ(g->quality, 0);
  EXPECT_FALSE(g->altitude_msl_m);
  EXPECT_FALSE(g->height_ellipsoid_m);
  const hal::GnssFix fix = to_gnss_fix(*g, 1);
  EXPECT_EQ(fix.fix_type, 0);
  EXPECT_FALSE(fix.has_3d_fix());
  // Completely empty apart from the quality: still a valid no-fix report.
  auto bare = parse_gga(with_checksum("GPGGA,,,,,,0,,,,,,,,"));
  ASSERT_TRUE(bare.ok()) << bare.status().to_string();
  EXPECT_FALSE(bare->utc_time_of_day_s);
  EXPECT_FALSE(bare->hdop);
  EXPECT_TRUE(std::isinf(to_gnss_fix(*bare, 0).h_acc_m));
}

TEST(NmeaGga, GivenEachQuality_WhenToGnssFix_ThenOnlyPositionQualitiesGive3D) {
  for (int q = 0; q <= 8; ++q) {
    const std::string s = with_checksum("GNGGA,173002.00,6322.46840,N,01020.45757,E," + std::to_string(q) +
                                        ",05,7.83,167.0,M,40.1,M,,");
    auto g = parse_gga(s);
    ASSERT_TRUE(g.ok()) << s << ": " << g.status().to_string();
    const bool position = q == 1 || q == 2 || q == 4 || q == 5;
    EXPECT_EQ(to_gnss_fix(*g, 0).fix_type, position ? 3 : 0) << "quality " << q;
  }
}

TEST(NmeaGga, GivenNoGeoidSeparation_WhenToGnssFix_Then2DWithMslHeight) {
  auto g = parse_gga(with_checksum("GNGGA,173002.00,6322.46840,N,01020.45757,E,1,05,7.83,167.0,M,,,,"));
  ASSERT_TRUE(g.ok()) << g.status().to_string();
  EXPECT_FALSE(g->height_ellipsoid_m);
  const hal::GnssFix fix = to_gnss_fix(*g, 0);
  EXPECT_EQ(fix.fix_type, 2);
  EXPECT_DOUBLE_EQ(fix.height_m, 167.0);
}

TEST(NmeaGga, GivenCorruptOrForeignLines_WhenParsed_ThenErrorsNameTheProblem) {
  std::string flipped = kGga;
  flipped[20] = '7';  // a digit of the latitude
  expect_error(flipped, core::ErrorCode::kCorruptData, "checksum mismatch");
  expect_error(kGga.substr(1), core::ErrorCode::kParseError, "start with '$'");
  expect_error(kGga.substr(0, kGga.size() - 3), core::ErrorCode::kParseError, "'*'");
  expect_error(kGga.substr(0, kGga.size() - 2) + "G5", core::ErrorCode::kParseError, "hex");
  expect_error(with_checksum("GNRMC,173002.00,A,6322.46840,N,01020.45757,E,0.0,,170524,,,A"),
               core::ErrorCode::kParseError, "not a GGA");
  expect_error(with_checksum("GNGGA,173002.00,6322.46840,N,01020.45757,E,1,05,7.83,167.0,M,40.1,M"),
               core::ErrorCode::kParseError, "14 fields");
  expect_error(with_checksum("GNGGA,173002.00,6322.46840,N,01020.45757,E,1,05,7.83,167.0,M,40.1,M,,,"),
               core::ErrorCode::kParseError, "14 fields");
  expect_error(with_checksum("GNGGA,173002.00,6372.46840,N,01020.45757,E,1,05,7.83,167.0,M,40.1,M,,"),
               core::ErrorCode::kOutOfRange, "latitude");
  expect_error(with_checksum("GNGGA,173002.00,9100.00000,N,01020.45757,E,1,05,7.83,167.0,M,40.1,M,,"),
               core::ErrorCode::kOutOfRange, "latitude");
  expect_error(with_checksum("GNGGA,173002.00,6322.46840,N,18100.00000,E,1,05,7.83,167.0,M,40.1,M,,"),
               core::ErrorCode::kOutOfRange, "longitude");
  expect_error(with_checksum("GNGGA,173002.00,6322.46840,X,01020.45757,E,1,05,7.83,167.0,M,40.1,M,,"),
               core::ErrorCode::kParseError, "N|S");
  expect_error(with_checksum("GNGGA,173002.00,6322.46840,N,,E,1,05,7.83,167.0,M,40.1,M,,"),
               core::ErrorCode::kParseError, "position");
  expect_error(with_checksum("GNGGA,173002.00,63-2.46840,N,01020.45757,E,1,05,7.83,167.0,M,40.1,M,,"),
               core::ErrorCode::kParseError, "latitude");
  expect_error(with_checksum("GNGGA,173002.00,6322.46840,N,01020.45757,E,A,05,7.83,167.0,M,40.1,M,,"),
               core::ErrorCode::kParseError, "quality");
  expect_error(with_checksum("GNGGA,173002.00,,,,,1,05,7.83,167.0,M,40.1,M,,"), core::ErrorCode::kCorruptData,
               "position is empty");
  expect_error(with_checksum("GNGGA,173002.00,6322.46840,N,01020.45757,E,1,05,7.83,167.0,F,40.1,M,,"),
               core::ErrorCode::kParseError, "not M");
  expect_error(with_checksum("GNGGA,173002.00,6322.46840,N,01020.45757,E,1,05,-1,167.0,M,40.1,M,,"),
               core::ErrorCode::kParseError, "HDOP");
  expect_error(with_checksum("GNGGA,256002.00,6322.46840,N,01020.45757,E,1,05,7.83,167.0,M,40.1,M,,"),
               core::ErrorCode::kParseError, "UTC time");
  expect_error(with_checksum("GNGGA,1730-2.00,6322.46840,N,01020.45757,E,1,05,7.83,167.0,M,40.1,M,,"),
               core::ErrorCode::kParseError, "UTC time");
  expect_error(with_checksum("GNGGA,173002.00,6322.46840,N,01020.45757,E,1,05,7.83,1.6.7,M,40.1,M,,"),
               core::ErrorCode::kParseError, "altitude");
  expect_error("", core::ErrorCode::kParseError, "'$'");
}

TEST(NmeaGga, GivenSentenceTruncatedAtEveryPosition_WhenParsed_ThenErrorNotCrash) {
  for (size_t k = 0; k < kGga.size(); ++k) {
    auto r = parse_gga(kGga.substr(0, k));
    EXPECT_FALSE(r.ok()) << "prefix of " << k;
    EXPECT_FALSE(r.status().message().empty());
  }
}

TEST(NmeaGga, GivenSentenceFromTheStreamParser_WhenParsed_ThenSameAsDirect) {
  // The path the driver takes: bytes → GnssStreamParser → parse_gga.
  const std::string line = "noise" + kGga + "\r\n";
  GnssStreamParser parser;
  int parsed = 0;
  parser.push(reinterpret_cast<const uint8_t*>(line.data()), line.size(), [&](const GnssMessage& m) {
    ASSERT_EQ(m.kind, GnssMessage::Kind::kNmea);
    auto g = parse_gga(m.nmea);
    ASSERT_TRUE(g.ok()) << g.status().to_string();
    EXPECT_DOUBLE_EQ(g->lat_deg, 63 + 22.4684 / 60);
    ++parsed;
  });
  EXPECT_EQ(parsed, 1);
}

}  // namespace
}  // namespace hwr::hal::hw
