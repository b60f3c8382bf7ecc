// Two-view triangulation (estimation/triangulation.hpp, paper eq. 4): exact on noise-free views,
// and each rejection reported for the geometry that causes it.

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "hwr/core/so3.hpp"
#include "hwr/estimation/triangulation.hpp"
#include "hwr/hal/tum_dataset.hpp"

namespace hwr::estimation {
namespace {

Eigen::Vector2d project(const Eigen::Isometry3d& T_cam_world, const hal::PinholeIntrinsics& K,
                        const Eigen::Vector3d& p_world) {
  const Eigen::Vector3d p = T_cam_world * p_world;
  return {K.fx * p.x() / p.z() + K.cx, K.fy * p.y() / p.z() + K.cy};
}

Eigen::Isometry3d camera(const Eigen::Vector3d& rotvec, const Eigen::Vector3d& centre_world) {
  // T_cam_world for a camera at centre_world with orientation R_world_cam = exp(rotvec).
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  T_world_cam.linear() = core::so3_exp(rotvec);
  T_world_cam.translation() = centre_world;
  return T_world_cam.inverse();
}

TEST(Triangulation, NoiseFreeViewsAreExact) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-1, 1), z(1, 10);
  const hal::PinholeIntrinsics K0 = hal::tum_fr3_intrinsics();
  hal::PinholeIntrinsics K1 = K0;
  K1.fx = 600, K1.fy = 610, K1.cx = 330, K1.cy = 240;
  int ok = 0;
  double worst = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const Eigen::Isometry3d T0 =
        camera(0.3 * Eigen::Vector3d(u(rng), u(rng), u(rng)), Eigen::Vector3d(u(rng), u(rng), u(rng)));
    // The second camera 0.3-1 m away, looking at the same region.
    const Eigen::Vector3d c0 = T0.inverse().translation();
    const Eigen::Vector3d c1 =
        c0 + (0.3 + 0.7 * std::abs(u(rng))) * Eigen::Vector3d(u(rng), u(rng), 0.2 * u(rng)).normalized();
    const Eigen::Vector3d rotvec1 =
        core::so3_log(T0.inverse().linear()) + 0.05 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    const Eigen::Isometry3d T1 = camera(rotvec1, c1);
    const Eigen::Vector3d p_cam0(u(rng) * 1.5, u(rng) * 1.0, z(rng));
    const Eigen::Vector3d p_world = T0.inverse() * p_cam0;
    if ((T1 * p_world).z() < 0.5) continue;
    Eigen::Vector3d est;
    TriangulationConfig cfg;
    cfg.min_parallax_deg = 0.5;
    const TriangulationStatus st =
        triangulate_two_view(T0, T1, K0, K1, project(T0, K0, p_world), project(T1, K1, p_world), cfg, &est);
    if (st == TriangulationStatus::kLowParallax) continue;
    ASSERT_EQ(st, TriangulationStatus::kOk) << to_string(st);
    worst = std::max(worst, (est - p_world).norm());
    ++ok;
  }
  EXPECT_GT(ok, 150);
  EXPECT_LT(worst, 1e-9);
}

struct TwoViews {
  hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  Eigen::Isometry3d T0 = camera(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  Eigen::Isometry3d T1 =
      camera(Eigen::Vector3d(0, -0.05, 0), Eigen::Vector3d(0.3, 0, 0));  // 30 cm to the right
  Eigen::Vector3d p_world{0.2, -0.1, 3.0};
};

TEST(Triangulation, ReportsLowParallax) {
  TwoViews v;
  Eigen::Vector3d est;
  // 1 cm baseline at 3 m: 0.2 deg of parallax.
  const Eigen::Isometry3d T1 = camera(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.01, 0, 0));
  EXPECT_EQ(triangulate_two_view(v.T0, T1, v.K, v.K, project(v.T0, v.K, v.p_world),
                                 project(T1, v.K, v.p_world), TriangulationConfig{}, &est),
            TriangulationStatus::kLowParallax);
  // The same point with 30 cm baseline is fine (5.7 deg).
  EXPECT_EQ(triangulate_two_view(v.T0, v.T1, v.K, v.K, project(v.T0, v.K, v.p_world),
                                 project(v.T1, v.K, v.p_world), TriangulationConfig{}, &est),
            TriangulationStatus::kOk);
  EXPECT_LT((est - v.p_world).norm(), 1e-9);
}

TEST(Triangulation, ReportsPointBehindACamera) {
  TwoViews v;
  Eigen::Vector3d est;
  // Camera 1 stands 5 m ahead, looking back at camera 0: the point at 3 m is in front of both...
  const Eigen::Isometry3d T1 = camera(Eigen::Vector3d(0, M_PI * 0.95, 0), Eigen::Vector3d(0.5, 0, 6.0));
  ASSERT_GT((T1 * v.p_world).z(), 0);
  EXPECT_EQ(triangulate_two_view(v.T0, T1, v.K, v.K, project(v.T0, v.K, v.p_world),
                                 project(T1, v.K, v.p_world), TriangulationConfig{}, &est),
            TriangulationStatus::kOk);
  // ...a point behind camera 0 projects to a valid pixel of camera 0 (through the centre) and
  // triangulates behind it.
  const Eigen::Vector3d behind(-0.2, 0.1, -3.0);
  EXPECT_EQ(triangulate_two_view(v.T0, T1, v.K, v.K, project(v.T0, v.K, behind), project(T1, v.K, behind),
                                 TriangulationConfig{}, &est),
            TriangulationStatus::kBehindCamera);
  EXPECT_LT((est - behind).norm(), 1e-9);
  // Beyond max_depth_m.
  TriangulationConfig near_only;
  near_only.max_depth_m = 2.0;
  EXPECT_EQ(triangulate_two_view(v.T0, v.T1, v.K, v.K, project(v.T0, v.K, v.p_world),
                                 project(v.T1, v.K, v.p_world), near_only, &est),
            TriangulationStatus::kBehindCamera);
}

TEST(Triangulation, ReportsLargeReprojection) {
  TwoViews v;
  Eigen::Vector3d est;
  // Baseline along x: epipolar lines are near-horizontal, so moving the second observation 10 px
  // vertically makes the rays skew; the DLT point misses both observations by several pixels.
  const Eigen::Vector2d uv1 = project(v.T1, v.K, v.p_world) + Eigen::Vector2d(0, 10);
  EXPECT_EQ(triangulate_two_view(v.T0, v.T1, v.K, v.K, project(v.T0, v.K, v.p_world), uv1,
                                 TriangulationConfig{}, &est),
            TriangulationStatus::kLargeReprojection);
  // 1 px is within the 2 px tolerance.
  const Eigen::Vector2d uv1_small = project(v.T1, v.K, v.p_world) + Eigen::Vector2d(0, 1);
  EXPECT_EQ(triangulate_two_view(v.T0, v.T1, v.K, v.K, project(v.T0, v.K, v.p_world), uv1_small,
                                 TriangulationConfig{}, &est),
            TriangulationStatus::kOk);
}

TEST(Triangulation, InvalidIntrinsicsAreDegenerate) {
  TwoViews v;
  Eigen::Vector3d est;
  EXPECT_EQ(triangulate_two_view(v.T0, v.T1, hal::PinholeIntrinsics{}, v.K, Eigen::Vector2d(1, 1),
                                 Eigen::Vector2d(2, 2), TriangulationConfig{}, &est),
            TriangulationStatus::kDegenerate);
  EXPECT_STREQ(to_string(TriangulationStatus::kLowParallax), "low parallax");
}

}  // namespace
}  // namespace hwr::estimation
