// libFuzzer target: arbitrary bytes into hwr::hal::hw::A9Parser (issue #8), pushed in chunks whose
// sizes the input's first byte picks. The oracle is a second, whole-buffer implementation of the
// framing rules (hardware.md "Handsfree A9": AA 55 | LEN | INFO[4] | payload | CRC16) below: the
// streaming parser must emit exactly its frames, from exactly its stream positions, with the same
// counters, whatever the chunking. Each emitted frame's CRC is recomputed bit by bit. Any mismatch,
// crash or sanitizer report is a finding.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "hwr/hal/hw/a9_protocol.hpp"

namespace {

using hwr::hal::hw::A9AttitudePacket;
using hwr::hal::hw::A9ImuPacket;
using hwr::hal::hw::A9Packet;
using hwr::hal::hw::A9Parser;
using hwr::hal::hw::A9ParserCounters;

uint16_t crc_bitwise(const uint8_t* d, size_t n) {
  uint16_t crc = 0xFFFF;
  for (size_t i = 0; i < n; ++i) {
    crc ^= d[i];
    for (int b = 0; b < 8; ++b) crc = (crc & 1) != 0 ? static_cast<uint16_t>((crc >> 1) ^ 0xA001) : crc >> 1;
  }
  return crc;
}

float f32_at(const uint8_t* p) {
  float f;
  std::memcpy(&f, p, 4);  // the fuzz host is little-endian like the A9's payload
  return f;
}

struct RefFrame {
  size_t start = 0;
  size_t size = 0;
};

struct RefResult {
  std::vector<RefFrame> frames;
  uint64_t crc_errors = 0, unknown_length = 0, non_finite = 0, discarded = 0;
  size_t buffered = 0;
};

// The framing rules, written out over the whole buffer: on any failure drop one byte and look again;
// a candidate that runs past the end of the data waits (stays buffered).
RefResult reference_parse(const uint8_t* d, size_t n) {
  RefResult r;
  size_t i = 0;
  while (i < n) {
    if (d[i] != 0xAA) {
      ++r.discarded;
      ++i;
      continue;
    }
    if (i + 1 >= n) break;
    if (d[i + 1] != 0x55) {
      ++r.discarded;
      ++i;
      continue;
    }
    if (i + 2 >= n) break;
    const uint8_t len = d[i + 2];
    if (len != 0x2C && len != 0x14) {
      ++r.unknown_length;
      ++r.discarded;
      ++i;
      continue;
    }
    const size_t size = static_cast<size_t>(len) + 5;
    if (i + size > n) break;
    const uint16_t sent = static_cast<uint16_t>(d[i + size - 2] | (d[i + size - 1] << 8));
    if (crc_bitwise(d + i + 2, size - 4) != sent) {
      ++r.crc_errors;
      ++r.discarded;
      ++i;
      continue;
    }
    bool finite = true;
    for (size_t off = 11; off + 4 <= size - 2; off += 4)
      finite = finite && std::isfinite(f32_at(d + i + off));
    if (!finite) {
      ++r.non_finite;
      r.discarded += size;
      i += size;
      continue;
    }
    r.frames.push_back({i, size});
    i += size;
  }
  r.buffered = n - i;
  return r;
}

void check(bool ok) {
  if (!ok) std::abort();
}

bool vec_is(const Eigen::Vector3d& v, const uint8_t* p) {
  // Bit-exact: the parser widens float32 to double, nothing else.
  for (int k = 0; k < 3; ++k) {
    if (v[k] != static_cast<double>(f32_at(p + 4 * k))) return false;
  }
  return true;
}

void check_accounting(const A9Parser& p) {
  const A9ParserCounters& c = p.counters();
  check(c.frames_ok == c.imu_frames + c.attitude_frames);
  check(c.bytes_received ==
        c.imu_frames * 49 + c.attitude_frames * 25 + c.bytes_discarded + p.bytes_buffered());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  // First byte: the chunking (0 → everything in one push; else a small LCG of chunk sizes).
  uint32_t lcg = data[0];
  const bool one_push = data[0] == 0;
  const uint8_t* stream = data + 1;
  const size_t n = size - 1;

  const RefResult ref = reference_parse(stream, n);

  A9Parser parser;
  size_t emitted = 0;
  auto sink = [&](const A9Packet& packet) {
    // The frame just emitted ends where the parser's consumed bytes end.
    const size_t end = static_cast<size_t>(parser.counters().bytes_received) - parser.bytes_buffered();
    check(emitted < ref.frames.size());
    const RefFrame& want = ref.frames[emitted++];
    check(end == want.start + want.size);
    const uint8_t* f = stream + want.start;
    check(crc_bitwise(f + 2, want.size - 4) ==
          static_cast<uint16_t>(f[want.size - 2] | (f[want.size - 1] << 8)));
    check(hwr::hal::hw::a9_frame_crc_ok(f, want.size));
    uint32_t t;
    std::memcpy(&t, f + 7, 4);
    if (const auto* imu = std::get_if<A9ImuPacket>(&packet)) {
      check(want.size == 49 && imu->t_us == t);
      check(vec_is(imu->gyro_radps, f + 11) && vec_is(imu->accel_g, f + 23) && vec_is(imu->mag_raw, f + 35));
      const hwr::hal::ImuSample s = hwr::hal::hw::to_imu_sample(*imu, 0);
      check(s.accel_mps2.allFinite() && s.gyro_radps.allFinite());
    } else {
      const auto& att = std::get<A9AttitudePacket>(packet);
      check(want.size == 25 && att.t_us == t && vec_is(att.rpy_deg, f + 11));
    }
  };
  size_t pos = 0;
  while (pos < n) {
    size_t chunk = n - pos;
    if (!one_push) {
      lcg = lcg * 1103515245u + 12345u;
      chunk = std::min<size_t>(chunk, 1 + (lcg >> 16) % 97);
    }
    parser.push(stream + pos, chunk, sink);
    pos += chunk;
    check_accounting(parser);
  }
  const A9ParserCounters& c = parser.counters();
  check(emitted == ref.frames.size());
  check(c.frames_ok == ref.frames.size());
  check(c.crc_errors == ref.crc_errors && c.unknown_length == ref.unknown_length &&
        c.non_finite == ref.non_finite);
  check(c.bytes_discarded == ref.discarded && parser.bytes_buffered() == ref.buffered);

  // The unwrapper on the emitted stamps' raw words: its steps must equal the modular differences.
  hwr::hal::hw::A9TimestampUnwrapper unwrap;
  int64_t last = 0;
  uint32_t last_raw = 0;
  for (size_t k = 0; k < ref.frames.size(); ++k) {
    uint32_t t;
    std::memcpy(&t, stream + ref.frames[k].start + 7, 4);
    const int64_t u = unwrap.unwrap_us(t);
    if (k > 0) check(static_cast<uint32_t>(u - last) == t - last_raw);
    check(static_cast<uint32_t>(u) == t);
    last = u;
    last_raw = t;
  }
  return 0;
}
