// associate_nearest follows TUM's associate.py: greedy by smallest |Δt|, each index once, only
// |Δt| < max_dt, result ordered by the first list.

#include <gtest/gtest.h>

#include "hwr/core/time_association.hpp"

namespace hwr::core {
namespace {

TEST(TimeAssociation, GivenTwoCandidatesForOneStampWhenAssociatedThenTheNearerWinsAndTheOtherFindsNoPartner) {
  // a = {100, 104}, b = {101, 103}: candidates by |Δt|: (0,0)=1, (1,1)=1, (1,0)=3, (0,1)=3.
  const auto pairs = associate_nearest({100, 104}, {101, 103}, 10);
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0].a, 0u);
  EXPECT_EQ(pairs[0].b, 0u);
  EXPECT_EQ(pairs[1].a, 1u);
  EXPECT_EQ(pairs[1].b, 1u);
}

TEST(TimeAssociation, GivenAGreedyConflictWhenAssociatedThenTheGlobalSmallestDifferenceIsTakenFirst) {
  // b[0]=105 is 1 from a[1]=106 and 5 from a[0]=100: a[1] takes it, a[0] is left alone.
  const auto pairs = associate_nearest({100, 106}, {105}, 10);
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs[0].a, 1u);
  EXPECT_EQ(pairs[0].b, 0u);
}

TEST(TimeAssociation, GivenDifferencesAtTheLimitWhenAssociatedThenOnlyStrictlySmallerOnesPair) {
  EXPECT_TRUE(associate_nearest({100}, {110}, 10).empty());
  EXPECT_EQ(associate_nearest({100}, {109}, 10).size(), 1u);
}

TEST(TimeAssociation, GivenAnOffsetWhenAssociatedThenItShiftsTheSecondList) {
  const auto pairs = associate_nearest({1000, 2000}, {0, 1000}, 5, 1000);
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0].b, 0u);
  EXPECT_EQ(pairs[1].b, 1u);
}

}  // namespace
}  // namespace hwr::core
