#pragma once
// hwr-ground's --operator-input: operator commands as text, one per line, read without blocking the
// station's loop (a file, `-` for stdin, or a FIFO a script or another terminal writes into).
//
//   [--robot ROBOT_ID] confirm ID
//   [--robot ROBOT_ID] reject ID
//   [--robot ROBOT_ID] move ID CX CY CZ SX SY SZ [QW QX QY QZ]   world frame, metres, full sizes;
//                                                                 orientation identity if omitted
//   [--robot ROBOT_ID] add KEYFRAME_T_NS X Y W H [CX CY CZ SX SY SZ]
//                      a region drawn on that keyframe (pixels: top-left x, y, width, height) and,
//                      optionally, its box in the world frame (metres, axis-aligned)
// Blank lines and lines starting with '#' are skipped.

#include <cstdint>
#include <string>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr_lcm/operator_command_t.hpp"

namespace hwr::ground {

struct OperatorLine {
  bool empty = true;                    // blank or a comment: nothing to do
  std::string robot_id;                 // from --robot; empty: the caller chooses
  hwr_lcm::operator_command_t command;  // every field set; robot_id, command_id and t_ns left empty
};

// kParseError saying what is wrong with the line (the caller adds its number).
core::Expected<OperatorLine> parse_operator_line(const std::string& line);

// Reads lines from a file descriptor without ever blocking. A FIFO is opened with O_NONBLOCK (so the
// open does not wait for a writer) and read again after each writer closes it; a regular file or
// stdin is read to its end, and from there on whatever is appended. A last line without its newline
// counts once the writer is done (end of file).
class OperatorInput {
 public:
  // `-` is stdin (its O_NONBLOCK flag is restored on destruction). kIoError when the path cannot be
  // opened.
  static core::Expected<OperatorInput> open(const std::string& path);
  OperatorInput(OperatorInput&& other) noexcept;
  OperatorInput& operator=(OperatorInput&&) = delete;
  OperatorInput(const OperatorInput&) = delete;
  ~OperatorInput();

  // Appends the complete lines available now (without their newline) and their 1-based numbers.
  // A line over kMaxLineChars is replaced by an error text starting with "\x01" (never a valid
  // command). kIoError when reading fails.
  core::Status poll(std::vector<std::pair<int64_t, std::string>>* lines);

  static constexpr size_t kMaxLineChars = 4096;
  static constexpr char kTooLong = '\x01';

 private:
  OperatorInput(int fd, bool is_stdin, int stdin_flags);
  void finish_line(std::vector<std::pair<int64_t, std::string>>* lines);

  int fd_ = -1;
  bool is_stdin_ = false;
  int stdin_flags_ = 0;
  std::string partial_;
  bool overlong_ = false;
  int64_t line_number_ = 0;
};

}  // namespace hwr::ground
