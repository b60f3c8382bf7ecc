#pragma once
// The robot's heap policy (ARCHITECTURE.md: memory bounded for the whole mission). glibc raises its
// mmap threshold to the size of the largest mmap'd block freed (up to 32 MiB on 64-bit), so after the
// first closed segment is written and freed, every later segment's point vectors (2-40 MB) come from
// the heap arenas instead, where freed space fragments and is kept: the resident size creeps up with
// each segment. A fixed threshold keeps blocks above it on mmap, returned to the system when freed.
// Call once at start-up, before the pipeline's threads exist.

#include <cstddef>

#include "hwr/core/status.hpp"

namespace hwr::core {

// Blocks of at least mmap_threshold_bytes are mmap'd and given back on free (glibc's M_MMAP_THRESHOLD,
// fixed, which also stops its dynamic adjustment). Elsewhere than glibc: Ok, nothing done.
Status fix_malloc_mmap_threshold(size_t mmap_threshold_bytes = 128 * 1024);

}  // namespace hwr::core
