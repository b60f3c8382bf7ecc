#pragma once
// Hand-built Handsfree A9 frames for the hal_hw tests (hardware.md: AA 55 | LEN | INFO[4] | u32 µs |
// float32 values | CRC-16/MODBUS low byte first), sealed with a bitwise CRC written from the
// definition, independent of crc16_modbus's table.
#include <cstdint>
#include <cstring>
#include <vector>

#include <Eigen/Core>

namespace hwr::hal::hw::test {

using Bytes = std::vector<uint8_t>;

inline uint16_t crc16_bitwise(const uint8_t* d, size_t n) {
  uint16_t crc = 0xFFFF;
  for (size_t i = 0; i < n; ++i) {
    crc ^= d[i];
    for (int b = 0; b < 8; ++b) crc = (crc & 1) != 0 ? static_cast<uint16_t>((crc >> 1) ^ 0xA001) : crc >> 1;
  }
  return crc;
}

inline void put_u32(Bytes* b, uint32_t v) {
  for (int i = 0; i < 4; ++i) b->push_back(static_cast<uint8_t>(v >> (8 * i)));
}
inline void put_f32(Bytes* b, float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  put_u32(b, u);
}
// Appends the CRC over LEN, INFO and payload.
inline void seal(Bytes* f) {
  const uint16_t crc = crc16_bitwise(f->data() + 2, f->size() - 2);
  f->push_back(static_cast<uint8_t>(crc & 0xFF));
  f->push_back(static_cast<uint8_t>(crc >> 8));
}

// LEN 0x2C: gyro (rad/s), accel (g), magnetometer.
inline Bytes make_a9_imu_frame(uint32_t t_us, const Eigen::Vector3f& gyro, const Eigen::Vector3f& accel,
                               const Eigen::Vector3f& mag) {
  Bytes f = {0xAA, 0x55, 0x2C, 0x29, 0xEC, 0x41, 0x00};
  put_u32(&f, t_us);
  for (const Eigen::Vector3f* v : {&gyro, &accel, &mag})
    for (int i = 0; i < 3; ++i) put_f32(&f, (*v)[i]);
  seal(&f);
  return f;
}

// LEN 0x14: roll, pitch, yaw in degrees.
inline Bytes make_a9_attitude_frame(uint32_t t_us, const Eigen::Vector3f& rpy) {
  Bytes f = {0xAA, 0x55, 0x14, 0x23, 0xE0, 0x48, 0x00};
  put_u32(&f, t_us);
  for (int i = 0; i < 3; ++i) put_f32(&f, rpy[i]);
  seal(&f);
  return f;
}

}  // namespace hwr::hal::hw::test
