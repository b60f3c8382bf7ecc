#include "text_table.hpp"

#include <charconv>
#include <cmath>
#include <limits>

namespace hwr::hal::text {

namespace {
bool is_space(char c) { return c == ' ' || c == '\t'; }

std::string_view trim(std::string_view s) {
  size_t b = 0;
  size_t e = s.size();
  while (b < e && is_space(s[b])) ++b;
  while (e > b && is_space(s[e - 1])) --e;
  return s.substr(b, e - b);
}
}  // namespace

size_t split_fields(std::string_view line, char sep, std::string_view* fields, size_t max_fields) {
  size_t n = 0;
  if (sep == ' ') {
    size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && is_space(line[i])) ++i;
      if (i == line.size()) break;
      const size_t b = i;
      while (i < line.size() && !is_space(line[i])) ++i;
      if (n < max_fields) fields[n] = line.substr(b, i - b);
      ++n;
    }
    return n;
  }
  size_t b = 0;
  while (true) {
    const size_t e = line.find(sep, b);
    const std::string_view f =
        trim(line.substr(b, e == std::string_view::npos ? std::string_view::npos : e - b));
    if (n < max_fields) fields[n] = f;
    ++n;
    if (e == std::string_view::npos) break;
    b = e + 1;
  }
  return n;
}

bool parse_int64(std::string_view s, int64_t* out) {
  if (!s.empty() && s.front() == '+') {
    s.remove_prefix(1);
    if (s.empty() || s.front() == '+' || s.front() == '-') return false;  // "++5", "+-5"
  }
  if (s.empty()) return false;
  int64_t v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size()) return false;
  *out = v;
  return true;
}

bool parse_double(std::string_view s, double* out) {
  if (!s.empty() && s.front() == '+') {
    s.remove_prefix(1);
    if (s.empty() || s.front() == '+' || s.front() == '-') return false;  // "++5", "+-5"
  }
  if (s.empty()) return false;
  double v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size() || !std::isfinite(v)) return false;
  *out = v;
  return true;
}

bool parse_double_or_nan(std::string_view s, double* out) {
  if (s == "nan" || s == "NaN" || s == "NAN" || s == "-nan" || s == "-NaN") {
    *out = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  return parse_double(s, out);
}

std::string where(const std::string& path, int line_no) {
  return path + ":" + std::to_string(line_no) + ": ";
}

std::string quote(std::string_view s) {
  if (s.size() > 40) return "'" + std::string(s.substr(0, 37)) + "...'";
  return "'" + std::string(s) + "'";
}

}  // namespace hwr::hal::text
