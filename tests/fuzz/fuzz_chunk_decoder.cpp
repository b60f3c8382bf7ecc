// libFuzzer target: arbitrary bytes into hwr::mapio::decode_chunk (issue #5 item 2: "a chunk claiming
// 10^9 points or with a corrupt payload is rejected with a clear error"). A crash, a sanitizer report
// or a broken invariant below is a finding.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "hwr/mapio/chunk_codec.hpp"

namespace {

// Whatever decode_chunk accepts must satisfy what it documents.
void check_invariants(const hwr::mapio::DecodedChunk& out, const hwr::mapio::ChunkDecodeLimits& limits) {
  if (out.points.empty() || out.points.size() > static_cast<size_t>(limits.max_points)) std::abort();
  if (!out.ids.empty() && out.ids.size() != out.points.size()) std::abort();
  if (!out.normals_xyz.empty() && out.normals_xyz.size() != 3 * out.points.size()) std::abort();
  for (const hwr::mapio::ChunkPoint& p : out.points) {
    if (!std::isfinite(p.x_m) || !std::isfinite(p.y_m) || !std::isfinite(p.z_m)) std::abort();
  }
  for (float v : out.normals_xyz) {
    if (!std::isfinite(v)) std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static hwr::mapio::DecodedChunk out;  // reused across inputs, as the ground station does
  // The default byte limit, a smaller point limit: Draco sizes its buffers from the claimed count,
  // and 2^20-point claims would spend the run in memset instead of in the decoder's branches. The
  // check that enforces either limit is the same code.
  hwr::mapio::ChunkDecodeLimits limits;
  limits.max_points = 1 << 16;
  const hwr::core::Status status = hwr::mapio::decode_chunk(data, size, /*expected_points=*/-1, limits, &out);
  if (status.ok()) {
    check_invariants(out, limits);
  } else if (status.message().empty()) {
    std::abort();  // every rejection must say why
  }
  return 0;
}
