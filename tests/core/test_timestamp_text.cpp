// Exact decimal-seconds <-> nanoseconds conversion (core/timestamp_text.hpp).

#include <cstdint>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include "hwr/core/timestamp_text.hpp"

namespace hwr::core {
namespace {

int64_t parse_or_die(const std::string& s) {
  int64_t t = -12345;
  EXPECT_TRUE(parse_timestamp_s(s, &t)) << s;
  return t;
}

TEST(TimestampText, GivenTumStyleText_WhenParsed_ThenNanosecondsAreExact) {
  // A double cannot hold 1305031102.175304 exactly; the integer parse must.
  EXPECT_EQ(parse_or_die("1305031102.175304"), 1305031102175304000LL);
  EXPECT_EQ(parse_or_die("1341841873.4151"), 1341841873415100000LL);
  EXPECT_EQ(parse_or_die("1403715273.262142976"), 1403715273262142976LL);
  EXPECT_EQ(parse_or_die("0"), 0);
  EXPECT_EQ(parse_or_die("7"), 7'000'000'000LL);
  EXPECT_EQ(parse_or_die("7."), 7'000'000'000LL);
  EXPECT_EQ(parse_or_die(".5"), 500'000'000LL);
  EXPECT_EQ(parse_or_die("+1.000000001"), 1'000'000'001LL);
  EXPECT_EQ(parse_or_die("-1.5"), -1'500'000'000LL);
  EXPECT_EQ(parse_or_die("-0.000000001"), -1);
}

TEST(TimestampText, GivenMalformedText_WhenParsed_ThenRejectedAndOutputUntouched) {
  for (const char* bad : {"", ".", "-", "+", "abc", "1.2.3", "1e9", " 1", "1 ", "1.0000000001", "0x10", "--1",
                          "1,5", "nan", "inf"}) {
    int64_t t = 42;
    EXPECT_FALSE(parse_timestamp_s(bad, &t)) << "'" << bad << "'";
    EXPECT_EQ(t, 42) << bad;
  }
}

TEST(TimestampText, GivenSecondsBeyondInt64Nanoseconds_WhenParsed_ThenRejectedNotWrapped) {
  // int64 nanoseconds end at 9223372036.854775807 s.
  EXPECT_EQ(parse_or_die("9223372036.854775807"), std::numeric_limits<int64_t>::max());
  EXPECT_EQ(parse_or_die("-9223372036.854775807"), -std::numeric_limits<int64_t>::max());
  int64_t t = 0;
  EXPECT_FALSE(parse_timestamp_s("9223372036.854775808", &t));
  EXPECT_FALSE(parse_timestamp_s("9223372037", &t));
  EXPECT_FALSE(parse_timestamp_s("9300000000", &t));
  EXPECT_FALSE(parse_timestamp_s("90000000000", &t));
  EXPECT_FALSE(parse_timestamp_s("99999999999999999999999999", &t));
}

TEST(TimestampText, GivenNanoseconds_WhenFormatted_ThenDigitsTruncateTowardMinusInfinity) {
  EXPECT_EQ(format_timestamp_s(1305031102175304000LL), "1305031102.175304");
  EXPECT_EQ(format_timestamp_s(1403715273262142976LL, 9), "1403715273.262142976");
  EXPECT_EQ(format_timestamp_s(1403715273262142976LL, 3), "1403715273.262");
  EXPECT_EQ(format_timestamp_s(1999999999, 0), "1");
  EXPECT_EQ(format_timestamp_s(0, 6), "0.000000");
  // Negative times: the text must read back as the same (or the next lower) value.
  EXPECT_EQ(format_timestamp_s(-1'500'000'000LL, 3), "-1.500");
  EXPECT_EQ(format_timestamp_s(-1, 9), "-0.000000001");
  EXPECT_EQ(format_timestamp_s(-1, 6), "-0.000001");
  EXPECT_EQ(format_timestamp_s(-1'000'000'000LL, 0), "-1");
  EXPECT_EQ(format_timestamp_s(-1, 0), "-1");
  // Out-of-range decimals are clamped to 0..9.
  EXPECT_EQ(format_timestamp_s(1'234'567'891LL, 12), "1.234567891");
  EXPECT_EQ(format_timestamp_s(1'234'567'891LL, -3), "1");
}

TEST(TimestampText, GivenAnyNanoseconds_WhenFormattedWithNineDigitsAndParsed_ThenRoundTripIsExact) {
  const int64_t values[] = {0,
                            1,
                            -1,
                            999'999'999,
                            -999'999'999,
                            1'000'000'000,
                            -1'000'000'001,
                            1341841873415100000LL,
                            -1341841873415100123LL,
                            std::numeric_limits<int64_t>::max(),
                            std::numeric_limits<int64_t>::min() + 1};
  for (int64_t v : values) {
    const std::string s = format_timestamp_s(v, 9);
    int64_t back = 0;
    ASSERT_TRUE(parse_timestamp_s(s, &back)) << s;
    EXPECT_EQ(back, v) << s;
  }
}

TEST(TimestampText, GivenFewerDecimals_WhenFormattedAndParsed_ThenResultIsTheFloorToThatResolution) {
  for (int64_t v : {int64_t{1'234'567'891}, int64_t{-1'234'567'891}, int64_t{-1}, int64_t{5}}) {
    for (int d = 0; d <= 9; ++d) {
      int64_t unit = 1;
      for (int k = 0; k < 9 - d; ++k) unit *= 10;
      const int64_t floor_v = (v >= 0 ? v / unit : -((-v + unit - 1) / unit)) * unit;
      int64_t back = 0;
      const std::string s = format_timestamp_s(v, d);
      ASSERT_TRUE(parse_timestamp_s(s, &back)) << s;
      EXPECT_EQ(back, floor_v) << "v=" << v << " decimals=" << d << " text=" << s;
    }
  }
}

}  // namespace
}  // namespace hwr::core
