// Writes a seed corpus for fuzz_zed_sensor_report into the folder given as the only argument: single
// reports (plain; frame sync with a new magnetometer reading; "not valid" temperatures; the IMU
// flagged not valid; a 64-byte transfer with padding; full-scale counts) and report streams for the
// monitor (400 Hz with sync events, a gap, a repeat, a clock restart). Generated at test time.

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "corpus_dir.hpp"

namespace {

using Bytes = std::vector<uint8_t>;

bool write(const std::string& path, const Bytes& bytes) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) return false;
  const bool ok = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  return std::fclose(f) == 0 && ok;
}

void put(Bytes* b, size_t off, uint64_t v, int n) {
  for (int i = 0; i < n; ++i) (*b)[off + static_cast<size_t>(i)] = static_cast<uint8_t>(v >> (8 * i));
}

// One 62-byte report at hardware.md's offsets.
Bytes report(uint64_t tick, bool sync, uint32_t count, uint8_t mag_valid, int16_t temp) {
  Bytes b(62, 0);
  b[0] = 0x01;
  put(&b, 2, tick, 8);
  put(&b, 10, static_cast<uint16_t>(int16_t{-120}), 2);  // gyro
  put(&b, 14, 33, 2);
  put(&b, 20, 4096, 2);  // accel z = 1 g
  b[22] = sync ? 1 : 0;
  b[23] = 1;
  put(&b, 24, count, 4);
  put(&b, 28, static_cast<uint16_t>(temp), 2);
  b[30] = mag_valid;
  put(&b, 31, 400, 2);  // 25 µT
  put(&b, 35, static_cast<uint16_t>(int16_t{-700}), 2);
  b[47] = 2;
  put(&b, 48, static_cast<uint16_t>(temp), 2);
  put(&b, 50, 10'132'500, 4);
  put(&b, 54, 4500, 4);
  put(&b, 58, 3900, 2);
  put(&b, 60, 3950, 2);
  return b;
}

void append(Bytes* stream, const Bytes& r) { stream->insert(stream->end(), r.begin(), r.end()); }

}  // namespace

int main(int argc, char** argv) {
  std::string dir;
  if (int rc = hwr::fuzz::corpus_dir_from_args(argc, argv, &dir); rc != 0) return rc;
  bool ok = write(dir + "/plain", report(25'600, false, 7, 0, 2512));
  ok = write(dir + "/sync_mag_new", report(25'664, true, 8, 2, 2513)) && ok;
  ok = write(dir + "/temps_not_valid", report(25'728, false, 8, 1, -27315)) && ok;
  Bytes stale = report(25'792, false, 8, 0, 2514);
  stale[1] = 1;
  ok = write(dir + "/imu_not_valid", stale) && ok;
  Bytes padded = report(25'856, false, 8, 0, 2514);
  padded.push_back(0xEE);
  padded.push_back(0xEE);
  ok = write(dir + "/transfer_64", padded) && ok;
  Bytes extreme = report(UINT64_MAX, true, UINT32_MAX, 255, -32768);
  for (size_t off : {10u, 12u, 14u, 16u, 18u, 20u}) put(&extreme, off, 0x8000, 2);
  ok = write(dir + "/full_scale", extreme) && ok;

  Bytes stream;
  uint32_t count = 100;
  for (uint64_t i = 0; i < 40; ++i) {
    const bool sync = i % 13 == 0;
    count += sync ? 1 : 0;
    if (i == 20) continue;  // a lost report: a gap
    append(&stream, report(1'000'000 + 64 * i, sync, count, i % 8 == 0 ? 2 : 1, 2500));
    if (i == 30) append(&stream, report(1'000'000 + 64 * i, sync, count, 1, 2500));  // a repeat
  }
  append(&stream, report(64, false, 0, 0, 2500));  // the MCU restarted
  ok = write(dir + "/stream", stream) && ok;
  if (!ok) {
    std::fprintf(stderr, "make_zed_report_seeds: cannot write into %s\n", dir.c_str());
    return 1;
  }
  return 0;
}
