// The batched Hamming kernels (hamming_kernel.hpp). Oracle: descriptor.hpp's one-pair count on the
// same random descriptors, including all-equal and all-different pairs, for the kernel in use and the
// portable one; the kernel in use is named.

#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "hwr/core/alloc_counter.hpp"
#include "hwr/estimation/descriptor.hpp"
#include "hwr/estimation/hamming_kernel.hpp"

namespace hwr::estimation {
namespace {

TEST(HammingKernel, GivenRandomDescriptorsThenTheBatchedDistancesEqualThePairwiseCount) {
  constexpr int kTrain = 257;  // not a multiple of any unrolling
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> byte(0, 255);
  std::vector<uint8_t> train(static_cast<size_t>(kTrain) * kOrbDescriptorBytes);
  for (uint8_t& b : train) b = static_cast<uint8_t>(byte(rng));
  std::vector<uint8_t> query(kOrbDescriptorBytes);
  for (uint8_t& b : query) b = static_cast<uint8_t>(byte(rng));
  // Train 0 equals the query (distance 0), train 1 is its complement (256).
  std::memcpy(train.data(), query.data(), kOrbDescriptorBytes);
  for (int k = 0; k < kOrbDescriptorBytes; ++k)
    train[kOrbDescriptorBytes + k] = static_cast<uint8_t>(~query[k]);

  std::vector<int> out(kTrain, -1);
  {
    core::AllocationScope scope;
    hamming_distances(query.data(), train.data(), kTrain, out.data());
    EXPECT_EQ(scope.allocations(), 0u);
  }
  EXPECT_EQ(out[0], 0);
  EXPECT_EQ(out[1], kOrbDescriptorBits);
  for (int t = 0; t < kTrain; ++t) {
    EXPECT_EQ(out[static_cast<size_t>(t)],
              hamming_distance(query.data(), &train[static_cast<size_t>(t) * kOrbDescriptorBytes]))
        << t;
  }

  // The portable kernel (SWAR where the target ISA has no population count) gives the same: on a host
  // where the kernel in use is the POPCNT one, both are checked.
  std::vector<int> portable(kTrain, -1);
  detail::hamming_distances_portable(query.data(), train.data(), kTrain, portable.data());
  EXPECT_EQ(portable, out);

  // Gathered: every third descriptor, backwards.
  std::vector<uint32_t> ids;
  for (int t = kTrain - 1; t >= 0; t -= 3) ids.push_back(static_cast<uint32_t>(t));
  std::vector<int> at(ids.size(), -1);
  hamming_distances_at(query.data(), train.data(), ids.data(), static_cast<int>(ids.size()), at.data());
  for (size_t i = 0; i < ids.size(); ++i) EXPECT_EQ(at[i], out[ids[i]]) << i;

  // None asked: nothing written.
  int untouched = -7;
  hamming_distances(query.data(), train.data(), 0, &untouched);
  EXPECT_EQ(untouched, -7);

  const std::string name = hamming_kernel_name();
  EXPECT_TRUE(name == "popcnt" || name == "builtin" || name == "swar") << name;
  std::printf("[ hamming  ] kernel: %s\n", name.c_str());
}

}  // namespace
}  // namespace hwr::estimation
