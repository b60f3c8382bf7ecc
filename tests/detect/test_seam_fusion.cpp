// Fusion of seam detections over keyframes (detect/seam_fusion.hpp): constructed detections of known
// seams, some with an end cut by the image border, some only supporting.

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "hwr/detect/seam_fusion.hpp"

namespace hwr::detect {
namespace {

Detection seen(const Eigen::Vector3d& a, const Eigen::Vector3d& b, bool a_seen = true, bool b_seen = true) {
  Detection d;
  d.seam_world = {a, b};
  d.end_observed = {a_seen, b_seen};
  return d;
}

TEST(SeamFusion, GivenViewsOfOneSeamThenItsLineAndItsSeenEndsAreFusedAndCutEndsOnlyWidenIt) {
  SeamFusion f;
  // The seam from (0, 0, 0.86) to (0.6, 0, 0.86): three views with millimetre errors, one reversed, one
  // cut at the +x end by the border (its end at 0.45 m says nothing of the true end).
  EXPECT_TRUE(f.add(seen({0.002, 0.001, 0.86}, {0.599, 0.001, 0.86})));
  EXPECT_TRUE(f.add(seen({0.601, -0.001, 0.861}, {-0.001, -0.001, 0.861})));
  EXPECT_TRUE(f.add(seen({0.000, 0.000, 0.859}, {0.45, 0.000, 0.859}, true, false)));
  // Another seam 1 m away, seen once: a track, not reported (min_detections 2).
  EXPECT_TRUE(f.add(seen({0, 1, 0.86}, {0.6, 1, 0.86})));
  EXPECT_EQ(f.tracks(), 2);
  const std::vector<FusedSeam> fused = f.fused();
  ASSERT_EQ(fused.size(), 1u);
  EXPECT_EQ(fused[0].detections, 3);
  EXPECT_TRUE(fused[0].seam.end_known[0] && fused[0].seam.end_known[1]);
  const Eigen::Vector3d lo = fused[0].seam.a.x() < fused[0].seam.b.x() ? fused[0].seam.a : fused[0].seam.b;
  const Eigen::Vector3d hi = fused[0].seam.a.x() < fused[0].seam.b.x() ? fused[0].seam.b : fused[0].seam.a;
  // Medians of the seen ends: 0.000 (of 0.002, -0.001, 0.000) and 0.600 (of 0.599, 0.601).
  EXPECT_NEAR(lo.x(), 0.0, 1e-3);
  EXPECT_NEAR(hi.x(), 0.600, 1e-3);
  EXPECT_NEAR(lo.y(), 0.0, 1e-3);
  EXPECT_NEAR(hi.z(), 0.86, 1e-3);
}

// A robot's fusion lives for the whole run: each end keeps at most max_ends_per_track seen ends, the
// first ones, and its median is theirs.
TEST(SeamFusion, GivenMoreSeenEndsThanItKeepsThenTheMedianIsOfTheFirstOnes) {
  SeamFusionConfig c;
  c.max_ends_per_track = 3;
  SeamFusion f(c);
  for (double x0 : {0.000, 0.001, 0.002, 0.050, 0.050, 0.050, 0.050})
    EXPECT_TRUE(f.add(seen({x0, 0, 0}, {0.6, 0, 0})));
  const std::vector<FusedSeam> fused = f.fused();
  ASSERT_EQ(fused.size(), 1u);
  EXPECT_EQ(fused[0].detections, 7);
  const double lo = std::min(fused[0].seam.a.x(), fused[0].seam.b.x());
  EXPECT_NEAR(lo, 0.001, 2e-3);  // all seven would give 0.050
}

TEST(SeamFusion, GivenASeamWhoseEndNoViewSawThenThatEndIsTheExtentAndUnknown) {
  SeamFusion f;
  EXPECT_TRUE(f.add(seen({0, 0, 0}, {0.5, 0, 0}, true, false)));
  EXPECT_TRUE(f.add(seen({0, 0, 0}, {0.7, 0, 0}, true, false)));
  const std::vector<FusedSeam> fused = f.fused();
  ASSERT_EQ(fused.size(), 1u);
  EXPECT_TRUE(fused[0].seam.end_known[0]);
  EXPECT_FALSE(fused[0].seam.end_known[1]);
  EXPECT_NEAR(fused[0].seam.b.x(), 0.7, 1e-9);  // the farthest any view reached
  // A detection of another kind, or one 3 cm aside, starts its own track.
  Detection butt = seen({0, 0, 0}, {0.5, 0, 0});
  butt.kind = SeamKind::kButt;
  EXPECT_TRUE(f.add(butt));
  EXPECT_TRUE(f.add(seen({0, 0.03, 0}, {0.5, 0.03, 0})));
  EXPECT_EQ(f.tracks(), 3);
  SeamFusionConfig one;
  one.max_tracks = 1;
  SeamFusion g(one);
  EXPECT_TRUE(g.add(seen({0, 0, 0}, {0.5, 0, 0})));
  EXPECT_FALSE(g.add(seen({0, 1, 0}, {0.5, 1, 0})));  // no track matched, the table is full
  EXPECT_FALSE(g.add(seen({0, 0, 0}, {0, 0, 0})));    // no length
}

Detection supporting(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  Detection d = seen(a, b);
  d.support_only = true;
  return d;
}

// GIVEN supporting detections (below the detector's bar) of two seams, and one confident detection of
//       the first, after them
// WHEN fused
// THEN the first seam is reported with every detection (the supporting ones too), the second, only
//      ever supported, is not, however often it was seen.
TEST(SeamFusion, GivenSupportingDetectionsThenOnlyASeamAConfidentDetectionFoundIsReported) {
  SeamFusion f;
  for (int i = 0; i < 5; ++i) {
    EXPECT_TRUE(f.add(supporting({0.001 * i, 0, 0}, {0.6, 0.001 * i, 0})));
    EXPECT_TRUE(f.add(supporting({0, 1, 0}, {0.6, 1, 0})));
  }
  EXPECT_EQ(f.tracks(), 2);
  EXPECT_TRUE(f.fused().empty());
  EXPECT_TRUE(f.add(seen({0, 0.001, 0}, {0.6, 0, 0})));
  const std::vector<FusedSeam> fused = f.fused();
  ASSERT_EQ(fused.size(), 1u);
  EXPECT_EQ(fused[0].detections, 6);
  EXPECT_NEAR(std::max(fused[0].seam.a.y(), fused[0].seam.b.y()), 0.0, 0.005);
}

// GIVEN a table of two tracks, one confirmed, one only supported
// WHEN a detection of a third seam comes
// THEN it replaces the only-supported track (the table stays bounded) and the confirmed one stays;
//      once both are confirmed, a new seam finds no room.
TEST(SeamFusion, GivenAFullTableThenAnOnlySupportedTrackMakesRoomAndConfirmedOnesStay) {
  SeamFusionConfig c;
  c.max_tracks = 2;
  SeamFusion f(c);
  EXPECT_TRUE(f.add(seen({0, 0, 0}, {0.6, 0, 0})));
  EXPECT_TRUE(f.add(seen({0, 0, 0}, {0.6, 0, 0})));
  EXPECT_TRUE(f.add(supporting({0, 1, 0}, {0.6, 1, 0})));
  EXPECT_TRUE(f.add(seen({0, 2, 0}, {0.6, 2, 0})));  // replaces the track at y = 1
  EXPECT_EQ(f.tracks(), 2);
  EXPECT_TRUE(f.add(seen({0, 2, 0}, {0.6, 2, 0})));
  const std::vector<FusedSeam> fused = f.fused();
  ASSERT_EQ(fused.size(), 2u);
  for (const FusedSeam& s : fused) EXPECT_NEAR(std::fabs(s.seam.a.y() - 1.0), 1.0, 1e-9);  // y 0 and 2
  EXPECT_FALSE(f.add(supporting({0, 3, 0}, {0.6, 3, 0})));  // both confirmed: no room
}

}  // namespace
}  // namespace hwr::detect
