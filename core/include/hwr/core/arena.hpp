#pragma once
// Monotonic bump arena over one buffer allocated at construction: per-frame scratch (point arrays,
// BA workspace) is carved out with a pointer increment and released all at once by reset().
// Single-threaded. Objects are not destroyed by reset(), so only trivially destructible types may
// live here.

#include <cassert>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <type_traits>

namespace hwr::core {

class Arena {
 public:
  explicit Arena(size_t capacity_bytes) : buf_(new std::byte[capacity_bytes]), capacity_(capacity_bytes) {}
  Arena(const Arena&) = delete;
  Arena& operator=(const Arena&) = delete;

  // n default-initialized T aligned to alignof(T); nullptr (counted) when they do not fit.
  template <class T>
  T* allocate(size_t n) {
    static_assert(std::is_trivially_destructible_v<T>, "reset() runs no destructors");
    if (n > SIZE_MAX / sizeof(T)) {
      ++failed_;
      return nullptr;
    }
    void* p = allocate_bytes(n * sizeof(T), alignof(T));
    if (p == nullptr) return nullptr;
    T* out = static_cast<T*>(p);
    std::uninitialized_default_construct_n(out, n);
    return out;
  }

  // Raw storage; alignment must be a power of two. nullptr (counted) when it does not fit.
  void* allocate_bytes(size_t bytes, size_t alignment) {
    assert(alignment != 0 && (alignment & (alignment - 1)) == 0);
    const uintptr_t base = reinterpret_cast<uintptr_t>(buf_.get());
    const uintptr_t cur = base + used_;
    const uintptr_t aligned = (cur + (alignment - 1)) & ~static_cast<uintptr_t>(alignment - 1);
    const size_t offset = static_cast<size_t>(aligned - base);
    if (offset > capacity_ || bytes > capacity_ - offset) {
      ++failed_;
      return nullptr;
    }
    used_ = offset + bytes;
    if (used_ > high_water_) high_water_ = used_;
    return buf_.get() + offset;
  }

  // Everything allocated so far becomes invalid; the buffer is kept.
  void reset() { used_ = 0; }

  size_t used_bytes() const { return used_; }
  // Largest used_bytes() since construction (sizing aid for the config).
  size_t high_water_bytes() const { return high_water_; }
  size_t capacity_bytes() const { return capacity_; }
  // allocate()/allocate_bytes() calls that returned nullptr.
  uint64_t failed_allocations() const { return failed_; }

 private:
  std::unique_ptr<std::byte[]> buf_;
  size_t capacity_;
  size_t used_ = 0;
  size_t high_water_ = 0;
  uint64_t failed_ = 0;
};

}  // namespace hwr::core
