// The POPCNT kernels of hamming_kernel.hpp. CMake compiles this file with -mpopcnt on x86-64 (and
// defines HWR_HAMMING_POPCNT_TU); hamming_kernel.cpp calls it only on a CPU that has the instruction.
#include "hamming_kernel_impl.hpp"

#if defined(HWR_HAMMING_POPCNT_TU) && defined(__x86_64__) && defined(__POPCNT__)

namespace hwr::estimation::detail {

namespace {
int popcount_instruction(uint64_t x) { return __builtin_popcountll(x); }
}  // namespace

void hamming_distances_popcnt(const uint8_t* query, const uint8_t* train, int n, int* out) {
  hamming_rows<popcount_instruction>(query, train, n, out);
}

void hamming_distances_at_popcnt(const uint8_t* query, const uint8_t* base, const uint32_t* ids, int n,
                                 int* out) {
  hamming_rows_at<popcount_instruction>(query, base, ids, n, out);
}

}  // namespace hwr::estimation::detail

#endif
