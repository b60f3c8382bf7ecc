#include "operator_input.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <sstream>

namespace hwr::ground {
namespace {

bool parse_int(const std::string& s, int64_t* v) {
  if (s.empty()) return false;
  errno = 0;
  char* end = nullptr;
  const long long x = std::strtoll(s.c_str(), &end, 10);
  if (errno != 0 || end != s.c_str() + s.size()) return false;
  *v = x;
  return true;
}

bool parse_number(const std::string& s, double* v) {
  if (s.empty()) return false;
  errno = 0;
  char* end = nullptr;
  const double x = std::strtod(s.c_str(), &end);
  if (errno != 0 || end != s.c_str() + s.size() || !std::isfinite(x)) return false;
  *v = x;
  return true;
}

hwr_lcm::operator_command_t blank_command() {
  hwr_lcm::operator_command_t c;  // LCM types leave their scalars uninitialized: set every field
  c.t_ns = 0;
  c.command_id = 0;
  c.kind = 0;
  c.detection_id = -1;
  c.keyframe_t_ns = 0;
  for (float& v : c.box_px) v = 0;
  for (double& v : c.box_center_world_m) v = 0;
  for (double& v : c.box_size_m) v = 0;
  c.box_q_world_box[0] = 1;
  c.box_q_world_box[1] = c.box_q_world_box[2] = c.box_q_world_box[3] = 0;
  return c;
}

core::Status numbers(const std::vector<std::string>& words, size_t from, size_t count, const char* names,
                     double* out) {
  for (size_t i = 0; i < count; ++i) {
    if (!parse_number(words[from + i], &out[i])) {
      return core::ParseError("'" + words[from + i] + "' is not a finite number (expected " + names + ")");
    }
  }
  return core::Status::Ok();
}

}  // namespace

core::Expected<OperatorLine> parse_operator_line(const std::string& line) {
  OperatorLine out;
  out.command = blank_command();
  std::istringstream in(line);
  std::vector<std::string> w;
  for (std::string word; in >> word;) w.push_back(word);
  if (w.empty() || w[0][0] == '#') return out;
  out.empty = false;
  size_t at = 0;
  if (w[0] == "--robot") {
    if (w.size() < 2) return core::ParseError("--robot needs a robot id");
    out.robot_id = w[1];
    at = 2;
    if (w.size() == 2) return core::ParseError("--robot " + w[1] + " is not followed by a command");
  }
  const std::string verb = w[at];
  const size_t args = w.size() - at - 1;
  auto usage = [&](const char* form) {
    return core::ParseError(verb + " takes " + form + ", got " + std::to_string(args) + " argument" +
                            (args == 1 ? "" : "s"));
  };
  hwr_lcm::operator_command_t& c = out.command;
  if (verb == "confirm" || verb == "reject") {
    if (args != 1) return usage("one detection id");
    if (!parse_int(w[at + 1], &c.detection_id) || c.detection_id < 0) {
      return core::ParseError("detection id '" + w[at + 1] + "' is not an integer >= 0");
    }
    c.kind = verb == "confirm" ? 0 : 1;
    return out;
  }
  if (verb == "move") {
    if (args != 7 && args != 11) return usage("ID CX CY CZ SX SY SZ [QW QX QY QZ]");
    if (!parse_int(w[at + 1], &c.detection_id) || c.detection_id < 0) {
      return core::ParseError("detection id '" + w[at + 1] + "' is not an integer >= 0");
    }
    c.kind = 2;
    HWR_RETURN_IF_ERROR(numbers(w, at + 2, 3, "CX CY CZ in metres", c.box_center_world_m));
    HWR_RETURN_IF_ERROR(numbers(w, at + 5, 3, "SX SY SZ in metres", c.box_size_m));
    if (args == 11) HWR_RETURN_IF_ERROR(numbers(w, at + 8, 4, "QW QX QY QZ", c.box_q_world_box));
    return out;
  }
  if (verb == "add") {
    if (args != 5 && args != 11) return usage("KEYFRAME_T_NS X Y W H [CX CY CZ SX SY SZ]");
    if (!parse_int(w[at + 1], &c.keyframe_t_ns) || c.keyframe_t_ns < 0) {
      return core::ParseError("keyframe time '" + w[at + 1] + "' is not an integer >= 0 (ns)");
    }
    c.kind = 3;
    double px[4];
    HWR_RETURN_IF_ERROR(numbers(w, at + 2, 4, "X Y W H in pixels", px));
    for (int i = 0; i < 4; ++i) c.box_px[i] = static_cast<float>(px[i]);
    if (args == 11) {
      HWR_RETURN_IF_ERROR(numbers(w, at + 6, 3, "CX CY CZ in metres", c.box_center_world_m));
      HWR_RETURN_IF_ERROR(numbers(w, at + 9, 3, "SX SY SZ in metres", c.box_size_m));
    }
    return out;
  }
  return core::ParseError("unknown command '" + verb + "' (expected confirm, reject, move or add)");
}

// --- OperatorInput ---------------------------------------------------------------------------------

OperatorInput::OperatorInput(int fd, bool is_stdin, int stdin_flags)
    : fd_(fd), is_stdin_(is_stdin), stdin_flags_(stdin_flags) {}

OperatorInput::OperatorInput(OperatorInput&& other) noexcept
    : fd_(other.fd_),
      is_stdin_(other.is_stdin_),
      stdin_flags_(other.stdin_flags_),
      partial_(std::move(other.partial_)),
      overlong_(other.overlong_),
      line_number_(other.line_number_) {
  other.fd_ = -1;
}

OperatorInput::~OperatorInput() {
  if (fd_ < 0) return;
  if (is_stdin_) {
    (void)::fcntl(fd_, F_SETFL, stdin_flags_);  // the shell shares this file description
  } else {
    ::close(fd_);
  }
}

core::Expected<OperatorInput> OperatorInput::open(const std::string& path) {
  if (path == "-") {
    const int flags = ::fcntl(STDIN_FILENO, F_GETFL);
    if (flags < 0 || ::fcntl(STDIN_FILENO, F_SETFL, flags | O_NONBLOCK) != 0) {
      return core::IoError(std::string("stdin: cannot make it non-blocking: ") + std::strerror(errno));
    }
    return OperatorInput(STDIN_FILENO, true, flags);
  }
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for its first writer.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return core::IoError(path + ": cannot open operator input: " + std::strerror(errno));
  return OperatorInput(fd, false, 0);
}

void OperatorInput::finish_line(std::vector<std::pair<int64_t, std::string>>* lines) {
  ++line_number_;
  if (overlong_) {
    lines->emplace_back(line_number_, std::string(1, kTooLong) + "longer than " +
                                          std::to_string(kMaxLineChars) + " characters");
  } else {
    lines->emplace_back(line_number_, partial_);
  }
  partial_.clear();
  overlong_ = false;
}

core::Status OperatorInput::poll(std::vector<std::pair<int64_t, std::string>>* lines) {
  char buf[4096];
  // Bounded per call, so a fast writer cannot hold up the station's loop.
  for (int reads = 0; reads < 16; ++reads) {
    const ssize_t n = ::read(fd_, buf, sizeof buf);
    if (n < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK) return core::Status::Ok();
      if (errno == EINTR) continue;
      return core::IoError(std::string("operator input: read failed: ") + std::strerror(errno));
    }
    if (n == 0) {
      // End of file, or a FIFO's writer closed it: a last line without a newline is complete.
      if (!partial_.empty() || overlong_) finish_line(lines);
      return core::Status::Ok();
    }
    for (ssize_t i = 0; i < n; ++i) {
      if (buf[i] == '\n') {
        finish_line(lines);
      } else if (partial_.size() < kMaxLineChars) {
        partial_.push_back(buf[i]);
      } else {
        overlong_ = true;
      }
    }
  }
  return core::Status::Ok();
}

}  // namespace hwr::ground
