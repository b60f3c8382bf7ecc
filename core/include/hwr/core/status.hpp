#pragma once
// Errors as values (STYLE.md practice 5): hardware and input errors are returned, never thrown
// across the scheduler loop. A Status carries a code and a message a person can act on, e.g.
// "rgb.txt:12: expected 'timestamp filename', got 'abc'".

#include <string>
#include <utility>
#include <variant>
#include <cassert>

namespace hwr::core {

enum class ErrorCode {
  kOk = 0,
  kInvalidArgument,  // caller passed something malformed (bad config key, wrong type)
  kNotFound,         // file, device or key absent
  kIoError,          // read/write/ioctl failed
  kParseError,       // bytes or text do not follow the expected format
  kCorruptData,      // checksum/CRC mismatch, truncated payload, impossible values
  kOutOfRange,       // value outside its documented range
  kUnavailable,      // device unplugged / not ready; may succeed later
  kTimeout,
  kEndOfStream,  // a replay or log has no more data
  kInternal,     // a bug; should not happen
};

const char* to_string(ErrorCode code);

class [[nodiscard]] Status {
 public:
  Status() = default;  // OK
  Status(ErrorCode code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status Ok() { return {}; }
  bool ok() const { return code_ == ErrorCode::kOk; }
  explicit operator bool() const { return ok(); }
  ErrorCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "<code>: <message>", one line.
  std::string to_string() const;

 private:
  ErrorCode code_ = ErrorCode::kOk;
  std::string message_;
};

inline Status InvalidArgument(std::string m) { return {ErrorCode::kInvalidArgument, std::move(m)}; }
inline Status NotFound(std::string m) { return {ErrorCode::kNotFound, std::move(m)}; }
inline Status IoError(std::string m) { return {ErrorCode::kIoError, std::move(m)}; }
inline Status ParseError(std::string m) { return {ErrorCode::kParseError, std::move(m)}; }
inline Status CorruptData(std::string m) { return {ErrorCode::kCorruptData, std::move(m)}; }
inline Status OutOfRange(std::string m) { return {ErrorCode::kOutOfRange, std::move(m)}; }
inline Status Unavailable(std::string m) { return {ErrorCode::kUnavailable, std::move(m)}; }
inline Status EndOfStream(std::string m) { return {ErrorCode::kEndOfStream, std::move(m)}; }
inline Status Internal(std::string m) { return {ErrorCode::kInternal, std::move(m)}; }

// Expected<T>: a T or a non-OK Status.
template <class T>
class [[nodiscard]] Expected {
 public:
  Expected(T value) : v_(std::move(value)) {}        // NOLINT(google-explicit-constructor)
  Expected(Status status) : v_(std::move(status)) {  // NOLINT(google-explicit-constructor)
    assert(!std::get<Status>(v_).ok() && "Expected<T> built from an OK Status has no value");
  }

  bool ok() const { return std::holds_alternative<T>(v_); }
  explicit operator bool() const { return ok(); }

  T& value() & {
    assert(ok());
    return std::get<T>(v_);
  }
  const T& value() const& {
    assert(ok());
    return std::get<T>(v_);
  }
  T&& value() && {
    assert(ok());
    return std::get<T>(std::move(v_));
  }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }

  // The error; Status::Ok() when a value is held.
  Status status() const { return ok() ? Status::Ok() : std::get<Status>(v_); }

 private:
  std::variant<T, Status> v_;
};

}  // namespace hwr::core

// Propagate a non-OK Status from an expression returning Status.
#define HWR_RETURN_IF_ERROR(expr)         \
  do {                                    \
    ::hwr::core::Status _hwr_st = (expr); \
    if (!_hwr_st.ok()) return _hwr_st;    \
  } while (0)
