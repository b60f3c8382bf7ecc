#include "hwr/hal/hw/crc16_modbus.hpp"

#include <array>

namespace hwr::hal::hw {
namespace {

// Byte-wise table of the reflected algorithm: entry b is the register after shifting b through
// eight rounds of "crc = (crc >> 1) ^ (crc & 1 ? 0xA001 : 0)".
constexpr std::array<uint16_t, 256> make_table() {
  std::array<uint16_t, 256> table{};
  for (uint32_t b = 0; b < 256; ++b) {
    uint16_t crc = static_cast<uint16_t>(b);
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 1u) != 0 ? static_cast<uint16_t>((crc >> 1) ^ 0xA001u) : static_cast<uint16_t>(crc >> 1);
    }
    table[b] = crc;
  }
  return table;
}

constexpr std::array<uint16_t, 256> kTable = make_table();

}  // namespace

uint16_t crc16_modbus_update(uint16_t crc, const uint8_t* data, size_t size) {
  for (size_t i = 0; i < size; ++i) {
    crc = static_cast<uint16_t>((crc >> 8) ^ kTable[(crc ^ data[i]) & 0xFFu]);
  }
  return crc;
}

uint16_t crc16_modbus(const uint8_t* data, size_t size) {
  return crc16_modbus_update(kCrc16ModbusInit, data, size);
}

}  // namespace hwr::hal::hw
