#pragma once
// Bounded walking of LCM-encoded messages (private to mapio), shared by the chunk and operator wires.
// LCM 1.3.1's generated decode() resizes a vector to whatever a count field says and mishandles a
// string length <= 0, so every received message is walked with this reader first: each length field
// is checked against the bytes present and the caller's limits, and only then is decode() run.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "hwr/core/status.hpp"

namespace hwr::mapio::detail {

// Big-endian reads over the received bytes (LCM's encoding); every read is bounds-checked. Errors
// (kParseError / kOutOfRange) name the message type, the field and its offset.
class BeReader {
 public:
  BeReader(const uint8_t* data, size_t size, const char* type) : data_(data), size_(size), type_(type) {}
  size_t pos() const { return pos_; }
  size_t left() const { return size_ - pos_; }
  core::Status need(size_t n, const char* field) const;
  core::Status skip(size_t n, const char* field);
  core::Status i32(int32_t* v, const char* field);
  core::Status i64(int64_t* v, const char* field);
  // An LCM string: int32 length including the terminating NUL, then the bytes. Rejects a length < 1,
  // more than max_bytes (without the NUL), a missing terminating NUL and a NUL inside.
  core::Status string(size_t max_bytes, const char* field);
  core::Status check_fingerprint(int64_t expected);
  // Bytes left over after the last field.
  core::Status check_end() const;

 private:
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  const char* type_;
};

// kOutOfRange when a whole message is over max_bytes (or over LCM's int offsets); kInvalidArgument
// for a null buffer with a non-zero size.
core::Status check_message_size(const uint8_t* data, size_t size, size_t max_bytes, const char* type);

// LCM's generated decode() over bytes the reader has already walked: it must consume them all.
template <class Msg>
core::Status decode_walked(const uint8_t* data, size_t size, const char* type, Msg* out) {
  const int n = out->decode(data, 0, static_cast<int>(size));
  if (n != static_cast<int>(size)) {
    return core::ParseError(std::string(type) + ": LCM decode failed (returned " + std::to_string(n) +
                            " of " + std::to_string(size) + " bytes)");
  }
  return core::Status::Ok();
}

// LCM encoding into `out` (resized to the message; capacity kept). The caller has checked that the
// message's counts match its vectors (LCM's encode() reads as many elements as a count says).
template <class Msg>
core::Status encode_lcm(const Msg& msg, const char* type, std::vector<uint8_t>* out) {
  const int64_t size = msg.getEncodedSize();
  if (size <= 0 || size > std::numeric_limits<int>::max()) {
    return core::InvalidArgument(std::string(type) + ": cannot encode a message of " + std::to_string(size) +
                                 " bytes");
  }
  out->resize(static_cast<size_t>(size));
  const int n = msg.encode(out->data(), 0, static_cast<int>(size));
  if (n != size) {
    return core::Internal(std::string(type) + ": LCM encode wrote " + std::to_string(n) + " of " +
                          std::to_string(size) + " bytes");
  }
  return core::Status::Ok();
}

}  // namespace hwr::mapio::detail
