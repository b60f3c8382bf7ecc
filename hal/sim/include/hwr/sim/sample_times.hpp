#pragma once
// Sample instants of a simulated sensor. Every stream starts at the run start (offset 0) and
// samples at k / rate_hz, rounded to whole microseconds: TUM's text files carry 6 decimals, so a
// camera time written to rgb.txt reads back exactly as the time it was rendered at.

#include <cmath>
#include <cstdint>
#include <vector>

namespace hwr::sim {

constexpr int64_t kSampleQuantumNs = 1000;

// Offsets from the run start in nanoseconds: k = 0, 1, ... while the offset <= duration_s.
inline std::vector<int64_t> sample_offsets_ns(double rate_hz, double duration_s) {
  std::vector<int64_t> out;
  if (!(rate_hz > 0.0) || !(duration_s >= 0.0)) return out;
  const double limit_ns = duration_s * 1e9 + 0.5;
  out.reserve(static_cast<size_t>(duration_s * rate_hz) + 2);
  for (int64_t k = 0;; ++k) {
    const double t = static_cast<double>(k) * 1e9 / rate_hz;
    const int64_t q = static_cast<int64_t>(std::llround(t / kSampleQuantumNs)) * kSampleQuantumNs;
    if (static_cast<double>(q) > limit_ns) break;
    out.push_back(q);
  }
  return out;
}

}  // namespace hwr::sim
