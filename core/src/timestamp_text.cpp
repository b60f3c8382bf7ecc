#include "hwr/core/timestamp_text.hpp"

#include <cstdio>
#include <limits>

namespace hwr::core {

bool parse_timestamp_s(std::string_view text, int64_t* t_ns) {
  size_t i = 0;
  bool negative = false;
  if (i < text.size() && (text[i] == '-' || text[i] == '+')) {
    negative = text[i] == '-';
    ++i;
  }
  // Magnitude in nanoseconds, accumulated unsigned; the limit is 2^63 - 1 (2^63 when negative).
  const uint64_t limit = static_cast<uint64_t>(std::numeric_limits<int64_t>::max()) + (negative ? 1u : 0u);
  constexpr uint64_t kMaxSeconds =
      static_cast<uint64_t>(std::numeric_limits<int64_t>::max()) / 1'000'000'000ULL + 1;
  uint64_t seconds = 0;
  size_t int_digits = 0;
  for (; i < text.size() && text[i] >= '0' && text[i] <= '9'; ++i, ++int_digits) {
    seconds = seconds * 10 + static_cast<uint64_t>(text[i] - '0');
    if (seconds > kMaxSeconds) return false;  // checked every digit, so the product never wraps
  }
  uint64_t frac_ns = 0;
  size_t frac_digits = 0;
  if (i < text.size() && text[i] == '.') {
    ++i;
    uint64_t scale = 100'000'000;
    for (; i < text.size() && text[i] >= '0' && text[i] <= '9'; ++i, ++frac_digits) {
      if (frac_digits >= 9) return false;
      frac_ns += static_cast<uint64_t>(text[i] - '0') * scale;
      scale /= 10;
    }
  }
  if (i != text.size() || (int_digits == 0 && frac_digits == 0)) return false;
  if (seconds > (limit - frac_ns) / 1'000'000'000ULL) return false;
  const uint64_t v = seconds * 1'000'000'000ULL + frac_ns;
  if (v > limit) return false;
  // Two's-complement negation of the magnitude (exact also for 2^63).
  *t_ns = negative ? static_cast<int64_t>(0 - v) : static_cast<int64_t>(v);
  return true;
}

std::string format_timestamp_s(int64_t t_ns, int decimals) {
  if (decimals < 0) decimals = 0;
  if (decimals > 9) decimals = 9;
  uint64_t unit = 1;  // nanoseconds per last printed digit
  for (int k = 0; k < 9 - decimals; ++k) unit *= 10;
  // Floor to a multiple of `unit`, then print sign and magnitude: a negative time must not be
  // written as "-<sec>.<positive fraction>", which reads back as a different number.
  const bool negative = t_ns < 0;
  const uint64_t mag = negative ? 0 - static_cast<uint64_t>(t_ns) : static_cast<uint64_t>(t_ns);
  const uint64_t units = negative ? (mag + unit - 1) / unit : mag / unit;  // floor toward -inf
  uint64_t per_second = 1;
  for (int k = 0; k < decimals; ++k) per_second *= 10;
  const unsigned long long sec = units / per_second;
  const unsigned long long frac = units % per_second;
  const char* sign = (negative && units != 0) ? "-" : "";
  char buf[48];
  if (decimals == 0) {
    std::snprintf(buf, sizeof(buf), "%s%llu", sign, sec);
  } else {
    std::snprintf(buf, sizeof(buf), "%s%llu.%0*llu", sign, sec, decimals, frac);
  }
  return buf;
}

}  // namespace hwr::core
