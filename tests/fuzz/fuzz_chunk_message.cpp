// libFuzzer target: arbitrary bytes as a received HWR_MAP_CHUNK message, through what the ground
// station runs before it trusts a chunk: decode_chunk_message (LCM decoding with every length field
// bounded first) and verify_chunk (sizes, ids, pose, CRC32). A crash, a sanitizer report, an
// allocation over the limits (-rss_limit_mb / -malloc_limit_mb) or a broken invariant is a finding.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "hwr/mapio/chunk_wire.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static hwr_lcm::map_chunk_t chunk;  // reused across inputs, as the receiver does
  static std::vector<uint8_t> again;
  const hwr::mapio::ChunkWireLimits limits;
  const hwr::core::Status decoded = hwr::mapio::decode_chunk_message(data, size, &chunk, limits);
  if (!decoded.ok()) {
    if (decoded.message().empty()) std::abort();  // every rejection says why
    return 0;
  }
  // decode is strict (no trailing bytes, no NUL inside robot_id): encoding gives the input back.
  if (!hwr::mapio::encode_chunk_message(chunk, &again).ok()) std::abort();
  if (again.size() != size || std::memcmp(again.data(), data, size) != 0) std::abort();
  if (chunk.payload.size() > limits.max_payload_bytes) std::abort();

  const hwr::core::Status verified = hwr::mapio::verify_chunk(chunk, limits);
  if (verified.ok()) {
    if (chunk.crc32 != static_cast<int64_t>(hwr::mapio::chunk_crc32(chunk))) std::abort();
    if (chunk.num_points < 1 || chunk.num_points > limits.max_points || chunk.payload.empty()) std::abort();
  } else if (verified.message().empty()) {
    std::abort();
  }
  return 0;
}
