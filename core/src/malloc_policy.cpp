#include "hwr/core/malloc_policy.hpp"

#include <string>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace hwr::core {

Status fix_malloc_mmap_threshold(size_t mmap_threshold_bytes) {
#if defined(__GLIBC__)
  // glibc caps the value at HEAP_MAX/2 (32 MiB on 64-bit) and refuses more (mallopt returns 0).
  if (mmap_threshold_bytes == 0 || mmap_threshold_bytes > (32u << 20))
    return InvalidArgument("malloc policy: mmap threshold must be in (0, 32 MiB], got " +
                           std::to_string(mmap_threshold_bytes));
  if (mallopt(M_MMAP_THRESHOLD, static_cast<int>(mmap_threshold_bytes)) != 1)
    return Internal("malloc policy: mallopt(M_MMAP_THRESHOLD) refused " +
                    std::to_string(mmap_threshold_bytes));
#else
  (void)mmap_threshold_bytes;
#endif
  return Status::Ok();
}

}  // namespace hwr::core
