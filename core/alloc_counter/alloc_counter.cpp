// Allocation counter: see hwr/core/alloc_counter.hpp. glibc only (forwards to __libc_*).

#include "hwr/core/alloc_counter.hpp"

#include <malloc.h>

#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <new>

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define HWR_ALLOC_COUNTER_HOOKS 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || __has_feature(memory_sanitizer)
#define HWR_ALLOC_COUNTER_HOOKS 1
#endif
#endif

namespace {

struct Counters {
  uint64_t allocations;
  uint64_t bytes;
  uint64_t deallocations;
};

// Trivial type, constant-initialized, initial-exec model: the counter sits in the executable's
// static TLS block, so touching it from inside malloc needs no lazy TLS setup (__tls_get_addr can
// itself call malloc) and cannot recurse.
__attribute__((tls_model("initial-exec"))) thread_local Counters t_counts = {0, 0, 0};

inline void count_allocation(size_t bytes) {
  ++t_counts.allocations;
  t_counts.bytes += bytes;
}

inline void count_deallocation(const volatile void* p) {
  if (p != nullptr) ++t_counts.deallocations;
}

}  // namespace

namespace hwr::core {

AllocationCounts thread_allocation_counts() {
  AllocationCounts c;
  c.allocations = t_counts.allocations;
  c.bytes = t_counts.bytes;
  c.deallocations = t_counts.deallocations;
  return c;
}

AllocationScope::AllocationScope() : start_(thread_allocation_counts()) {}
uint64_t AllocationScope::allocations() const { return t_counts.allocations - start_.allocations; }
uint64_t AllocationScope::bytes() const { return t_counts.bytes - start_.bytes; }
uint64_t AllocationScope::deallocations() const { return t_counts.deallocations - start_.deallocations; }

}  // namespace hwr::core

#if defined(HWR_ALLOC_COUNTER_HOOKS)

// The sanitizer runtime replaces malloc and operator new itself; interposing them again would hand
// its pointers to glibc. It calls these hooks for every allocation it serves instead.
extern "C" int __sanitizer_install_malloc_and_free_hooks(void (*malloc_hook)(const volatile void*, size_t),
                                                         void (*free_hook)(const volatile void*));

namespace {
void on_malloc(const volatile void*, size_t size) { count_allocation(size); }
void on_free(const volatile void* p) { count_deallocation(p); }
struct HookInstaller {
  HookInstaller() { __sanitizer_install_malloc_and_free_hooks(on_malloc, on_free); }
};
const HookInstaller g_hook_installer;
}  // namespace

#else

// glibc's own entry points, exported for exactly this purpose (malloc interposition).
extern "C" {
void* __libc_malloc(size_t size) noexcept;
void* __libc_calloc(size_t n, size_t size) noexcept;
void* __libc_realloc(void* p, size_t size) noexcept;
void __libc_free(void* p) noexcept;
void* __libc_memalign(size_t alignment, size_t size) noexcept;
void* __libc_valloc(size_t size) noexcept;
void* __libc_pvalloc(size_t size) noexcept;

void* malloc(size_t size) noexcept {
  count_allocation(size);
  return __libc_malloc(size);
}

void free(void* p) noexcept {
  count_deallocation(p);
  __libc_free(p);
}

void* calloc(size_t n, size_t size) noexcept {
  size_t total = 0;
  if (__builtin_mul_overflow(n, size, &total)) {
    errno = ENOMEM;
    return nullptr;
  }
  count_allocation(total);
  return __libc_calloc(n, size);
}

void* realloc(void* p, size_t size) noexcept {
  // glibc: realloc(p, 0) frees p; realloc(nullptr, n) is malloc(n).
  if (size == 0 && p != nullptr) {
    count_deallocation(p);
  } else {
    count_allocation(size);
  }
  return __libc_realloc(p, size);
}

void* reallocarray(void* p, size_t n, size_t size) noexcept {
  size_t total = 0;
  if (__builtin_mul_overflow(n, size, &total)) {
    errno = ENOMEM;
    return nullptr;
  }
  return realloc(p, total);
}

int posix_memalign(void** out, size_t alignment, size_t size) noexcept {
  if (alignment % sizeof(void*) != 0 || (alignment & (alignment - 1)) != 0 || alignment == 0) return EINVAL;
  count_allocation(size);
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}

void* aligned_alloc(size_t alignment, size_t size) noexcept {
  count_allocation(size);
  return __libc_memalign(alignment, size);
}

void* memalign(size_t alignment, size_t size) noexcept {
  count_allocation(size);
  return __libc_memalign(alignment, size);
}

void* valloc(size_t size) noexcept {
  count_allocation(size);
  return __libc_valloc(size);
}

void* pvalloc(size_t size) noexcept {
  count_allocation(size);
  return __libc_pvalloc(size);
}
}  // extern "C"

// Global operator new/delete. They go through the interposed malloc/free above, so each
// allocation is counted exactly once. The throwing forms throw std::bad_alloc as the standard
// requires of them (this library is test/bench support, not firmware).
namespace {

void* new_impl(size_t size, size_t alignment, bool nothrow) {
  if (size == 0) size = 1;
  for (;;) {
    void* p = alignment <= __STDCPP_DEFAULT_NEW_ALIGNMENT__ ? malloc(size) : aligned_alloc(alignment, size);
    if (p != nullptr) return p;
    std::new_handler handler = std::get_new_handler();
    if (handler == nullptr) {
      if (nothrow) return nullptr;
      throw std::bad_alloc();
    }
    if (nothrow) {
      try {
        handler();
      } catch (...) {
        return nullptr;
      }
    } else {
      handler();
    }
  }
}

}  // namespace

void* operator new(size_t size) { return new_impl(size, 0, false); }
void* operator new[](size_t size) { return new_impl(size, 0, false); }
void* operator new(size_t size, const std::nothrow_t&) noexcept { return new_impl(size, 0, true); }
void* operator new[](size_t size, const std::nothrow_t&) noexcept { return new_impl(size, 0, true); }
void* operator new(size_t size, std::align_val_t al) {
  return new_impl(size, static_cast<size_t>(al), false);
}
void* operator new[](size_t size, std::align_val_t al) {
  return new_impl(size, static_cast<size_t>(al), false);
}
void* operator new(size_t size, std::align_val_t al, const std::nothrow_t&) noexcept {
  return new_impl(size, static_cast<size_t>(al), true);
}
void* operator new[](size_t size, std::align_val_t al, const std::nothrow_t&) noexcept {
  return new_impl(size, static_cast<size_t>(al), true);
}

void operator delete(void* p) noexcept { free(p); }
void operator delete[](void* p) noexcept { free(p); }
void operator delete(void* p, size_t) noexcept { free(p); }
void operator delete[](void* p, size_t) noexcept { free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { free(p); }
void operator delete(void* p, std::align_val_t) noexcept { free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { free(p); }
void operator delete(void* p, size_t, std::align_val_t) noexcept { free(p); }
void operator delete[](void* p, size_t, std::align_val_t) noexcept { free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { free(p); }

#endif  // HWR_ALLOC_COUNTER_HOOKS
