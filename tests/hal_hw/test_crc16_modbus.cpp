// CRC-16/MODBUS (hal/hw/crc16_modbus.hpp): the catalogue check value, the A9 vendor frame's CRC
// (hardware.md), and agreement with a bit-at-a-time implementation of the definition.
#include "hwr/hal/hw/crc16_modbus.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace hwr::hal::hw {
namespace {

// The definition, one bit at a time: init 0xFFFF, reflected poly 0xA001, no final XOR.
uint16_t crc16_bitwise(const uint8_t* data, size_t size) {
  uint16_t crc = 0xFFFF;
  for (size_t i = 0; i < size; ++i) {
    crc ^= data[i];
    for (int b = 0; b < 8; ++b) crc = (crc & 1) != 0 ? static_cast<uint16_t>((crc >> 1) ^ 0xA001) : crc >> 1;
  }
  return crc;
}

std::vector<uint8_t> from_hex(const std::string& hex) {
  std::vector<uint8_t> out;
  for (size_t i = 0; i + 1 < hex.size(); i += 2)
    out.push_back(static_cast<uint8_t>(std::stoi(hex.substr(i, 2), nullptr, 16)));
  return out;
}

TEST(Crc16Modbus, GivenCatalogueCheckString_WhenCrc_Then0x4B37) {
  const std::string s = "123456789";
  EXPECT_EQ(crc16_modbus(reinterpret_cast<const uint8_t*>(s.data()), s.size()), 0x4B37);
}

TEST(Crc16Modbus, GivenNoBytes_WhenCrc_ThenInitValue) { EXPECT_EQ(crc16_modbus(nullptr, 0), 0xFFFF); }

TEST(Crc16Modbus, GivenA9VendorImuFrame_WhenCrcOverLenInfoPayload_Then0xFB5DSentLowByteFirst) {
  // hardware.md: the 49-byte LEN 0x2C frame, CRC 0xFB5D, on the wire as 5D FB.
  const auto f = from_hex(
      "aa552c29ec41004029706b9d66383a508faab9da33c0b9a6e74d3c0267b9bb030480bf25bfac3d4fd40fbdcd4c4a3f5dfb");
  ASSERT_EQ(f.size(), 49u);
  EXPECT_EQ(crc16_modbus(f.data() + 2, 45), 0xFB5D);
  EXPECT_EQ(f[47], 0x5D);
  EXPECT_EQ(f[48], 0xFB);
  // Appending the CRC low byte first gives residue 0 (a property of reflected CRCs without final XOR).
  EXPECT_EQ(crc16_modbus(f.data() + 2, 47), 0x0000);
}

TEST(Crc16Modbus, GivenRandomBuffers_WhenCrc_ThenEqualsBitwiseDefinitionAndUpdateChains) {
  std::mt19937 rng(42);
  std::uniform_int_distribution<int> byte(0, 255);
  for (size_t n : {1u, 2u, 7u, 64u, 255u, 1000u}) {
    std::vector<uint8_t> d(n);
    for (auto& b : d) b = static_cast<uint8_t>(byte(rng));
    const uint16_t whole = crc16_modbus(d.data(), n);
    EXPECT_EQ(whole, crc16_bitwise(d.data(), n)) << "n=" << n;
    for (size_t split = 0; split <= n; split += (n / 5 + 1)) {
      EXPECT_EQ(crc16_modbus_update(crc16_modbus(d.data(), split), d.data() + split, n - split), whole);
    }
  }
}

}  // namespace
}  // namespace hwr::hal::hw
