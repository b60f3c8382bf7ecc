// ObjectPool and Arena: closed-form capacity, exhaustion and alignment behaviour.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <set>
#include <thread>
#include <vector>

#include "hwr/core/arena.hpp"
#include "hwr/core/object_pool.hpp"
#include "hwr/core/spsc_ring.hpp"

namespace hwr::core {
namespace {

struct Frame {
  int id = 7;
  double data[16] = {};
};

TEST(ObjectPool, GivenPoolOfFourWhenAllAcquiredThenDistinctObjectsAndFifthIsNullAndCounted) {
  ObjectPool<Frame> pool(4);
  EXPECT_EQ(pool.capacity(), 4u);
  EXPECT_EQ(pool.available(), 4u);
  std::set<Frame*> got;
  for (int i = 0; i < 4; ++i) {
    Frame* f = pool.acquire();
    ASSERT_NE(f, nullptr);
    EXPECT_TRUE(pool.owns(f));
    EXPECT_EQ(f->id, 7);  // default-constructed at start-up
    got.insert(f);
  }
  EXPECT_EQ(got.size(), 4u);
  EXPECT_EQ(pool.available(), 0u);
  EXPECT_EQ(pool.acquire(), nullptr);
  EXPECT_EQ(pool.acquire(), nullptr);
  EXPECT_EQ(pool.exhausted(), 2u);

  Frame* back = *got.begin();
  pool.release(back);
  EXPECT_EQ(pool.available(), 1u);
  EXPECT_EQ(pool.acquire(), back);
}

TEST(ObjectPool, GivenPrototypeWhenPoolBuiltThenEveryObjectIsACopyAndKeepsItsState) {
  Frame proto;
  proto.id = 42;
  proto.data[3] = 1.5;
  ObjectPool<Frame> pool(3, proto);
  Frame* a = pool.acquire();
  ASSERT_NE(a, nullptr);
  EXPECT_EQ(a->id, 42);
  EXPECT_EQ(a->data[3], 1.5);
  a->id = 5;
  pool.release(a);
  // Objects are handed out as left (no reset): the free list is FIFO, so a returns last.
  Frame* b = pool.acquire();
  Frame* c = pool.acquire();
  Frame* d = pool.acquire();
  EXPECT_EQ(d, a);
  EXPECT_EQ(d->id, 5);
  EXPECT_EQ(b->id, 42);
  EXPECT_EQ(c->id, 42);
}

TEST(ObjectPool, GivenAcquirerAndReleaserThreadsWhenCyclingThenNothingLeaksOrDuplicates) {
  constexpr size_t kCapacity = 16;
  constexpr int kCycles = 200'000;
  ObjectPool<Frame> pool(kCapacity);
  SpscRing<Frame*> in_flight(kCapacity);
  std::thread releaser([&] {
    for (int n = 0; n < kCycles;) {
      Frame* f = nullptr;
      if (in_flight.try_pop(f)) {
        f->id = -1;  // the releaser owns it until release
        pool.release(f);
        ++n;
      } else {
        std::this_thread::yield();
      }
    }
  });
  for (int n = 0; n < kCycles;) {
    Frame* f = pool.acquire();
    if (f == nullptr) {
      std::this_thread::yield();
      continue;
    }
    f->id = n;
    while (!in_flight.try_push(f)) std::this_thread::yield();
    ++n;
  }
  releaser.join();
  EXPECT_EQ(pool.available(), kCapacity);
  std::set<Frame*> all;
  for (size_t i = 0; i < kCapacity; ++i) all.insert(pool.acquire());
  EXPECT_EQ(all.size(), kCapacity);
  EXPECT_EQ(all.count(nullptr), 0u);
}

TEST(Arena, GivenArenaWhenAllocatingMixedTypesThenEachIsAlignedAndUsageIsExact) {
  Arena arena(1024);
  EXPECT_EQ(arena.capacity_bytes(), 1024u);
  char* c = arena.allocate<char>(3);
  ASSERT_NE(c, nullptr);
  double* d = arena.allocate<double>(4);
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(d) % alignof(double), 0u);
  struct alignas(64) Line {
    float v[16];
  };
  Line* l = arena.allocate<Line>(2);
  ASSERT_NE(l, nullptr);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(l) % 64, 0u);
  // Distinct, non-overlapping, in order.
  EXPECT_GE(reinterpret_cast<char*>(d), c + 3);
  EXPECT_GE(reinterpret_cast<char*>(l), reinterpret_cast<char*>(d + 4));
  // The first char needs no padding, so it sits at the buffer start.
  EXPECT_EQ(arena.used_bytes(), static_cast<size_t>(reinterpret_cast<char*>(l + 2) - c));
  EXPECT_EQ(arena.high_water_bytes(), arena.used_bytes());
  for (int i = 0; i < 4; ++i) d[i] = i;  // writable
  EXPECT_EQ(arena.failed_allocations(), 0u);
}

TEST(Arena, GivenArenaWhenItRunsOutThenNullptrIsCountedAndResetReclaimsEverything) {
  Arena arena(256);
  uint8_t* a = arena.allocate<uint8_t>(200);
  ASSERT_NE(a, nullptr);
  EXPECT_EQ(arena.used_bytes(), 200u);
  EXPECT_EQ(arena.allocate<uint8_t>(57), nullptr);
  EXPECT_EQ(arena.failed_allocations(), 1u);
  EXPECT_EQ(arena.used_bytes(), 200u);  // a failed call takes nothing
  uint8_t* b = arena.allocate<uint8_t>(56);
  ASSERT_NE(b, nullptr);
  EXPECT_EQ(arena.used_bytes(), 256u);
  EXPECT_EQ(arena.allocate<uint8_t>(1), nullptr);
  EXPECT_EQ(arena.allocate<uint64_t>(SIZE_MAX / 4), nullptr);  // n * sizeof(T) overflows
  EXPECT_EQ(arena.failed_allocations(), 3u);

  arena.reset();
  EXPECT_EQ(arena.used_bytes(), 0u);
  EXPECT_EQ(arena.high_water_bytes(), 256u);
  EXPECT_EQ(arena.allocate<uint8_t>(256), a);  // same buffer reused from its start
  arena.reset();
  ASSERT_NE(arena.allocate<uint8_t>(10), nullptr);
  EXPECT_EQ(arena.high_water_bytes(), 256u);
}

}  // namespace
}  // namespace hwr::core
