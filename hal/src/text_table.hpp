#pragma once
// Private to hal: the small text-table toolkit every replay reader shares (TUM lists, EuRoC CSV,
// our own sensor logs). Parsing is locale-independent (std::from_chars) and strict: a field is a
// number only if the whole field is one.

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "hwr/core/file_io.hpp"
#include "hwr/core/status.hpp"

namespace hwr::hal::text {

// Whole-file read (core/file_io.hpp).
using core::read_file;

// Calls fn(int line_no, std::string_view line) for every line that is not blank and does not
// start with '#' (after leading whitespace); '\r' and surrounding whitespace are stripped.
// Stops at and returns the first non-OK Status fn returns.
template <class Fn>
core::Status for_each_data_line(std::string_view text, Fn&& fn) {
  int line_no = 0;
  size_t pos = 0;
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    const size_t b = line.find_first_not_of(" \t\r");
    if (b == std::string_view::npos || line[b] == '#') continue;
    const size_t e = line.find_last_not_of(" \t\r");
    core::Status st = fn(line_no, line.substr(b, e - b + 1));
    if (!st.ok()) return st;
  }
  return core::Status::Ok();
}

// Splits on `sep` (',' for CSV; ' ' means runs of spaces/tabs), trimming spaces around fields.
// Writes at most max_fields views into fields and returns the total number of fields found
// (which may exceed max_fields: the caller reports the count).
size_t split_fields(std::string_view line, char sep, std::string_view* fields, size_t max_fields);

// Whole-field integer, optional leading '+' or '-'.
bool parse_int64(std::string_view s, int64_t* out);
// Whole-field finite decimal number (fixed or scientific).
bool parse_double(std::string_view s, double* out);
// Like parse_double but also accepts "nan" / "NaN" / "-nan" (returned as quiet NaN).
bool parse_double_or_nan(std::string_view s, double* out);

// "path:line: " prefix for messages.
std::string where(const std::string& path, int line_no);
// Quotes a field for a message, shortened to 40 characters.
std::string quote(std::string_view s);

}  // namespace hwr::hal::text
