// Writes a seed corpus for fuzz_a9_parser into the folder given as the only argument: the vendor
// sheet's two frames (hardware.md), frames built with crc16_modbus, and streams mixing them with
// noise, truncations and a corrupted CRC, so the fuzzer starts past the CRC check. The first byte
// of each seed is the harness's chunking selector. Generated at test time; never committed.

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "corpus_dir.hpp"
#include "hwr/hal/hw/crc16_modbus.hpp"

namespace {

using Bytes = std::vector<uint8_t>;

Bytes from_hex(const char* hex) {
  Bytes out;
  for (size_t i = 0; hex[i] != 0 && hex[i + 1] != 0; i += 2) {
    out.push_back(static_cast<uint8_t>(std::stoi(std::string(hex + i, 2), nullptr, 16)));
  }
  return out;
}

Bytes make_frame(uint8_t len, uint32_t t_us, const std::vector<float>& values) {
  Bytes f = {0xAA, 0x55, len, 0x29, 0xEC, 0x41, 0x00};
  for (int i = 0; i < 4; ++i) f.push_back(static_cast<uint8_t>(t_us >> (8 * i)));
  for (float v : values) {
    uint8_t b[4];
    std::memcpy(b, &v, 4);
    f.insert(f.end(), b, b + 4);
  }
  const uint16_t crc = hwr::hal::hw::crc16_modbus(f.data() + 2, f.size() - 2);
  f.push_back(static_cast<uint8_t>(crc & 0xFF));
  f.push_back(static_cast<uint8_t>(crc >> 8));
  return f;
}

}  // namespace

int main(int argc, char** argv) {
  std::string dir;
  if (const int rc = hwr::fuzz::corpus_dir_from_args(argc, argv, &dir); rc != 0) return rc;
  const Bytes imu = from_hex(
      "aa552c29ec41004029706b9d66383a508faab9da33c0b9a6e74d3c0267b9bb030480bf25bfac3d4fd40fbdcd4c4a3f5dfb");
  const Bytes att = from_hex("aa551423e04800ac9a1e83839a1c3f6b100341568d29c1170e");
  const Bytes built_imu =
      make_frame(0x2C, 0xFFFFFF00u, {0.1f, -0.2f, 0.3f, 0.01f, 0.02f, -1.0f, 0.2f, 0.1f, 0.4f});
  const Bytes built_att = make_frame(0x14, 0x00000100u, {1.5f, -2.0f, 170.0f});
  Bytes bad_crc = imu;
  bad_crc[30] ^= 0x10;
  const Bytes noise = {0x00, 0xAA, 0x12, 0xAA, 0x55, 0x99, 0x55, 0xAA, 0xAA};

  std::vector<Bytes> seeds;
  auto seed = [&](uint8_t chunking, std::initializer_list<Bytes> parts) {
    Bytes s = {chunking};
    for (const Bytes& p : parts) s.insert(s.end(), p.begin(), p.end());
    seeds.push_back(s);
  };
  seed(0, {imu});
  seed(0, {att});
  seed(1, {imu, att, built_imu, built_att});
  seed(7, {noise, imu, noise, att, noise});
  seed(3, {bad_crc, att, imu});
  seed(0, {Bytes(imu.begin(), imu.begin() + 9), att, built_imu});  // a frame hidden inside a bad one
  seed(5, {built_att, built_imu, built_att, Bytes(imu.begin(), imu.begin() + 30)});
  int written = 0;
  for (const Bytes& s : seeds) {
    const std::string path = dir + "/seed_a9_" + std::to_string(written) + ".bin";
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (f == nullptr || std::fwrite(s.data(), 1, s.size(), f) != s.size() || std::fclose(f) != 0) {
      std::fprintf(stderr, "cannot write %s\n", path.c_str());
      return 1;
    }
    ++written;
  }
  std::printf("wrote %d A9 seed streams to %s\n", written, dir.c_str());
  return 0;
}
