#pragma once
// Handsfree A9 IMU serial protocol (USB serial, 921600 8N1, ~150 Hz; hardware.md "Handsfree A9"):
//
//   AA 55 | LEN | INFO[4] | payload | CRC16          (LEN + 5 bytes in all)
//
// CRC-16/MODBUS over LEN, INFO and payload, sent low byte first. The payload is a u32 LE timestamp
// in µs followed by float32 LE values. Two frame types exist:
//   LEN 0x2C (49 bytes): gyro xyz rad/s @11/15/19, accel xyz in g @23/27/31, magnetometer xyz @35/39/43
//   LEN 0x14 (25 bytes): roll, pitch, yaw in degrees @11/15/19 (yaw 0 = x axis to magnetic north)
// (offsets from the first sync byte). A9Parser turns whatever a serial read() returned into these
// packets, without allocating, and counts every byte it could not use.

#include <array>
#include <cstddef>
#include <cstdint>
#include <variant>

#include <Eigen/Core>

#include "hwr/hal/imu_sample.hpp"

namespace hwr::hal::hw {

inline constexpr uint8_t kA9Sync0 = 0xAA;
inline constexpr uint8_t kA9Sync1 = 0x55;
inline constexpr uint8_t kA9LenImu = 0x2C;
inline constexpr uint8_t kA9LenAttitude = 0x14;
inline constexpr size_t kA9FrameOverhead = 5;  // sync (2) + CRC (2) + the LEN byte itself
inline constexpr size_t kA9ImuFrameSize = kA9LenImu + kA9FrameOverhead;            // 49
inline constexpr size_t kA9AttitudeFrameSize = kA9LenAttitude + kA9FrameOverhead;  // 25
inline constexpr size_t kA9MaxFrameSize = kA9ImuFrameSize;

// LEN 0x2C. Axes are the A9's own body axes, values as sent (see to_imu_sample for the frame).
struct A9ImuPacket {
  uint32_t t_us = 0;  // device clock; wraps every 2^32 µs (~71.6 min): A9TimestampUnwrapper
  Eigen::Vector3d gyro_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_g = Eigen::Vector3d::Zero();  // z ≈ −1 g at rest, level (hardware.md)
  // Magnetometer as sent. hardware.md marks the unit "Gauss?" (unverified): kept raw, not converted
  // to µT, until a measurement against a known field settles it.
  Eigen::Vector3d mag_raw = Eigen::Vector3d::Zero();
};

// LEN 0x14: the A9's own attitude estimate.
struct A9AttitudePacket {
  uint32_t t_us = 0;
  Eigen::Vector3d rpy_deg = Eigen::Vector3d::Zero();  // roll, pitch, yaw; yaw 0 = x to magnetic north
};

using A9Packet = std::variant<A9ImuPacket, A9AttitudePacket>;

// What the parser saw. Every byte pushed is either in an emitted frame, counted in bytes_discarded,
// or still buffered: bytes_received == imu_frames * 49 + attitude_frames * 25 + bytes_discarded +
// A9Parser::bytes_buffered().
struct A9ParserCounters {
  uint64_t bytes_received = 0;
  uint64_t frames_ok = 0;        // emitted: imu_frames + attitude_frames
  uint64_t imu_frames = 0;       // LEN 0x2C emitted
  uint64_t attitude_frames = 0;  // LEN 0x14 emitted
  uint64_t crc_errors = 0;       // complete candidate frame whose CRC did not match
  uint64_t unknown_length = 0;   // AA 55 followed by a LEN other than 0x2C / 0x14
  uint64_t non_finite = 0;       // CRC good but a NaN/inf value: dropped (bytes counted as discarded)
  uint64_t bytes_discarded = 0;  // noise, failed syncs, non-finite frames
};

// Streaming frame parser. Resynchronisation: after a CRC error or an unknown LEN only the first
// sync byte is dropped and the search for the next AA 55 starts at the byte after it, over the bytes
// already buffered, so a valid frame hidden inside a corrupted one is still found.
// Not thread-safe: one reader thread owns it.
class A9Parser {
 public:
  A9Parser() = default;

  // Feeds n bytes (any split: a frame may arrive across many calls) and calls sink(const A9Packet&)
  // once per frame completed by them, in stream order. The packet reference is valid during the call.
  template <class Sink>
  void push(const uint8_t* bytes, size_t n, Sink&& sink) {
    A9Packet packet;
    while (n > 0) {
      const size_t used = append(bytes, n);
      bytes += used;
      n -= used;
      while (extract(&packet)) sink(static_cast<const A9Packet&>(packet));
    }
  }

