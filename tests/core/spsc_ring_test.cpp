// SpscRing: single-thread semantics with closed-form contents, and two-thread stress tests whose
// oracle is the sequence number carried by every element.

#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <thread>

#include "hwr/core/spsc_ring.hpp"

namespace hwr::core {
namespace {

TEST(SpscRing, GivenEmptyRingWhenPoppedThenNothingAndSizeZero) {
  SpscRing<int> ring(4);
  int v = -1;
  EXPECT_FALSE(ring.try_pop(v));
  EXPECT_EQ(v, -1);
  EXPECT_EQ(ring.size(), 0u);
  EXPECT_TRUE(ring.empty());
  EXPECT_EQ(ring.capacity(), 4u);
  EXPECT_EQ(ring.dropped(), 0u);
}

TEST(SpscRing, GivenFullRingWhenTryPushThenRefusedAndCountedAndContentsKept) {
  SpscRing<int> ring(4);
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(ring.try_push(i));
  EXPECT_EQ(ring.size(), 4u);
  EXPECT_FALSE(ring.try_push(99));
  EXPECT_FALSE(ring.try_push(100));
  EXPECT_EQ(ring.dropped(), 2u);
  for (int i = 0; i < 4; ++i) {
    int v = -1;
    ASSERT_TRUE(ring.try_pop(v));
    EXPECT_EQ(v, i);
  }
  int v = -1;
  EXPECT_FALSE(ring.try_pop(v));
}

TEST(SpscRing, GivenManyWrapsWhenPushingAndPoppingThenFifoOrder) {
  SpscRing<uint64_t> ring(3);
  uint64_t next_in = 0, next_out = 0;
  for (int round = 0; round < 1000; ++round) {
    const int n = 1 + round % 3;
    for (int i = 0; i < n; ++i) ASSERT_TRUE(ring.try_push(next_in++));
    for (int i = 0; i < n; ++i) {
      uint64_t v = 0;
      ASSERT_TRUE(ring.try_pop(v));
      ASSERT_EQ(v, next_out++);
    }
  }
  EXPECT_EQ(ring.dropped(), 0u);
}

TEST(SpscRing, GivenFullRingWhenPushDropOldestThenOldestDiscardedAndCounted) {
  SpscRing<int> ring(3);
  for (int i = 1; i <= 5; ++i) ring.push_drop_oldest(i);
  EXPECT_EQ(ring.size(), 3u);
  EXPECT_EQ(ring.dropped(), 2u);
  for (int expected : {3, 4, 5}) {
    int v = 0;
    ASSERT_TRUE(ring.try_pop(v));
    EXPECT_EQ(v, expected);
  }
  EXPECT_TRUE(ring.empty());
}

TEST(SpscRing, GivenCapacityOneWhenPushDropOldestThenOnlyTheNewestIsKept) {
  SpscRing<int> ring(1);
  ring.push_drop_oldest(1);
  ring.push_drop_oldest(2);
  ring.push_drop_oldest(3);
  EXPECT_EQ(ring.dropped(), 2u);
  int v = 0;
  ASSERT_TRUE(ring.try_pop(v));
  EXPECT_EQ(v, 3);
  EXPECT_FALSE(ring.try_pop(v));
  EXPECT_TRUE(ring.try_push(4));
  EXPECT_FALSE(ring.try_push(5));
}

// Several words so a torn copy (half old, half new) would be caught.
struct Sample {
  uint64_t seq = 0;
  uint64_t twice = 0;
  uint64_t inverted = ~uint64_t{0};
  bool consistent() const { return twice == 2 * seq && inverted == ~seq; }
};
Sample make_sample(uint64_t s) { return Sample{s, 2 * s, ~s}; }

constexpr uint64_t kStressItems = 1'000'000;

TEST(SpscRingStress, GivenTwoThreadsWhenTryPushRetriesThenEveryItemArrivesInOrder) {
  SpscRing<Sample> ring(64);
  std::thread producer([&] {
    for (uint64_t i = 0; i < kStressItems; ++i) {
      while (!ring.try_push(make_sample(i))) std::this_thread::yield();
    }
  });
  uint64_t expected = 0;
  bool ok = true;
  while (expected < kStressItems) {
    Sample s;
    if (!ring.try_pop(s)) {
      std::this_thread::yield();
      continue;
    }
    if (s.seq != expected || !s.consistent()) {
      ok = false;
      break;
    }
    ++expected;
  }
  producer.join();
  EXPECT_TRUE(ok) << "first mismatch at " << expected;
  EXPECT_EQ(expected, kStressItems);
  EXPECT_TRUE(ring.empty());
}

TEST(SpscRingStress, GivenTwoThreadsWhenPushDropOldestThenIncreasingSubsequenceAndNothingUnaccounted) {
  SpscRing<Sample> ring(8);  // small, so the producer laps the consumer often
  std::atomic<bool> done{false};
  std::thread producer([&] {
    for (uint64_t i = 0; i < kStressItems; ++i) ring.push_drop_oldest(make_sample(i));
    done.store(true, std::memory_order_release);
  });
  uint64_t popped = 0;
  uint64_t last = 0;
  bool increasing = true, consistent = true;
  for (;;) {
    Sample s;
    if (ring.try_pop(s)) {
      if (popped > 0 && s.seq <= last) increasing = false;
      if (!s.consistent()) consistent = false;
      last = s.seq;
      ++popped;
      continue;
    }
    // The producer's last push happens before done; one more drain after seeing done.
    if (done.load(std::memory_order_acquire)) {
      while (ring.try_pop(s)) {
        if (popped > 0 && s.seq <= last) increasing = false;
        if (!s.consistent()) consistent = false;
        last = s.seq;
        ++popped;
      }
      break;
    }
  }
  producer.join();
  EXPECT_TRUE(increasing);
  EXPECT_TRUE(consistent);
  EXPECT_EQ(popped + ring.dropped(), kStressItems);
  EXPECT_GT(popped, 0u);
}

}  // namespace
}  // namespace hwr::core
