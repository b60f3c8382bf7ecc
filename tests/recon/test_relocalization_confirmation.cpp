// Confirmation of weak relocalizations across attempts (recon/relocalization_confirmation.hpp).
// Oracles: results built here with known T_prior_world, weak or not, with or without a position prior;
// the verdicts follow from the rule (a weak fit without a position prior waits for a later attempt
// that agrees within agree_m at its camera and agree_rad).

#include <gtest/gtest.h>

#include "hwr/recon/relocalization_confirmation.hpp"

namespace hwr::recon {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

Eigen::Isometry3d pose(double yaw_deg, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = t;
  return T;
}

RelocalizationResult localized(const Eigen::Isometry3d& T_prior_world, bool weak) {
  RelocalizationResult r;
  r.localized = true;
  r.reason = RelocalizationReason::kLocalized;
  r.T_prior_world = T_prior_world;
  r.orb_refined = weak;
  r.orb_refined_weak = weak;
  return r;
}

RelocalizationResult not_localized() {
  RelocalizationResult r;
  r.reason = RelocalizationReason::kAmbiguous;
  return r;
}

RelocalizationQuery query_at(const Eigen::Vector3d& p_world_cam, bool position_prior) {
  RelocalizationQuery q;
  q.T_world_cam = pose(0.0, p_world_cam);
  q.position.valid = position_prior;
  q.position.sigma_m = 1.8;
  return q;
}

const Eigen::Isometry3d kTrue = pose(40.0, {3.0, -2.0, 0.1});
const Eigen::Isometry3d kRepeat = pose(40.3, {55.0, 5.0, 0.1});  // the place recurs 57 m away

TEST(RelocalizationConfirmation, GivenAFitThatIsNotWeakOrHasAPositionPriorThenItIsAcceptedAtOnce) {
  RelocalizationConfirmation c;
  EXPECT_EQ(c.offer(localized(kTrue, false), query_at({1, 0, 0}, false)), ConfirmationVerdict::kAccepted);
  EXPECT_TRUE(c.accepted());
  EXPECT_TRUE(c.accepted_T_prior_world().isApprox(kTrue));

  RelocalizationConfirmation with_gnss;
  EXPECT_EQ(with_gnss.offer(localized(kTrue, true), query_at({1, 0, 0}, true)),
            ConfirmationVerdict::kAccepted);

  RelocalizationConfirmationConfig off;
  off.confirm_weak_without_position = false;
  RelocalizationConfirmation at_once(off);
  EXPECT_EQ(at_once.offer(localized(kRepeat, true), query_at({1, 0, 0}, false)),
            ConfirmationVerdict::kAccepted);
}

TEST(RelocalizationConfirmation, GivenAWeakFitWithoutAPositionPriorThenALaterAttemptMustAgree) {
  RelocalizationConfirmation c;
  EXPECT_EQ(c.offer(not_localized(), query_at({1, 0, 0}, false)), ConfirmationVerdict::kNotLocalized);
  // The wrong weak fit first (outdoor f4565): held, not accepted.
  EXPECT_EQ(c.offer(localized(kRepeat, true), query_at({2, 0, 0}, false)), ConfirmationVerdict::kPending);
  EXPECT_FALSE(c.accepted());
  EXPECT_TRUE(c.pending());
  // Attempts that find nothing keep it pending.
  EXPECT_EQ(c.offer(not_localized(), query_at({3, 0, 0}, false)), ConfirmationVerdict::kPending);
  // A weak fit elsewhere replaces it, still unconfirmed.
  EXPECT_EQ(c.offer(localized(kTrue, true), query_at({4, 0, 0}, false)), ConfirmationVerdict::kPending);
  EXPECT_EQ(c.superseded(), 1);
  EXPECT_TRUE(c.pending_T_prior_world().isApprox(kTrue));
  // A later weak fit 3 cm / 0.2 deg from it (another attempt's error) confirms it: the later pose.
  const Eigen::Isometry3d again = pose(40.2, {3.03, -2.0, 0.1});
  EXPECT_EQ(c.offer(localized(again, true), query_at({7, 0, 0}, false)), ConfirmationVerdict::kAccepted);
  EXPECT_TRUE(c.accepted_T_prior_world().isApprox(again));
  EXPECT_FALSE(c.pending());
  // Accepted stays accepted until reset.
  EXPECT_EQ(c.offer(localized(kRepeat, true), query_at({9, 0, 0}, false)), ConfirmationVerdict::kAccepted);
  EXPECT_TRUE(c.accepted_T_prior_world().isApprox(again));
  c.reset();
  EXPECT_FALSE(c.accepted());
  EXPECT_FALSE(c.pending());
  EXPECT_EQ(c.superseded(), 0);
}

TEST(RelocalizationConfirmation,
     GivenAPendingWeakFitAndALaterFitThatNeedsNoConfirmationThenTheLaterOneIsAccepted) {
  RelocalizationConfirmation c;
  EXPECT_EQ(c.offer(localized(kRepeat, true), query_at({2, 0, 0}, false)), ConfirmationVerdict::kPending);
  EXPECT_EQ(c.offer(localized(kTrue, false), query_at({3, 0, 0}, false)), ConfirmationVerdict::kAccepted);
  EXPECT_TRUE(c.accepted_T_prior_world().isApprox(kTrue));
}

// Of two that agree, the ORB pose-only fit: the pending weak one over a later NDT pose the polish did
// not refine (outdoor f4609: 0.20 cm against 4.5 cm), a later polished one over the pending one.
TEST(RelocalizationConfirmation, GivenAPendingWeakFitConfirmedByAnAgreeingFitThenTheOrbRefinedPoseIsKept) {
  const Eigen::Isometry3d near = pose(40.3, {3.04, -2.0, 0.1});
  RelocalizationConfirmation c;
  ASSERT_EQ(c.offer(localized(kTrue, true), query_at({2, 0, 0}, false)), ConfirmationVerdict::kPending);
  RelocalizationResult unpolished = localized(near, false);
  ASSERT_EQ(c.offer(unpolished, query_at({5, 0, 0}, false)), ConfirmationVerdict::kAccepted);
  EXPECT_TRUE(c.accepted_T_prior_world().isApprox(kTrue));

  RelocalizationConfirmation d;
  ASSERT_EQ(d.offer(localized(kTrue, true), query_at({2, 0, 0}, false)), ConfirmationVerdict::kPending);
  RelocalizationResult polished = localized(near, false);
  polished.orb_refined = true;  // a converged fit the ORB polish moved
  ASSERT_EQ(d.offer(polished, query_at({5, 0, 0}, false)), ConfirmationVerdict::kAccepted);
  EXPECT_TRUE(d.accepted_T_prior_world().isApprox(near));
}

// outdoor f4500 (seed 2, GNSS rows): a converged NDT fit 11.4 cm / 1.45 deg off, accepted with a GNSS
// position prior although its ORB polish was refused (99 of the 100 inliers it needs).
TEST(RelocalizationConfirmation, GivenAFitWhosePolishWasRefusedThenItWaitsEvenWithAPositionPrior) {
  const Eigen::Isometry3d off = pose(41.45, {3.08, -1.93, 0.1});  // ~11 cm, 1.45 deg from kTrue
  RelocalizationResult unpolished = localized(off, false);
  unpolished.polish_refused = true;
  {
    RelocalizationConfirmation c;
    EXPECT_EQ(c.offer(unpolished, query_at({1, 0, 0}, true)), ConfirmationVerdict::kPending);
    // A later polished fit that disagrees needs no confirmation: accepted, the held one dropped.
    RelocalizationResult polished = localized(kTrue, false);
    polished.orb_refined = true;
    EXPECT_EQ(c.offer(polished, query_at({2, 0, 0}, true)), ConfirmationVerdict::kAccepted);
    EXPECT_TRUE(c.accepted_T_prior_world().isApprox(kTrue));
  }
  {
    // Two refused polishes that agree: accepted, the later one kept (the same support).
    RelocalizationConfirmation c;
    RelocalizationResult first = localized(kTrue, false);
    first.polish_refused = true;
    EXPECT_EQ(c.offer(first, query_at({1, 0, 0}, true)), ConfirmationVerdict::kPending);
    RelocalizationResult second = localized(pose(40.1, {3.01, -2.0, 0.1}), false);
    second.polish_refused = true;
    EXPECT_EQ(c.offer(second, query_at({4, 0, 0}, true)), ConfirmationVerdict::kAccepted);
    EXPECT_TRUE(c.accepted_T_prior_world().isApprox(second.T_prior_world));
  }
  {
    // A held unpolished fit confirmed by an agreeing NDT fit whose polish was not tried: the latter kept.
    RelocalizationConfirmation c;
    EXPECT_EQ(c.offer(unpolished, query_at({1, 0, 0}, true)), ConfirmationVerdict::kPending);
    const RelocalizationResult ndt = localized(pose(41.4, {3.07, -1.93, 0.1}), false);
    EXPECT_EQ(c.offer(ndt, query_at({4, 0, 0}, true)), ConfirmationVerdict::kAccepted);
    EXPECT_TRUE(c.accepted_T_prior_world().isApprox(ndt.T_prior_world));
  }
  RelocalizationConfirmationConfig no_unpolished;
  no_unpolished.confirm_unpolished = false;
  RelocalizationConfirmation c(no_unpolished);
  EXPECT_EQ(c.offer(unpolished, query_at({1, 0, 0}, true)), ConfirmationVerdict::kAccepted);
}

// outdoor f4708 (seed 4, no GNSS): a weak fit 49 m off at 8.29 m of motion, the same wrong pose again
// from 0.7 m further on (the same view: the same evidence), which confirmed it.
TEST(RelocalizationConfirmation, GivenAnAgreeingFitFromNearTheHeldOnesCameraThenItConfirmsNothing) {
  RelocalizationConfirmation c;  // min_separation_m 2
  ASSERT_EQ(c.offer(localized(kRepeat, true), query_at({8.29, 0, 0}, false)), ConfirmationVerdict::kPending);
  EXPECT_EQ(c.offer(localized(kRepeat, true), query_at({9.01, 0, 0}, false)), ConfirmationVerdict::kPending);
  EXPECT_FALSE(c.accepted());
  EXPECT_EQ(c.superseded(), 0);  // the held fit and its camera kept: the separation counts from there
  EXPECT_EQ(c.offer(localized(kRepeat, true), query_at({10.1, 0, 0}, false)), ConfirmationVerdict::kPending);
  // A weak fit elsewhere (the right place, 11.18 m) replaces it; a fit that needs no confirmation
  // is accepted at once, near or not.
  EXPECT_EQ(c.offer(localized(kTrue, true), query_at({11.18, 0, 0}, false)), ConfirmationVerdict::kPending);
  EXPECT_EQ(c.superseded(), 1);
  EXPECT_EQ(c.offer(localized(kTrue, false), query_at({12.26, 0, 0}, false)), ConfirmationVerdict::kAccepted);
  EXPECT_TRUE(c.accepted_T_prior_world().isApprox(kTrue));

  // Far enough along (2 m): the held fit is confirmed.
  RelocalizationConfirmation d;
  ASSERT_EQ(d.offer(localized(kTrue, true), query_at({1, 0, 0}, false)), ConfirmationVerdict::kPending);
  EXPECT_EQ(d.offer(localized(kTrue, true), query_at({2.5, 0, 0}, false)), ConfirmationVerdict::kPending);
  EXPECT_EQ(d.offer(localized(kTrue, true), query_at({1, 2.1, 0}, false)), ConfirmationVerdict::kAccepted);

  RelocalizationConfirmationConfig none;
  none.min_separation_m = 0.0;
  RelocalizationConfirmation e(none);
  ASSERT_EQ(e.offer(localized(kRepeat, true), query_at({8.29, 0, 0}, false)), ConfirmationVerdict::kPending);
  EXPECT_EQ(e.offer(localized(kRepeat, true), query_at({8.29, 0, 0}, false)), ConfirmationVerdict::kAccepted);
}

TEST(RelocalizationConfirmation, GivenTwoPosesThenTheyAgreeWithinTheLimitsAtTheLaterCamera) {
  RelocalizationConfirmation c;  // 10 cm, 1 deg
  const Eigen::Isometry3d cam = pose(0.0, {10.0, 0.0, 0.0});
  EXPECT_TRUE(c.agree(kTrue, pose(40.0, {3.08, -2.0, 0.1}), cam));
  EXPECT_FALSE(c.agree(kTrue, pose(40.0, {3.12, -2.0, 0.1}), cam));
  EXPECT_FALSE(c.agree(kTrue, pose(41.5, {3.0, -2.0, 0.1}), cam));  // 1.5 deg
  // 0.5 deg about the world origin moves a camera 7 m from it by 6.1 cm (agree), one 20 m away by 17.5 cm.
  EXPECT_TRUE(c.agree(kTrue, pose(40.5, {3.0, -2.0, 0.1}), pose(0.0, {7.0, 0.0, 0.0})));
  EXPECT_FALSE(c.agree(kTrue, pose(40.5, {3.0, -2.0, 0.1}), pose(0.0, {20.0, 0.0, 0.0})));
}

}  // namespace
}  // namespace hwr::recon
