#pragma once
// Private to estimation: the batched Hamming loops (hamming_kernel.hpp), written once and compiled
// twice: in hamming_kernel.cpp for the target ISA, in hamming_popcnt.cpp with -mpopcnt (x86-64).
// The population count is a template argument so that each translation unit expands it for its own
// ISA. This header includes nothing of the project's: an inline function of a shared header compiled
// with -mpopcnt in one translation unit and without it in another would break the one-definition rule
// (the linker may keep the POPCNT copy for every caller).

#include <cstddef>
#include <cstdint>
#include <cstring>

namespace hwr::estimation::detail {

constexpr int kHammingDescriptorBytes = 32;  // == kOrbDescriptorBytes (checked in hamming_kernel.cpp)

template <int (*Popcount)(uint64_t)>
inline int hamming_words(const uint8_t* a, const uint8_t* b) {
  int d = 0;
  for (int k = 0; k < kHammingDescriptorBytes; k += 8) {
    uint64_t x, y;
    std::memcpy(&x, a + k, 8);
    std::memcpy(&y, b + k, 8);
    d += Popcount(x ^ y);
  }
  return d;
}

template <int (*Popcount)(uint64_t)>
inline void hamming_rows(const uint8_t* query, const uint8_t* train, int n, int* out) {
  for (int t = 0; t < n; ++t) {
    out[t] = hamming_words<Popcount>(query, train + static_cast<size_t>(t) * kHammingDescriptorBytes);
  }
}

template <int (*Popcount)(uint64_t)>
inline void hamming_rows_at(const uint8_t* query, const uint8_t* base, const uint32_t* ids, int n, int* out) {
  for (int i = 0; i < n; ++i) {
    out[i] = hamming_words<Popcount>(query, base + static_cast<size_t>(ids[i]) * kHammingDescriptorBytes);
  }
}

// The POPCNT kernels (hamming_popcnt.cpp, x86-64 only).
void hamming_distances_popcnt(const uint8_t* query, const uint8_t* train, int n, int* out);
void hamming_distances_at_popcnt(const uint8_t* query, const uint8_t* base, const uint32_t* ids, int n,
                                 int* out);

}  // namespace hwr::estimation::detail