  const A9ParserCounters& counters() const { return counters_; }
  size_t bytes_buffered() const { return tail_ - head_; }
  // Drops buffered bytes (counted as discarded), e.g. after the port was reopened.
  void reset();

 private:
  // Copies as many bytes as fit behind the buffered ones; returns how many.
  size_t append(const uint8_t* bytes, size_t n);
  // Takes the next complete valid frame off the buffer; false when more bytes are needed.
  bool extract(A9Packet* out);
  void discard(size_t n);

  // Room for one longest frame plus a read's worth, so push() rarely loops.
  static constexpr size_t kBufferSize = 512;
  std::array<uint8_t, kBufferSize> buf_{};
  size_t head_ = 0;  // first unparsed byte
  size_t tail_ = 0;  // one past the last buffered byte
  A9ParserCounters counters_;
};

// Decodes one complete frame of exactly LEN + 5 bytes. Checks sync, LEN and size, not the CRC
// (a9_frame_crc_ok does); false when the bytes are not an A9 frame of a known type. A9Parser uses it.
bool decode_a9_frame(const uint8_t* frame, size_t size, A9Packet* out);

// True when the frame's last two bytes are the CRC-16/MODBUS of its LEN, INFO and payload.
bool a9_frame_crc_ok(const uint8_t* frame, size_t size);

// Standard gravity (CGPM 1901), the g the A9 reports in. The vendor's ROS driver uses 9.8.
inline constexpr double kA9StandardGravityMps2 = 9.80665;

// The A9 body frame as hal::ImuSample. hardware.md: accel z ≈ −1 g at rest, level, while ImuSample
// wants specific force +9.81 on a z-up axis, so the A9's raw accel cannot be used as is.
// Chosen convention: the A9 is an AHRS that reports attitude the aviation way (yaw 0 = x to magnetic
// north, hardware.md; the vendor's ROS node, HANDS-FREE/handsfree_ros_imu scripts/hfi_a9_ros.py,
// turns its angles into a ROS quaternion as (roll, −pitch, −yaw), which is exactly the change from
// x-forward/y-right/z-down to x-forward/y-left/z-up), so its body frame is taken as FRD and its accel
// as specific force in that frame: −1 g on z-down at rest, as observed. FRD → FLU is the proper
// rotation R_x(π): (x, y, z) → (x, −y, −z), applied to gyro AND accel alike (a rotation, not a
// mirror, so the two stay consistent): accel_mps2 = R_x(π) · accel_g · 9.80665,
// gyro_radps = R_x(π) · gyro.
// The vendor node differs: it multiplies all three accel axes by −9.8 and passes the gyro through
// unchanged. That matches the other reading, an FLU frame whose accel is the gravity vector (−specific
// force); both readings give +9.81 on z at rest and differ in the sign of accel x and gyro y/z.
// Unverified on hardware; check once on the robot: nose pitched down → accel_mps2.x < 0 (gravity
// has a forward component, specific force points back/up); turning left (counter-clockwise seen from
// above) → gyro_radps.z > 0. If the A9 turns out to follow the vendor node's reading, the fix is here
// alone: negate accel, keep gyro.
hal::ImuSample to_imu_sample(const A9ImuPacket& packet, int64_t t_ns);

// The A9's u32 µs clock as a 64-bit µs timeline. Consecutive stamps are compared modulo 2^32 and
// the signed difference is added, so a wrap (~ every 71.6 min) continues the timeline forwards. A
// step backwards (device reset, reordered data) is passed through as a smaller value and counted,
// so the stream monitor downstream rejects it; a gap longer than 2^31 µs (~35.8 min) between two
// stamps cannot be told from a step backwards.
class A9TimestampUnwrapper {
 public:
  // The first stamp maps to itself (0 ≤ t < 2^32); later ones continue from it.
  int64_t unwrap_us(uint32_t t_us);
  uint64_t wraps() const { return wraps_; }
  uint64_t backward_steps() const { return backward_steps_; }
  void reset() { started_ = false; }

 private:
  bool started_ = false;
  uint32_t last_raw_ = 0;
  int64_t last_us_ = 0;
  uint64_t wraps_ = 0;
  uint64_t backward_steps_ = 0;
};

}  // namespace hwr::hal::hw
