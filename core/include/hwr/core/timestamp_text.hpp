#pragma once
// Decimal-seconds timestamps as TUM RGB-D and our run files write them ("1305031102.175304"),
// converted to and from int64_t nanoseconds exactly: digits are parsed as integers, never through
// a double, so 1305031102.175304 s becomes 1305031102175304000 ns.

#include <cstdint>
#include <string>
#include <string_view>

namespace hwr::core {

// Accepts [-]digits[.digits] with at most 9 fractional digits. Returns false on anything else.
bool parse_timestamp_s(std::string_view text, int64_t* t_ns);

// "<seconds>.<fraction>" with `decimals` fractional digits (0..9), truncating toward -inf.
std::string format_timestamp_s(int64_t t_ns, int decimals = 6);

}  // namespace hwr::core
