// PlaneMoments and fit_plane: closed-form planes, merge = union, degenerate inputs.
#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "hwr/detect/plane_fit.hpp"

namespace hwr::detect {
namespace {

// An orthonormal pair spanning the plane of unit normal n.
void plane_basis(const Eigen::Vector3d& n, Eigen::Vector3d* e1, Eigen::Vector3d* e2) {
  *e1 = n.unitOrthogonal();
  *e2 = n.cross(*e1);
}

PlaneMoments moments_of(const std::vector<Eigen::Vector3d>& points) {
  PlaneMoments m;
  for (const Eigen::Vector3d& p : points) m.add(p);
  return m;
}

TEST(PlaneMoments, GivenTwoPointSetsThenTheMergedMomentsAreTheMomentsOfTheUnion) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::vector<Eigen::Vector3d> a, b, all;
  for (int i = 0; i < 17; ++i) a.emplace_back(u(rng), u(rng), 1.0 + std::abs(u(rng)));
  for (int i = 0; i < 9; ++i) b.emplace_back(u(rng), u(rng), 1.0 + std::abs(u(rng)));
  all = a;
  all.insert(all.end(), b.begin(), b.end());
  PlaneMoments merged = moments_of(a);
  merged.merge(moments_of(b));
  const PlaneMoments direct = moments_of(all);
  EXPECT_EQ(merged.n, 26.0);
  EXPECT_LT((merged.sum - direct.sum).norm(), 1e-12);
  EXPECT_LT((merged.sum_outer - direct.sum_outer).norm(), 1e-12);
  const PlaneFit fm = fit_plane(merged), fd = fit_plane(direct);
  ASSERT_TRUE(fm.ok && fd.ok);
  EXPECT_LT((fm.normal - fd.normal).norm(), 1e-12);
  EXPECT_NEAR(fm.d, fd.d, 1e-12);

  PlaneMoments empty;
  empty.merge(direct);
  EXPECT_EQ(empty.n, direct.n);
  EXPECT_LT((empty.sum_outer - direct.sum_outer).norm(), 1e-15);
}

// Points exactly on n . p = d at 1-2 m in front of the camera: the fit is that plane, its normal the
// one facing the origin (the camera) whichever sign the truth was written with.
TEST(PlaneFit, GivenPointsOnAKnownPlaneThenThePlaneIsRecoveredTo1e9WithTheNormalFacingTheCamera) {
  const Eigen::Vector3d p0(0.2, -0.1, 1.6);
  for (const Eigen::Vector3d& written :
       {Eigen::Vector3d(0.3, -0.5, 0.8), Eigen::Vector3d(-0.3, 0.5, -0.8), Eigen::Vector3d(0.0, -1.0, 0.0)}) {
    const Eigen::Vector3d n = written.normalized();
    Eigen::Vector3d e1, e2;
    plane_basis(n, &e1, &e2);
    std::vector<Eigen::Vector3d> points;
    for (int i = -5; i <= 5; ++i) {
      for (int j = -3; j <= 4; ++j) points.push_back(p0 + 0.05 * i * e1 + 0.07 * j * e2);
    }
    const PlaneFit fit = fit_plane(moments_of(points));
    ASSERT_TRUE(fit.ok);
    const Eigen::Vector3d facing = n.dot(p0) <= 0.0 ? n : Eigen::Vector3d(-n);
    EXPECT_LT((fit.normal - facing).norm(), 1e-9) << "written normal " << written.transpose();
    EXPECT_NEAR(fit.d, facing.dot(p0), 1e-9);
    EXPECT_LE(fit.d, 0.0);
    EXPECT_LE(fit.normal.dot(fit.centroid), 0.0);
    EXPECT_NEAR(fit.normal.norm(), 1.0, 1e-12);
    EXPECT_LT(fit.rms_m, 1e-6);  // sqrt of the scatter's cancellation error, ~1e-8
    for (const Eigen::Vector3d& p : points) EXPECT_NEAR(fit.signed_distance(p), 0.0, 1e-9);
  }
}

// A 4x4 grid with offsets +-e in a checkerboard: the offsets are uncorrelated with both in-plane
// coordinates and sum to zero, so the plane is unchanged and every point is e from it: RMS = e.
TEST(PlaneFit, GivenCheckerboardOffsetsOfPlusMinusEThenThePlaneIsUnchangedAndTheRmsIsE) {
  const Eigen::Vector3d n = Eigen::Vector3d(0.1, -0.9, -0.4).normalized();
  const Eigen::Vector3d p0(0.0, 0.3, 2.0);
  Eigen::Vector3d e1, e2;
  plane_basis(n, &e1, &e2);
  const double e = 0.002;
  PlaneMoments m;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      const double sign = (i + j) % 2 == 0 ? 1.0 : -1.0;
      m.add(p0 + 0.1 * (i - 1.5) * e1 + 0.1 * (j - 1.5) * e2 + sign * e * n);
    }
  }
  const PlaneFit fit = fit_plane(m);
  ASSERT_TRUE(fit.ok);
  const Eigen::Vector3d facing = n.dot(p0) <= 0.0 ? n : Eigen::Vector3d(-n);
  EXPECT_LT((fit.normal - facing).norm(), 1e-9);
  EXPECT_NEAR(fit.d, facing.dot(p0), 1e-9);
  EXPECT_NEAR(fit.rms_m, e, 1e-9);
}

TEST(PlaneFit, GivenFewerThanThreeCollinearOrCoincidentPointsThenNotOk) {
  EXPECT_FALSE(fit_plane(PlaneMoments{}).ok);
  EXPECT_FALSE(fit_plane(moments_of({{0, 0, 1}, {1, 0, 1}})).ok);

  const Eigen::Vector3d a(0.3, -0.2, 1.4), dir = Eigen::Vector3d(0.2, 0.7, 0.1).normalized();
  std::vector<Eigen::Vector3d> line;
  for (int i = 0; i < 40; ++i) line.push_back(a + 0.013 * i * dir);
  EXPECT_FALSE(fit_plane(moments_of(line)).ok);

  EXPECT_FALSE(fit_plane(moments_of(std::vector<Eigen::Vector3d>(10, a))).ok);

  // Three points off the line: a plane, through them exactly.
  const PlaneFit three = fit_plane(moments_of({{0, 0, 1}, {1, 0, 1}, {0, 1, 2}}));
  ASSERT_TRUE(three.ok);
  EXPECT_LT((three.normal - Eigen::Vector3d(0, 1, -1).normalized()).norm(), 1e-9);
  EXPECT_NEAR(three.d, -1.0 / std::sqrt(2.0), 1e-9);
}

}  // namespace
}  // namespace hwr::detect
