#pragma once
// Fixed-capacity pool of T, all constructed at start-up (frames, keyframes, chunk buffers), so the
// steady-state path reuses objects instead of allocating (ARCHITECTURE.md "Firmware-style rules").
//
// Threads: one thread may call acquire() while one other thread calls release() (the free list is
// an SpscRing of indices: release() is its producer, acquire() its consumer). With a single thread
// doing both, that is fine too. Objects are handed out as they were left: release() does not reset
// them.

#include <atomic>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "hwr/core/spsc_ring.hpp"

namespace hwr::core {

template <class T>
class ObjectPool {
 public:
  // capacity default-constructed objects.
  explicit ObjectPool(size_t capacity) : items_(capacity), free_(capacity) { fill_free_list(); }
  // capacity copies of prototype (e.g. an image with its buffer already sized).
  ObjectPool(size_t capacity, const T& prototype) : items_(capacity, prototype), free_(capacity) {
    fill_free_list();
  }
  ObjectPool(const ObjectPool&) = delete;
  ObjectPool& operator=(const ObjectPool&) = delete;

  // nullptr when every object is out (counted in exhausted()).
  T* acquire() {
    uint32_t i = 0;
    if (!free_.try_pop(i)) {
      exhausted_.fetch_add(1, std::memory_order_relaxed);
      return nullptr;
    }
    return &items_[i];
  }

  // p must come from this pool's acquire() and not have been released since.
  void release(T* p) {
    assert(owns(p));
    const bool ok = free_.try_push(static_cast<uint32_t>(p - items_.data()));
    // Cannot fail: the free list has room for every object, and with no drop path the producer
    // never needs the slot the consumer is reading (see SpscRing).
    assert(ok);
    (void)ok;
  }

  bool owns(const T* p) const { return p >= items_.data() && p < items_.data() + items_.size(); }
  size_t capacity() const { return items_.size(); }
  // Objects ready to acquire (a snapshot when called concurrently).
  size_t available() const { return free_.size(); }
  // Calls to acquire() that found the pool empty.
  uint64_t exhausted() const { return exhausted_.load(std::memory_order_relaxed); }

 private:
  void fill_free_list() {
    assert(items_.size() <= UINT32_MAX);
    for (size_t i = 0; i < items_.size(); ++i) free_.try_push(static_cast<uint32_t>(i));
  }

  std::vector<T> items_;  // sized once; never grows, so pointers stay valid
  SpscRing<uint32_t> free_;
  std::atomic<uint64_t> exhausted_{0};
};

}  // namespace hwr::core
