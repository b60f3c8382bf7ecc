#pragma once
// Bounded lock-free single-producer single-consumer ring (ARCHITECTURE.md "Queues are bounded; a
// full queue drops the oldest sensor sample and counts it").
//
// Threads: exactly one thread calls try_push/push_drop_oldest, exactly one thread calls try_pop;
// size(), capacity() and dropped() may be read from any thread. Storage (capacity + 1 slots of T)
// is allocated once in the constructor; no call allocates afterwards.
//
// How dropping the oldest stays safe against a concurrent consumer:
//  - head_ (next element to take) is advanced with compare_exchange by both the consumer (pop) and
//    the producer (drop), so each element is taken by exactly one of them.
//  - The consumer claims an element before copying it out, and announces the index it is about to
//    claim in reading_ beforehand (the hazard-pointer pattern). A claimed element is never
//    overwritten while reading_ names it: the producer checks reading_ before reusing a slot. The
//    extra (capacity + 1)-th slot makes that check fail only when the consumer stalls inside
//    try_pop while the producer laps it; the producer then drops the new element (counted) rather
//    than wait, so neither side ever blocks.
// Indices are 64-bit and never wrap in practice (2^64 pushes).

#include <atomic>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <utility>

namespace hwr::core {

template <class T>
class SpscRing {
 public:
  // capacity >= 1 elements. T must be default-constructible and copy-assignable.
  explicit SpscRing(size_t capacity) : capacity_(capacity), slots_(capacity + 1), buf_(new T[capacity + 1]) {
    assert(capacity >= 1);
  }
  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;

  // Producer. Appends v; false (and one drop counted) when no slot is free.
  bool try_push(const T& v) {
    const uint64_t t = tail_.load(std::memory_order_relaxed);
    const uint64_t h = head_.load(std::memory_order_seq_cst);
    if (t - h >= capacity_ || slot_being_read(t)) {
      dropped_.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    publish(t, v);
    return true;
  }

  // Producer. Appends v; when full, first discards the oldest element (one drop counted).
  void push_drop_oldest(const T& v) {
    const uint64_t t = tail_.load(std::memory_order_relaxed);
    uint64_t h = head_.load(std::memory_order_seq_cst);
    if (slot_being_read(t)) {
      dropped_.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    if (t - h >= capacity_) {
      // On failure the consumer has just taken the oldest element, so there is room anyway.
      if (head_.compare_exchange_strong(h, h + 1, std::memory_order_seq_cst)) {
        dropped_.fetch_add(1, std::memory_order_relaxed);
      }
    }
    publish(t, v);
  }

  // Consumer. Moves the oldest element into out; false when empty.
  bool try_pop(T& out) {
    uint64_t h = head_.load(std::memory_order_seq_cst);
    for (;;) {
      if (h == tail_.load(std::memory_order_acquire)) return false;
      reading_.store(h, std::memory_order_seq_cst);
      // On failure the producer dropped element h; h now holds the new head and we retry.
      if (head_.compare_exchange_weak(h, h + 1, std::memory_order_seq_cst)) break;
    }
    out = std::move(buf_[h % slots_]);  // the claimed slot is ours until reading_ is cleared
    reading_.store(kIdle, std::memory_order_release);
    return true;
  }

  // Elements currently held (a snapshot when called concurrently).
  size_t size() const {
    const uint64_t h = head_.load(std::memory_order_acquire);
    const uint64_t t = tail_.load(std::memory_order_acquire);
    return static_cast<size_t>(t - h);
  }
  bool empty() const { return size() == 0; }
  size_t capacity() const { return capacity_; }
  // Elements discarded by push_drop_oldest plus pushes refused by try_push.
  uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }

 private:
  static constexpr uint64_t kIdle = ~uint64_t{0};

  // Slot t % slots_ last held element t - slots_; true while the consumer may still be copying it.
  bool slot_being_read(uint64_t t) const {
    return t >= slots_ && reading_.load(std::memory_order_seq_cst) == t - slots_;
  }

  void publish(uint64_t t, const T& v) {
    buf_[t % slots_] = v;
    tail_.store(t + 1, std::memory_order_release);
  }

  const size_t capacity_;
  const size_t slots_;
  const std::unique_ptr<T[]> buf_;
  // Separate cache lines: head_/reading_ are written by the consumer, tail_ by the producer.
  alignas(64) std::atomic<uint64_t> head_{0};
  std::atomic<uint64_t> reading_{kIdle};
  alignas(64) std::atomic<uint64_t> tail_{0};
  std::atomic<uint64_t> dropped_{0};
};

}  // namespace hwr::core
