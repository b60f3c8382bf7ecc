#pragma once
// Binary ORB descriptors (Rublee et al., ICCV 2011): 256 intensity tests = 32 bytes, compared by
// Hamming distance. Header-only: the matchers call it in their inner loops.

#include <cstdint>
#include <cstring>

namespace hwr::estimation {

constexpr int kOrbDescriptorBytes = 32;
constexpr int kOrbDescriptorBits = 8 * kOrbDescriptorBytes;

namespace detail {
inline int popcount64(uint64_t x) {
#if defined(__GNUC__) && (defined(__POPCNT__) || defined(__aarch64__))
  return __builtin_popcountll(x);
#else
  // SWAR popcount (without the popcnt instruction GCC's builtin calls a libgcc table routine).
  x -= (x >> 1) & 0x5555555555555555ULL;
  x = (x & 0x3333333333333333ULL) + ((x >> 2) & 0x3333333333333333ULL);
  x = (x + (x >> 4)) & 0x0f0f0f0f0f0f0f0fULL;
  return static_cast<int>((x * 0x0101010101010101ULL) >> 56);
#endif
}
}  // namespace detail

// Number of differing bits of two 256-bit descriptors (0..256). Unaligned pointers are fine.
inline int hamming_distance(const uint8_t* a, const uint8_t* b) {
  int d = 0;
  for (int k = 0; k < kOrbDescriptorBytes; k += 8) {
    uint64_t x, y;
    std::memcpy(&x, a + k, 8);
    std::memcpy(&y, b + k, 8);
    d += detail::popcount64(x ^ y);
  }
  return d;
}

}  // namespace hwr::estimation
