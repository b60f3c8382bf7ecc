#include "hwr/hal/hw/a9_protocol.hpp"

#include <cmath>
#include <cstring>

#include "hwr/hal/hw/crc16_modbus.hpp"

namespace hwr::hal::hw {
namespace {

uint32_t read_u32_le(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}

float read_f32_le(const uint8_t* p) {
  const uint32_t bits = read_u32_le(p);
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

Eigen::Vector3d read_vec3_f32(const uint8_t* frame, size_t offset) {
  return {read_f32_le(frame + offset), read_f32_le(frame + offset + 4), read_f32_le(frame + offset + 8)};
}

// Byte offsets from the first sync byte (hardware.md "Handsfree A9").
constexpr size_t kOffLen = 2;
constexpr size_t kOffTimestamp = 7;
constexpr size_t kOffGyro = 11;
constexpr size_t kOffAccel = 23;
constexpr size_t kOffMag = 35;
constexpr size_t kOffRpy = 11;

bool is_known_len(uint8_t len) { return len == kA9LenImu || len == kA9LenAttitude; }

bool all_finite(const A9Packet& p) {
  if (const auto* imu = std::get_if<A9ImuPacket>(&p)) {
    return imu->gyro_radps.allFinite() && imu->accel_g.allFinite() && imu->mag_raw.allFinite();
  }
  return std::get<A9AttitudePacket>(p).rpy_deg.allFinite();
}

}  // namespace

bool a9_frame_crc_ok(const uint8_t* frame, size_t size) {
  if (size < kA9FrameOverhead || size != static_cast<size_t>(frame[kOffLen]) + kA9FrameOverhead) return false;
  // CRC over LEN, INFO and payload: bytes [2, size − 2); sent low byte first.
  const uint16_t crc = crc16_modbus(frame + kOffLen, size - 4);
  const uint16_t sent = static_cast<uint16_t>(frame[size - 2] | (frame[size - 1] << 8));
  return crc == sent;
}

bool decode_a9_frame(const uint8_t* frame, size_t size, A9Packet* out) {
  if (size < kA9FrameOverhead || frame[0] != kA9Sync0 || frame[1] != kA9Sync1) return false;
  const uint8_t len = frame[kOffLen];
  if (!is_known_len(len) || size != static_cast<size_t>(len) + kA9FrameOverhead) return false;
  const uint32_t t_us = read_u32_le(frame + kOffTimestamp);
  if (len == kA9LenImu) {
    A9ImuPacket imu;
    imu.t_us = t_us;
    imu.gyro_radps = read_vec3_f32(frame, kOffGyro);
    imu.accel_g = read_vec3_f32(frame, kOffAccel);
    imu.mag_raw = read_vec3_f32(frame, kOffMag);
    *out = imu;
  } else {
    A9AttitudePacket att;
    att.t_us = t_us;
    att.rpy_deg = read_vec3_f32(frame, kOffRpy);
    *out = att;
  }
  return true;
}

size_t A9Parser::append(const uint8_t* bytes, size_t n) {
  if (head_ > 0) {
    // Keep the unparsed bytes at the front: at most one partial frame (< kA9MaxFrameSize) is left
    // after extract() returned false, so the room behind it is always > 0.
    const size_t kept = tail_ - head_;
    std::memmove(buf_.data(), buf_.data() + head_, kept);
    head_ = 0;
    tail_ = kept;
  }
  const size_t room = kBufferSize - tail_;
  const size_t used = n < room ? n : room;
  std::memcpy(buf_.data() + tail_, bytes, used);
  tail_ += used;
  counters_.bytes_received += used;
  return used;
}

void A9Parser::discard(size_t n) {
  head_ += n;
  counters_.bytes_discarded += n;
}

bool A9Parser::extract(A9Packet* out) {
  while (head_ < tail_) {
    const uint8_t* p = buf_.data() + head_;
    const size_t avail = tail_ - head_;
    if (p[0] != kA9Sync0) {
      // Skip to the next possible first sync byte.
      const void* next = std::memchr(p + 1, kA9Sync0, avail - 1);
      discard(next != nullptr ? static_cast<size_t>(static_cast<const uint8_t*>(next) - p) : avail);
      continue;
    }
    if (avail < 2) return false;
    if (p[1] != kA9Sync1) {
      discard(1);
      continue;
    }
    if (avail < 3) return false;
    const uint8_t len = p[kOffLen];
    if (!is_known_len(len)) {
      ++counters_.unknown_length;
      discard(1);  // resync from the byte after AA
      continue;
    }
    const size_t frame_size = static_cast<size_t>(len) + kA9FrameOverhead;
    if (avail < frame_size) return false;
    if (!a9_frame_crc_ok(p, frame_size)) {
      ++counters_.crc_errors;
      discard(1);  // a valid frame may start inside this one
      continue;
    }
    decode_a9_frame(p, frame_size, out);  // cannot fail: sync, LEN and size checked above
    if (!all_finite(*out)) {
      ++counters_.non_finite;
      discard(frame_size);  // the CRC vouches for the frame's extent: skip all of it
      continue;
    }
    head_ += frame_size;
    ++counters_.frames_ok;
    if (len == kA9LenImu) {
      ++counters_.imu_frames;
    } else {
      ++counters_.attitude_frames;
    }
    return true;
  }
  head_ = tail_ = 0;
  return false;
}

void A9Parser::reset() {
  counters_.bytes_discarded += tail_ - head_;
  head_ = tail_ = 0;
}

hal::ImuSample to_imu_sample(const A9ImuPacket& packet, int64_t t_ns) {
  // R_x(π): A9 x-forward/y-right/z-down → x-forward/y-left/z-up (see the header for the evidence).
  const Eigen::Vector3d flip(1.0, -1.0, -1.0);
  hal::ImuSample s;
  s.t_ns = t_ns;
  s.gyro_radps = packet.gyro_radps.cwiseProduct(flip);
  s.accel_mps2 = packet.accel_g.cwiseProduct(flip) * kA9StandardGravityMps2;
  return s;
}

int64_t A9TimestampUnwrapper::unwrap_us(uint32_t t_us) {
  if (!started_) {
    started_ = true;
    last_raw_ = t_us;
    last_us_ = static_cast<int64_t>(t_us);
    return last_us_;
  }
  // Difference modulo 2^32, read as signed: a wrap is a small positive step.
  const uint32_t diff_mod = t_us - last_raw_;
  const int64_t step = diff_mod < 0x80000000u ? static_cast<int64_t>(diff_mod)
                                              : static_cast<int64_t>(diff_mod) - (int64_t{1} << 32);
  if (step > 0 && t_us < last_raw_) ++wraps_;
  if (step < 0) ++backward_steps_;
  last_raw_ = t_us;
  last_us_ += step;
  return last_us_;
}

}  // namespace hwr::hal::hw
