#pragma once
// CRC-16/MODBUS: init 0xFFFF, reflected polynomial 0xA001 (0x8005 reversed), no final XOR. The
// Handsfree A9 protects each frame with it (hardware.md, "Handsfree A9": over LEN, INFO and payload,
// sent low byte first). Check value: crc16_modbus("123456789") == 0x4B37.

#include <cstddef>
#include <cstdint>

namespace hwr::hal::hw {

inline constexpr uint16_t kCrc16ModbusInit = 0xFFFF;

// CRC of data[0, size). size == 0 gives the init value.
uint16_t crc16_modbus(const uint8_t* data, size_t size);

// Continues a CRC over more bytes: crc16_modbus_update(crc16_modbus(a, n), b, m) is the CRC of a
// followed by b.
uint16_t crc16_modbus_update(uint16_t crc, const uint8_t* data, size_t size);

}  // namespace hwr::hal::hw
