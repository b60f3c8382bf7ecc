// core::fix_malloc_mmap_threshold: out-of-range thresholds are refused; with the threshold fixed,
// a 1 MiB block is still mmap'd after a 4 MiB mmap'd block was freed (glibc's dynamic threshold
// would have risen to 4 MiB and served it from the heap, where freed space is kept).

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>

#include "hwr/core/malloc_policy.hpp"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace hwr::core {
namespace {

TEST(MallocPolicy, GivenAThresholdOutOfRangeThenItIsRefused) {
  EXPECT_EQ(fix_malloc_mmap_threshold(0).code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(fix_malloc_mmap_threshold((32u << 20) + 1).code(), ErrorCode::kInvalidArgument);
  EXPECT_TRUE(fix_malloc_mmap_threshold(32u << 20).ok());
}

#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
// Blocks currently mmap'd by malloc.
size_t mmapped_blocks() { return mallinfo2().hblks; }

void* touch(size_t bytes) {
  void* p = std::malloc(bytes);
  if (p != nullptr) std::memset(p, 1, bytes);
  return p;
}

TEST(MallocPolicy, GivenTheThresholdFixedThenBlocksAboveItStayMmappedAfterALargerFree) {
  ASSERT_TRUE(fix_malloc_mmap_threshold(128 * 1024).ok());
  void* big = touch(4u << 20);
  ASSERT_NE(big, nullptr);
  std::free(big);  // without the fix the threshold would now be 4 MiB
  const size_t before = mmapped_blocks();
  void* mid = touch(1u << 20);
  ASSERT_NE(mid, nullptr);
  EXPECT_EQ(mmapped_blocks(), before + 1) << "a 1 MiB block came from the heap";
  std::free(mid);
  EXPECT_EQ(mmapped_blocks(), before);  // given back
}
#endif

}  // namespace
}  // namespace hwr::core
