#include "hwr/estimation/hamming_kernel.hpp"

#include "hamming_kernel_impl.hpp"
#include "hwr/estimation/descriptor.hpp"

namespace hwr::estimation {

static_assert(detail::kHammingDescriptorBytes == kOrbDescriptorBytes, "one ORB descriptor is 32 bytes");

namespace {

struct Kernels {
  void (*rows)(const uint8_t*, const uint8_t*, int, int*);
  void (*rows_at)(const uint8_t*, const uint8_t*, const uint32_t*, int, int*);
  const char* name;
};

void portable_rows(const uint8_t* query, const uint8_t* train, int n, int* out) {
  detail::hamming_rows<detail::popcount64>(query, train, n, out);
}
void portable_rows_at(const uint8_t* query, const uint8_t* base, const uint32_t* ids, int n, int* out) {
  detail::hamming_rows_at<detail::popcount64>(query, base, ids, n, out);
}

const Kernels& kernels() {
  static const Kernels k = [] {
#if defined(HWR_HAMMING_POPCNT_TU) && defined(__x86_64__) && !defined(__POPCNT__)
    if (__builtin_cpu_supports("popcnt")) {
      return Kernels{detail::hamming_distances_popcnt, detail::hamming_distances_at_popcnt, "popcnt"};
    }
#endif
    return Kernels {
      portable_rows, portable_rows_at,
#if defined(__POPCNT__) || defined(__aarch64__)
          "builtin"  // the target ISA's population count (aarch64 CNT, x86-64 built with POPCNT)
#else
          "swar"
#endif
    };
  }();
  return k;
}

}  // namespace

void hamming_distances(const uint8_t* query, const uint8_t* train, int n, int* out) {
  kernels().rows(query, train, n, out);
}

void hamming_distances_at(const uint8_t* query, const uint8_t* base, const uint32_t* ids, int n, int* out) {
  kernels().rows_at(query, base, ids, n, out);
}

const char* hamming_kernel_name() { return kernels().name; }

void detail::hamming_distances_portable(const uint8_t* query, const uint8_t* train, int n, int* out) {
  portable_rows(query, train, n, out);
}

}  // namespace hwr::estimation
