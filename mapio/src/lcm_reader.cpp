#include "lcm_reader.hpp"

#include <cstring>

namespace hwr::mapio::detail {

core::Status BeReader::need(size_t n, const char* field) const {
  if (left() < n) {
    return core::ParseError(std::string(type_) + ": message truncated at " + field + " (offset " +
                            std::to_string(pos_) + ", needs " + std::to_string(n) + " bytes, " +
                            std::to_string(left()) + " left of " + std::to_string(size_) + ")");
  }
  return core::Status::Ok();
}

core::Status BeReader::skip(size_t n, const char* field) {
  HWR_RETURN_IF_ERROR(need(n, field));
  pos_ += n;
  return core::Status::Ok();
}

core::Status BeReader::i32(int32_t* v, const char* field) {
  HWR_RETURN_IF_ERROR(need(4, field));
  uint32_t u = 0;
  for (int i = 0; i < 4; ++i) u = (u << 8) | data_[pos_ + i];
  pos_ += 4;
  *v = static_cast<int32_t>(u);
  return core::Status::Ok();
}

core::Status BeReader::i64(int64_t* v, const char* field) {
  HWR_RETURN_IF_ERROR(need(8, field));
  uint64_t u = 0;
  for (int i = 0; i < 8; ++i) u = (u << 8) | data_[pos_ + i];
  pos_ += 8;
  *v = static_cast<int64_t>(u);
  return core::Status::Ok();
}

core::Status BeReader::string(size_t max_bytes, const char* field) {
  const size_t at = pos_;
  int32_t length = 0;
  HWR_RETURN_IF_ERROR(i32(&length, field));
  if (length < 1) {
    return core::ParseError(std::string(type_) + ": " + field + " length " + std::to_string(length) +
                            " at offset " + std::to_string(at) + " (an LCM string is at least its NUL)");
  }
  if (static_cast<size_t>(length) - 1 > max_bytes) {
    return core::OutOfRange(std::string(type_) + ": " + field + " claims " + std::to_string(length - 1) +
                            " bytes, more than the limit of " + std::to_string(max_bytes));
  }
  HWR_RETURN_IF_ERROR(need(static_cast<size_t>(length), field));
  const uint8_t* s = data_ + pos_;
  if (s[length - 1] != 0) {
    return core::ParseError(std::string(type_) + ": " + field + " at offset " + std::to_string(at) +
                            " is not NUL-terminated");
  }
  if (std::memchr(s, 0, static_cast<size_t>(length) - 1) != nullptr) {
    return core::ParseError(std::string(type_) + ": " + field + " contains a NUL byte");
  }
  pos_ += static_cast<size_t>(length);
  return core::Status::Ok();
}

core::Status BeReader::check_fingerprint(int64_t expected) {
  int64_t hash = 0;
  HWR_RETURN_IF_ERROR(i64(&hash, "fingerprint"));
  if (hash != expected) {
    return core::ParseError(std::string("not a ") + type_ + " message (type fingerprint " +
                            std::to_string(static_cast<uint64_t>(hash)) + ", expected " +
                            std::to_string(static_cast<uint64_t>(expected)) + ")");
  }
  return core::Status::Ok();
}

core::Status BeReader::check_end() const {
  if (left() != 0) {
    return core::ParseError(std::string(type_) + ": " + std::to_string(left()) +
                            " unexpected bytes after the end of the message (offset " + std::to_string(pos_) +
                            ")");
  }
  return core::Status::Ok();
}

core::Status check_message_size(const uint8_t* data, size_t size, size_t max_bytes, const char* type) {
  if (size > max_bytes || size > static_cast<size_t>(std::numeric_limits<int>::max())) {
    return core::OutOfRange(std::string(type) + ": message of " + std::to_string(size) +
                            " bytes exceeds the limit of " + std::to_string(max_bytes));
  }
  if (data == nullptr && size > 0) return core::InvalidArgument(std::string(type) + ": null buffer");
  return core::Status::Ok();
}

}  // namespace hwr::mapio::detail
