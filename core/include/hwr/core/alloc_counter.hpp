#pragma once
// Heap-allocation counter for tests and benchmarks: proves that the steady-state path allocates
// nothing (ARCHITECTURE.md "a test counts allocations to prove it").
//
// Lives in its own library, hwr::alloc_counter, never in hwr::core: linking it into a program
// replaces the global operator new/delete (every variant) and interposes malloc, calloc, realloc,
// reallocarray, free, posix_memalign, aligned_alloc, memalign, valloc and pvalloc, forwarding to
// glibc's __libc_* entry points, so allocations made inside Eigen, OpenCV or libstdc++ are counted
// too. Under AddressSanitizer (which owns malloc itself) it counts through the sanitizer's
// allocation hooks instead (exact for ASan; under ThreadSanitizer the hooks miss some calls).
// Counters are per thread. glibc only.
//
//   hwr::core::AllocationScope scope;
//   run_cycle();
//   EXPECT_EQ(scope.allocations(), 0u);

#include <cstdint>

namespace hwr::core {

struct AllocationCounts {
  uint64_t allocations = 0;    // successful or attempted allocation calls
  uint64_t bytes = 0;          // bytes requested by them
  uint64_t deallocations = 0;  // free/delete of a non-null pointer
};

// The calling thread's totals since it started.
AllocationCounts thread_allocation_counts();

// Counts the allocations made by the constructing thread from construction on. Use it on the
// thread that constructed it.
class AllocationScope {
 public:
  AllocationScope();
  uint64_t allocations() const;
  uint64_t bytes() const;
  uint64_t deallocations() const;

 private:
  AllocationCounts start_;
};

// Allocations made inside a stage that reports its begin and end through a hook
// (e.g. VisualTracker::set_extract_hook(&StageAllocations::hook, &counter)), summed over calls.
struct StageAllocations {
  uint64_t at_begin = 0;
  uint64_t allocations = 0;
  static void hook(void* user, bool begin) {
    auto* s = static_cast<StageAllocations*>(user);
    const uint64_t now = thread_allocation_counts().allocations;
    if (begin) {
      s->at_begin = now;
    } else {
      s->allocations += now - s->at_begin;
    }
  }
};

}  // namespace hwr::core
