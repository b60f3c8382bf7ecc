// Status/Expected, the logger and the clocks: the lead's core files, checked against their
// documented behaviour.

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "hwr/core/log.hpp"
#include "hwr/core/status.hpp"
#include "hwr/core/time.hpp"

namespace hwr::core {
namespace {

TEST(Status, GivenDefaultStatusThenOkWithEmptyMessage) {
  const Status st;
  EXPECT_TRUE(st.ok());
  EXPECT_TRUE(static_cast<bool>(st));
  EXPECT_EQ(st.code(), ErrorCode::kOk);
  EXPECT_EQ(st.to_string(), "ok");
  EXPECT_TRUE(Status::Ok().ok());
}

TEST(Status, GivenErrorHelpersThenCodeAndMessageAndOneLineText) {
  const Status st = ParseError("rgb.txt:12: expected 'timestamp filename', got 'abc'");
  EXPECT_FALSE(st.ok());
  EXPECT_EQ(st.code(), ErrorCode::kParseError);
  EXPECT_EQ(st.to_string(), "parse error: rgb.txt:12: expected 'timestamp filename', got 'abc'");
  EXPECT_EQ(InvalidArgument("x").code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(NotFound("x").code(), ErrorCode::kNotFound);
  EXPECT_EQ(IoError("x").code(), ErrorCode::kIoError);
  EXPECT_EQ(CorruptData("x").code(), ErrorCode::kCorruptData);
  EXPECT_EQ(OutOfRange("x").code(), ErrorCode::kOutOfRange);
  EXPECT_EQ(Unavailable("x").code(), ErrorCode::kUnavailable);
  EXPECT_EQ(EndOfStream("x").code(), ErrorCode::kEndOfStream);
  EXPECT_EQ(Internal("x").code(), ErrorCode::kInternal);
}

TEST(Status, GivenEveryErrorCodeThenItHasADistinctName) {
  std::vector<std::string> names;
  for (int c = 0; c <= static_cast<int>(ErrorCode::kInternal); ++c) {
    const std::string n = to_string(static_cast<ErrorCode>(c));
    EXPECT_NE(n, "unknown error");
    for (const std::string& other : names) EXPECT_NE(n, other);
    names.push_back(n);
  }
}

Expected<int> parse_positive(int v) {
  if (v <= 0) return OutOfRange("value " + std::to_string(v) + " must be > 0");
  return v;
}

Status chain(int v, int* out) {
  HWR_RETURN_IF_ERROR(parse_positive(v).status());
  *out = v * 2;
  return Status::Ok();
}

TEST(Expected, GivenValueOrErrorThenAccessorsReflectWhichIsHeld) {
  Expected<int> good = parse_positive(3);
  ASSERT_TRUE(good.ok());
  EXPECT_EQ(*good, 3);
  EXPECT_EQ(good.value(), 3);
  EXPECT_TRUE(good.status().ok());

  Expected<int> bad = parse_positive(-1);
  EXPECT_FALSE(bad.ok());
  EXPECT_FALSE(static_cast<bool>(bad));
  EXPECT_EQ(bad.status().code(), ErrorCode::kOutOfRange);
  EXPECT_EQ(bad.status().message(), "value -1 must be > 0");

  Expected<std::string> s = std::string("moved");
  const std::string taken = std::move(s).value();
  EXPECT_EQ(taken, "moved");
  Expected<std::string> t = std::string("abc");
  EXPECT_EQ(t->size(), 3u);
}

TEST(Expected, GivenReturnIfErrorWhenTheCallFailsThenTheErrorPropagatesUnchanged) {
  int out = 0;
  EXPECT_TRUE(chain(4, &out).ok());
  EXPECT_EQ(out, 8);
  const Status st = chain(0, &out);
  EXPECT_EQ(st.code(), ErrorCode::kOutOfRange);
  EXPECT_EQ(st.message(), "value 0 must be > 0");
  EXPECT_EQ(out, 8);
}

struct Captured {
  std::vector<LogLevel> levels;
  std::vector<std::string> modules;
  std::vector<std::string> messages;
};

void capture_sink(LogLevel level, const char* module, const char* message, void* user) {
  auto* c = static_cast<Captured*>(user);
  c->levels.push_back(level);
  c->modules.push_back(module);
  c->messages.push_back(message);
}

// Restores the global logger state whatever a test does.
class Log : public ::testing::Test {
 protected:
  void SetUp() override { saved_ = log_level(); }
  void TearDown() override {
    set_log_sink(nullptr);
    set_log_level(saved_);
  }
  LogLevel saved_ = LogLevel::kInfo;
};

TEST_F(Log, GivenSinkAndLevelWhenLoggingThenOnlyMessagesAtOrAboveTheLevelArriveFormatted) {
  Captured c;
  set_log_sink(&capture_sink, &c);
  set_log_level(LogLevel::kWarn);
  HWR_LOG_DEBUG("core", "debug %d", 1);
  HWR_LOG_INFO("core", "info %d", 2);
  HWR_LOG_WARN("hal", "camera %s unplugged after %d frames", "zed", 42);
  HWR_LOG_ERROR("mapio", "crc mismatch");
  log(LogLevel::kOff, "core", "never");
  ASSERT_EQ(c.messages.size(), 2u);
  EXPECT_EQ(c.levels[0], LogLevel::kWarn);
  EXPECT_EQ(c.modules[0], "hal");
  EXPECT_EQ(c.messages[0], "camera zed unplugged after 42 frames");
  EXPECT_EQ(c.levels[1], LogLevel::kError);
  EXPECT_EQ(c.messages[1], "crc mismatch");

  set_log_level(LogLevel::kOff);
  HWR_LOG_ERROR("core", "silenced");
  EXPECT_EQ(c.messages.size(), 2u);
  set_log_level(LogLevel::kDebug);
  HWR_LOG_DEBUG("core", "now visible");
  EXPECT_EQ(c.messages.size(), 3u);
}

TEST_F(Log, GivenVeryLongMessageWhenLoggedThenTruncatedNotOverflowed) {
  Captured c;
  set_log_sink(&capture_sink, &c);
  set_log_level(LogLevel::kInfo);
  const std::string big(5000, 'x');
  HWR_LOG_INFO("core", "%s", big.c_str());
  ASSERT_EQ(c.messages.size(), 1u);
  EXPECT_EQ(c.messages[0].size(), 1023u);
}

TEST_F(Log, GivenLevelNamesThenParseAndToStringRoundTripAndUnknownIsRejected) {
  for (LogLevel l : {LogLevel::kDebug, LogLevel::kInfo, LogLevel::kWarn, LogLevel::kError, LogLevel::kOff}) {
    LogLevel parsed = LogLevel::kInfo;
    ASSERT_TRUE(parse_log_level(to_string(l), &parsed));
    EXPECT_EQ(parsed, l);
  }
  LogLevel unchanged = LogLevel::kError;
  EXPECT_FALSE(parse_log_level("verbose", &unchanged));
  EXPECT_EQ(unchanged, LogLevel::kError);
}

TEST(Time, GivenSecondsWhenConvertedThenRoundedToTheNearestNanosecond) {
  static_assert(s_to_ns(1.5) == 1'500'000'000, "constexpr");
  EXPECT_EQ(s_to_ns(1305031102.5), 1305031102500000000);
  // An epoch-scale double carries only ~0.24 us resolution (half an ulp is 119 ns), so text
  // timestamps must be parsed as text, not through a double; s_to_ns cannot do better than this.
  EXPECT_LE(std::llabs(s_to_ns(1305031102.175304) - 1305031102175304000), 120);
  EXPECT_EQ(s_to_ns(-0.25), -250'000'000);
  EXPECT_EQ(s_to_ns(1e-9 * 0.4), 0);
  EXPECT_EQ(s_to_ns(1e-9 * 0.6), 1);
  EXPECT_DOUBLE_EQ(ns_to_s(2'500'000'000), 2.5);
}

TEST(Time, GivenSimClockWhenSleepingAndAdvancingThenTimeMovesOnlyForwardAndInstantly) {
  SimClock clock(100);
  EXPECT_EQ(clock.now_ns(), 100);
  clock.sleep_until_ns(50);  // in the past: no-op
  EXPECT_EQ(clock.now_ns(), 100);
  clock.sleep_until_ns(kNsPerS);
  EXPECT_EQ(clock.now_ns(), kNsPerS);
  clock.advance_ns(5);
  EXPECT_EQ(clock.now_ns(), kNsPerS + 5);
}

TEST(Time, GivenMonotonicClockWhenReadAndSleptThenNeverGoesBackAndReachesTheTarget) {
  MonotonicClock clock;
  const int64_t a = clock.now_ns();
  const int64_t target = a + 200 * kNsPerUs;
  clock.sleep_until_ns(target);
  const int64_t b = clock.now_ns();
  EXPECT_GE(b, target);     // a contract of sleep_until_ns, not a timing measurement
  clock.sleep_until_ns(a);  // past: returns at once
  EXPECT_GE(clock.now_ns(), b);
}

}  // namespace
}  // namespace hwr::core
