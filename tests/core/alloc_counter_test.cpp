// The allocation counter must see every heap allocation route (operator new, containers, the C
// allocator family, allocations made inside libraries) and nothing on the preallocated paths.

#include <gtest/gtest.h>

#include <malloc.h>

#include <array>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <thread>
#include <vector>

#include <Eigen/Core>

#include "hwr/core/alloc_counter.hpp"
#include "hwr/core/arena.hpp"
#include "hwr/core/object_pool.hpp"
#include "hwr/core/spsc_ring.hpp"

namespace hwr::core {
namespace {

// Keeps the compiler from proving an allocation unused and deleting the new/delete pair.
void escape(const void* p) { asm volatile("" : : "g"(p) : "memory"); }

TEST(AllocCounter, GivenScopeWhenNewAndDeleteThenOneAllocationOfThatSizeAndOneDeallocation) {
  AllocationScope scope;
  int* p = new int(3);
  escape(p);
  EXPECT_EQ(scope.allocations(), 1u);
  EXPECT_EQ(scope.bytes(), sizeof(int));
  delete p;
  EXPECT_EQ(scope.deallocations(), 1u);

  AllocationScope arrays;
  double* a = new double[10];
  escape(a);
  delete[] a;
  EXPECT_EQ(arrays.allocations(), 1u);
  EXPECT_GE(arrays.bytes(), 10 * sizeof(double));

  struct alignas(128) Wide {
    char c[128];
  };
  AllocationScope aligned;
  Wide* w = new Wide;
  escape(w);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(w) % 128, 0u);
  delete w;
  EXPECT_EQ(aligned.allocations(), 1u);
  EXPECT_EQ(aligned.deallocations(), 1u);

  AllocationScope nothrow_scope;
  int* q = new (std::nothrow) int[4];
  escape(q);
  delete[] q;
  EXPECT_EQ(nothrow_scope.allocations(), 1u);
}

TEST(AllocCounter, GivenVectorWhenItGrowsThenEachReallocationIsCounted) {
  std::vector<int> v;
  AllocationScope scope;
  for (int i = 0; i < 1000; ++i) v.push_back(i);
  escape(v.data());
  // libstdc++ doubles the capacity: 1, 2, 4, ..., 1024 -> 11 allocations.
  EXPECT_EQ(scope.allocations(), 11u);
  EXPECT_EQ(scope.deallocations(), 10u);

  AllocationScope reserved;
  std::vector<int> w;
  w.reserve(1000);
  for (int i = 0; i < 1000; ++i) w.push_back(i);
  escape(w.data());
  EXPECT_EQ(reserved.allocations(), 1u);
}

TEST(AllocCounter, GivenCAllocatorFamilyWhenCalledThenEveryCallIsCounted) {
  AllocationScope scope;
  void* m = std::malloc(100);
  escape(m);
  void* c = std::calloc(10, 8);
  escape(c);
  m = std::realloc(m, 1000);
  escape(m);
  void* pm = nullptr;
  ASSERT_EQ(posix_memalign(&pm, 64, 256), 0);
  escape(pm);
  void* aa = std::aligned_alloc(64, 128);
  escape(aa);
  void* ma = memalign(32, 64);
  escape(ma);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(pm) % 64, 0u);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(aa) % 64, 0u);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(ma) % 32, 0u);
  EXPECT_EQ(scope.allocations(), 6u);
  EXPECT_EQ(scope.bytes(), 100u + 80u + 1000u + 256u + 128u + 64u);
  for (void* p : {m, c, pm, aa, ma}) std::free(p);
}

TEST(AllocCounter, GivenLibraryCodeWhenItAllocatesThenItIsCountedToo) {
  // strdup allocates inside glibc; a dynamic Eigen matrix inside Eigen's aligned allocator.
  AllocationScope scope;
  char* s = strdup("relocalization");
  escape(s);
  std::free(s);
  EXPECT_EQ(scope.allocations(), 1u);

  AllocationScope eigen;
  Eigen::MatrixXd M = Eigen::MatrixXd::Random(40, 40);
  escape(M.data());
  EXPECT_EQ(eigen.allocations(), 1u);
  // Eigen may over-allocate by one alignment unit when it aligns by hand (some builds do).
  EXPECT_GE(eigen.bytes(), 40u * 40u * sizeof(double));
  EXPECT_LE(eigen.bytes(), 40u * 40u * sizeof(double) + 64u);

  AllocationScope fixed;
  Eigen::Matrix<double, 6, 6> F = Eigen::Matrix<double, 6, 6>::Random();
  escape(F.data());
  EXPECT_EQ(fixed.allocations(), 0u);  // fixed-size Eigen types live on the stack
}

TEST(AllocCounter, GivenAnotherThreadWhenItAllocatesThenThisThreadsScopeDoesNotSeeIt) {
  AllocationScope scope;
  uint64_t other = 0;
  std::thread t([&] {
    AllocationScope inner;
    for (int i = 0; i < 5; ++i) {
      int* p = new int(i);
      escape(p);
      delete p;
    }
    other = inner.allocations();
  });
  const uint64_t before_join = scope.allocations();  // std::thread itself allocates its state
  t.join();
  EXPECT_EQ(other, 5u);
  EXPECT_EQ(scope.allocations(), before_join);
}

TEST(AllocCounter, GivenPreallocatedStructuresWhenUsedAfterConstructionThenZeroAllocations) {
  SpscRing<uint64_t> ring(64);
  ObjectPool<std::array<double, 32>> pool(8);
  Arena arena(1 << 16);

  AllocationScope scope;
  for (uint64_t i = 0; i < 10'000; ++i) {
    ring.push_drop_oldest(i);
    if (i % 3 == 0) {
      uint64_t v = 0;
      ring.try_pop(v);
    }
    ring.try_push(i);
  }
  for (int i = 0; i < 10'000; ++i) {
    auto* a = pool.acquire();
    auto* b = pool.acquire();
    escape(a);
    pool.release(a);
    pool.release(b);
  }
  for (int i = 0; i < 1000; ++i) {
    double* d = arena.allocate<double>(100);
    escape(d);
    if (arena.allocate<float>(3000) == nullptr) arena.reset();
  }
  EXPECT_EQ(scope.allocations(), 0u);
  EXPECT_EQ(scope.bytes(), 0u);
}

}  // namespace
}  // namespace hwr::core
