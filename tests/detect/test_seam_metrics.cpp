// Seam scoring against the truth (detect/seam_metrics.hpp): constructed segments with known offsets,
// and the visible part of a rendered fillet (depth_render.hpp).

#include <gtest/gtest.h>

#include "depth_render.hpp"
#include "hwr/detect/seam_metrics.hpp"

namespace hwr::detect {
namespace {

SeamSegment seg(const Eigen::Vector3d& a, const Eigen::Vector3d& b, SeamKind kind = SeamKind::kFillet) {
  SeamSegment s;
  s.a = a;
  s.b = b;
  s.kind = kind;
  return s;
}

const SeamSegment kTruth = seg({0, 0, 0.86}, {0.6, 0, 0.86});

TEST(SeamMetrics, GivenKnownOffsetsThenMatchesLateralAndEndpointErrorsFollow) {
  {
    const SeamScore s = score_seams({kTruth}, {kTruth});
    EXPECT_EQ(s.matched, 1);
    EXPECT_DOUBLE_EQ(s.precision(), 1.0);
    EXPECT_DOUBLE_EQ(s.recall(), 1.0);
    EXPECT_NEAR(s.matches[0].lateral_m, 0.0, 1e-12);
  }
  {
    // 10 mm sideways, 4 mm short at the start: matched, errors as built.
    const SeamScore s = score_seams({seg({0.004, 0.01, 0.86}, {0.6, 0.01, 0.86})}, {kTruth});
    ASSERT_EQ(s.matched, 1);
    EXPECT_NEAR(s.matches[0].lateral_m, 0.01, 1e-12);
    EXPECT_NEAR(s.matches[0].endpoint_m[0], std::hypot(0.004, 0.01), 1e-12);
    EXPECT_NEAR(s.matches[0].endpoint_m[1], 0.01, 1e-12);
    EXPECT_TRUE(s.matches[0].endpoint_valid[0] && s.matches[0].endpoint_valid[1]);
  }
  // 25 mm sideways, 15 deg off, too short an overlap, another kind: no match.
  EXPECT_EQ(score_seams({seg({0, 0.025, 0.86}, {0.6, 0.025, 0.86})}, {kTruth}).matched, 0);
  EXPECT_EQ(score_seams({seg({0, 0, 0.86}, {0.6, 0.6 * std::tan(0.26), 0.86})}, {kTruth}).matched, 0);
  EXPECT_EQ(score_seams({seg({0.5, 0, 0.86}, {0.9, 0, 0.86})}, {kTruth}).matched, 0);
  EXPECT_EQ(score_seams({seg({0, 0, 0.86}, {0.6, 0, 0.86}, SeamKind::kButt)}, {kTruth}).matched, 0);
  {
    // Reversed: its ends pair with the truth's the other way round; an unobserved end is no error.
    SeamSegment r = seg({0.6, 0, 0.86}, {0.003, 0, 0.86});
    r.end_known = {true, false};
    const SeamScore s = score_seams({r}, {kTruth});
    ASSERT_EQ(s.matched, 1);
    EXPECT_NEAR(s.matches[0].endpoint_m[0], 0.0, 1e-12);
    EXPECT_NEAR(s.matches[0].endpoint_m[1], 0.003, 1e-12);
    EXPECT_TRUE(s.matches[0].endpoint_valid[0]);
    EXPECT_FALSE(s.matches[0].endpoint_valid[1]);
  }
  {
    // The same seam detected twice: one match, precision 1/2; a second truth unmatched: recall 1/2.
    const SeamScore s = score_seams({kTruth, kTruth}, {kTruth, seg({0, 1, 0.86}, {0.6, 1, 0.86})});
    EXPECT_EQ(s.matched, 1);
    EXPECT_DOUBLE_EQ(s.precision(), 0.5);
    EXPECT_DOUBLE_EQ(s.recall(), 0.5);
  }
  EXPECT_DOUBLE_EQ(score_seams({}, {}).precision(), 1.0);
}

TEST(SeamMetrics, GivenARenderedFilletThenItsSeamIsVisibleOnlyFromItsOpenSideAndNotBehindABox) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  testing::RenderScene scene;
  scene.has_floor = true;
  scene.floor_z_m = 0.85;
  const testing::FilletJoint j = testing::make_fillet({-0.3, 0.1, 0.86}, 0.0, 0.6, 0.3, 0.2, 0.01, 2, 3);
  scene.boxes = {j.base, j.web};
  SeamSegment truth = seg(j.start_world, j.end_world);
  truth.open_side = -Eigen::Vector3d::UnitY();  // the base lies towards -y of the web
  const DepthNoiseModel noise;
  SeamSegment seen;
  {
    const Eigen::Isometry3d T = testing::look_at({0, -1.3, 1.55}, {0, 0, 0.9});
    const testing::RenderedDepth r = testing::render_depth(scene, K, T);
    ASSERT_TRUE(visible_seam_part(truth, T, K, r.depth_m, noise, 0.3, 3.5, 0.1, &seen));
    EXPECT_TRUE(seen.end_known[0] && seen.end_known[1]);
    EXPECT_NEAR((seen.a - j.start_world).norm(), 0.0, 1e-9);
    EXPECT_NEAR((seen.b - j.end_world).norm(), 0.0, 1e-9);
  }
  {
    const Eigen::Isometry3d T = testing::look_at({0, 1.5, 1.55}, {0, 0, 0.9});  // behind the web
    const testing::RenderedDepth r = testing::render_depth(scene, K, T);
    EXPECT_FALSE(visible_seam_part(truth, T, K, r.depth_m, noise, 0.3, 3.5, 0.1, &seen));
  }
  {
    // A box in front hides the seam's -x half: the part seen starts past it, that end unknown.
    testing::RenderBox box;
    box.T_world_box.translation() = Eigen::Vector3d(-0.2, -0.6, 1.0);
    box.half_size_m = Eigen::Vector3d(0.2, 0.05, 0.3);
    box.id = 4;
    scene.boxes.push_back(box);
    const Eigen::Isometry3d T = testing::look_at({0, -1.3, 1.55}, {0, 0, 0.9});
    const testing::RenderedDepth r = testing::render_depth(scene, K, T);
    ASSERT_TRUE(visible_seam_part(truth, T, K, r.depth_m, noise, 0.3, 3.5, 0.1, &seen));
    EXPECT_FALSE(seen.end_known[0]);
    EXPECT_TRUE(seen.end_known[1]);
    EXPECT_GT(seen.a.x(), -0.2);
  }
}

}  // namespace
}  // namespace hwr::detect
