#pragma once
// Batched Hamming distances of 256-bit ORB descriptors (descriptor.hpp) for the inner loops of the
// exhaustive matchers (exact_matcher.hpp, the relocalizer's vote index): one query descriptor against
// many, each 32 bytes.
//
// The kernel is chosen once per process for the CPU it runs on. On x86-64 the host builds target the
// baseline ISA, which has no POPCNT instruction, so descriptor.hpp's portable count is a SWAR sequence
// of ~12 operations per 64-bit word; every x86-64 CPU since ~2008 has POPCNT (Intel Nehalem, AMD
// K10). The POPCNT kernel lives in its own translation unit compiled with -mpopcnt and is used only
// when the CPU reports the instruction (__builtin_cpu_supports), else the portable one. Where the
// target ISA has a population count (aarch64's CNT on the Jetson AGX; x86-64 built with -mpopcnt or
// -march=x86-64-v2 and up) the portable kernel is that instruction already. Both give the same
// distances (tests/estimation/test_hamming_kernel.cpp). No allocation.

#include <cstdint>

namespace hwr::estimation {

// out[t] = Hamming distance of query and the t-th descriptor of `train` (n contiguous descriptors,
// 32 bytes each), t in [0, n).
void hamming_distances(const uint8_t* query, const uint8_t* train, int n, int* out);

// out[i] = Hamming distance of query and the descriptor at base + 32 * ids[i], i in [0, n).
void hamming_distances_at(const uint8_t* query, const uint8_t* base, const uint32_t* ids, int n, int* out);

// The kernel in use: "popcnt" (dispatched at run time, x86-64), "builtin" (the target ISA's own
// population count) or "swar" (descriptor.hpp's portable count).
const char* hamming_kernel_name();

namespace detail {
// The portable kernel whatever the CPU (tests compare it with the one in use).
void hamming_distances_portable(const uint8_t* query, const uint8_t* train, int n, int* out);
}  // namespace detail

}  // namespace hwr::estimation
