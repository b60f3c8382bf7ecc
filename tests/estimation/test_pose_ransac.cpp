// PoseRansac, the Lambda Twist P3P solver and the 3D-3D rigid fit (estimation/pose_ransac.hpp)
// against synthetic scenes with a known pose: exact on noise-free data, within tight tolerances
// with noise and 40 % outliers, with and without depth; allocation-free.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "hal/hal_test_util.hpp"
#include "hwr/core/alloc_counter.hpp"
#include "hwr/core/se3.hpp"
#include "hwr/estimation/lsh_matcher.hpp"
#include "hwr/estimation/orb_extractor.hpp"
#include "hwr/core/so3.hpp"
#include "hwr/estimation/pose_ransac.hpp"
#include "hwr/hal/tum_dataset.hpp"

namespace hwr::estimation {
namespace {

Eigen::Isometry3d random_pose(std::mt19937_64& rng, double max_angle, double max_t) {
  std::normal_distribution<double> g(0, 1);
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() =
      core::so3_exp(max_angle * std::abs(u(rng)) * Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized());
  T.translation() = max_t * Eigen::Vector3d(u(rng), u(rng), u(rng));
  return T;
}

double rotation_error_deg(const Eigen::Isometry3d& A, const Eigen::Isometry3d& B) {
  return core::so3_log(A.linear() * B.linear().transpose()).norm() * 180.0 / M_PI;
}

double translation_error_m(const Eigen::Isometry3d& A, const Eigen::Isometry3d& B) {
  // Camera centres.
  return (A.inverse().translation() - B.inverse().translation()).norm();
}

struct Scene {
  Eigen::Isometry3d T_cam_world;
  std::vector<Correspondence> c;
  std::vector<bool> is_outlier;
};

// n correspondences seen by a VGA camera at a random pose; a fraction are outliers (random pixel,
// random depth), the rest carry Gaussian pixel noise (sigma scaled by the octave) and depth noise.
Scene make_scene(std::mt19937_64& rng, int n, double outlier_frac, double px_sigma, double depth_sigma_rel,
                 bool with_depth) {
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  Scene s;
  s.T_cam_world = random_pose(rng, 0.8, 2.0);
  std::uniform_real_distribution<double> U(0, 640), V(0, 480), Z(0.8, 6.0), unit(0, 1);
  std::normal_distribution<double> g(0, 1);
  for (int i = 0; i < n; ++i) {
    Correspondence c;
    c.octave = i % 4;
    const double sigma = px_sigma * std::pow(1.2, c.octave);
    const double u = U(rng), v = V(rng), z = Z(rng);
    const Eigen::Vector3d p_cam((u - K.cx) * z / K.fx, (v - K.cy) * z / K.fy, z);
    c.p_world = s.T_cam_world.inverse() * p_cam;
    const bool outlier = unit(rng) < outlier_frac;
    if (outlier) {
      c.uv_px = Eigen::Vector2d(U(rng), V(rng));
      if (with_depth) c.depth_m = Z(rng);
    } else {
      c.uv_px = Eigen::Vector2d(u + sigma * g(rng), v + sigma * g(rng));
      if (with_depth) c.depth_m = z * (1.0 + depth_sigma_rel * g(rng));
    }
    s.c.push_back(c);
    s.is_outlier.push_back(outlier);
  }
  return s;
}

TEST(P3P, LambdaTwistExactOnNoiseFreeData) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(0, 640), V(0, 480), Z(0.5, 8.0);
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  int solved = 0;
  double worst_r = 0, worst_t = 0;
  for (int trial = 0; trial < 500; ++trial) {
    const Eigen::Isometry3d T = random_pose(rng, 3.0, 3.0);
    Eigen::Vector3d bearings[3], x_world[3];
    for (int k = 0; k < 3; ++k) {
      const double u = U(rng), v = V(rng), z = Z(rng);
      bearings[k] = Eigen::Vector3d((u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0);
      x_world[k] = T.inverse() * (bearings[k] * z);
    }
    std::array<Eigen::Isometry3d, 4> sols;
    const int n = p3p_lambda_twist(bearings, x_world, &sols);
    ASSERT_LE(n, 4);
    double best_r = 1e9, best_t = 1e9;
    for (int k = 0; k < n; ++k) {
      // Every solution explains the three observations.
      for (int j = 0; j < 3; ++j) {
        const Eigen::Vector3d p = sols[static_cast<size_t>(k)] * x_world[j];
        EXPECT_GT(p.z(), 0);
        EXPECT_NEAR((p / p.z() - bearings[j]).norm(), 0, 1e-6);
      }
      const double er = (sols[static_cast<size_t>(k)].linear() - T.linear()).norm();
      const double et = (sols[static_cast<size_t>(k)].translation() - T.translation()).norm();
      if (er + et < best_r + best_t) best_r = er, best_t = et;
    }
    if (best_r < 1e-9 && best_t < 1e-9) ++solved;
    worst_r = std::max(worst_r, best_r);
    worst_t = std::max(worst_t, best_t);
  }
  std::printf("P3P: %d/500 exact (1e-9); worst R %.2e, t %.2e\n", solved, worst_r, worst_t);
  EXPECT_GE(solved, 495);  // near-degenerate random triangles may lose a few digits
  EXPECT_LT(worst_r, 1e-6);
  EXPECT_LT(worst_t, 1e-6);
}

TEST(P3P, DegenerateInputsGiveNoSolution) {
  Eigen::Vector3d b[3] = {{0, 0, 1}, {0.1, 0, 1}, {0, 0.1, 1}};
  Eigen::Vector3d same[3] = {{1, 1, 1}, {1, 1, 1}, {0, 0, 5}};
  std::array<Eigen::Isometry3d, 4> sols;
  EXPECT_EQ(p3p_lambda_twist(b, same, &sols), 0);
}

TEST(RigidFit3d3d, ExactAndRejectsCollinear) {
  std::mt19937_64 rng(9);
  const Eigen::Isometry3d T = random_pose(rng, 3.0, 5.0);
  std::uniform_real_distribution<double> u(-3, 3);
  Eigen::Vector3d src[10], dst[10];
  for (int i = 0; i < 10; ++i) {
    src[i] = Eigen::Vector3d(u(rng), u(rng), u(rng));
    dst[i] = T * src[i];
  }
  Eigen::Isometry3d est;
  ASSERT_TRUE(rigid_fit_3d3d(src, dst, nullptr, 10, &est));
  EXPECT_LT((est.matrix() - T.matrix()).norm(), 1e-12);
  ASSERT_TRUE(rigid_fit_3d3d(src, dst, nullptr, 3, &est));
  EXPECT_LT((est.matrix() - T.matrix()).norm(), 1e-12);
  Eigen::Vector3d line[3] = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}};
  Eigen::Vector3d line_dst[3] = {T * line[0], T * line[1], T * line[2]};
  EXPECT_FALSE(rigid_fit_3d3d(line, line_dst, nullptr, 3, &est));
}

TEST(PoseRansac, NoiseFreeExactWithAndWithoutDepth) {
  std::mt19937_64 rng(21);
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  PoseRansac ransac(400);
  std::vector<uint8_t> mask(400);
  for (bool depth : {true, false}) {
    const Scene s = make_scene(rng, 300, 0.4, 0.0, 0.0, depth);
    PoseRansacConfig cfg;
    cfg.refine = false;  // the minimal solver alone
    const PoseRansacResult r = ransac.solve(s.c.data(), 300, K, cfg, mask.data());
    ASSERT_TRUE(r.ok);
    EXPECT_EQ(r.used_p3p, !depth);
    EXPECT_LT(rotation_error_deg(r.T_cam_world, s.T_cam_world), 1e-7);
    EXPECT_LT(translation_error_m(r.T_cam_world, s.T_cam_world), 1e-8);
    for (int i = 0; i < 300; ++i) {
      if (!s.is_outlier[static_cast<size_t>(i)]) {
        EXPECT_EQ(mask[static_cast<size_t>(i)], 1) << i;
      }
    }
  }
}

TEST(PoseRansac, FortyPercentOutliersWithNoise) {
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  PoseRansac ransac(500);
  std::vector<uint8_t> mask(500);
  for (bool depth : {true, false}) {
    std::mt19937_64 rng(depth ? 31 : 32);
    double worst_r = 0, worst_t = 0;
    int misses = 0, false_inliers = 0, outliers = 0, inliers = 0;
    for (int trial = 0; trial < 10; ++trial) {
      const Scene s = make_scene(rng, 400, 0.4, 0.7, 0.005, depth);
      PoseRansacConfig cfg;
      cfg.seed = static_cast<uint64_t>(trial + 1);
      uint64_t allocations = 0;
      PoseRansacResult r;
      {
        core::AllocationScope scope;
        r = ransac.solve(s.c.data(), 400, K, cfg, mask.data());
        allocations = scope.allocations();
      }
      EXPECT_EQ(allocations, 0u);
      ASSERT_TRUE(r.ok);
      EXPECT_EQ(r.used_p3p, !depth);
      worst_r = std::max(worst_r, rotation_error_deg(r.T_cam_world, s.T_cam_world));
      worst_t = std::max(worst_t, translation_error_m(r.T_cam_world, s.T_cam_world));
      for (int i = 0; i < 400; ++i) {
        if (s.is_outlier[static_cast<size_t>(i)]) {
          ++outliers;
          false_inliers += mask[static_cast<size_t>(i)];
        } else {
          ++inliers;
          misses += mask[static_cast<size_t>(i)] ? 0 : 1;
        }
      }
    }
    std::printf(
        "PoseRansac %s depth: worst rotation %.3f deg, camera centre %.4f m; missed %d/%d inliers, "
        "accepted %d/%d outliers\n",
        depth ? "with" : "without", worst_r, worst_t, misses, inliers, false_inliers, outliers);
    EXPECT_LT(worst_r, 0.2);
    EXPECT_LT(worst_t, 0.02);
    EXPECT_LT(misses, 0.03 * inliers);
    EXPECT_LT(false_inliers, 0.03 * outliers);  // a random pixel rarely lands within 3 px
  }
}

TEST(PoseRansac, FailsWithoutConsensus) {
  std::mt19937_64 rng(41);
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  PoseRansac ransac(100);
  std::vector<uint8_t> mask(100, 7);
  const Scene s = make_scene(rng, 100, 1.0, 0.0, 0.0, true);
  const PoseRansacResult r = ransac.solve(s.c.data(), 100, K, PoseRansacConfig{}, mask.data());
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.iterations, PoseRansacConfig{}.max_iterations);
  const PoseRansacResult r2 = ransac.solve(s.c.data(), 2, K, PoseRansacConfig{}, mask.data());
  EXPECT_FALSE(r2.ok);
  EXPECT_EQ(mask[0], 0);
}

// Real data, no pose prior: LSH matches between teddy frames 20 and 30 (frame 20's depth points
// placed with the ground truth) give frame 30's pose within 2 cm / 1 deg of the motion-capture truth,
// with the 3D-3D and with the P3P minimal solver.
TEST(PoseRansac, TeddyLshMatchesTenFramesApart) {
  HWR_REQUIRE_DATASET(hal::testing::kTeddyDir);
  auto ds = hal::TumDataset::open(hal::testing::kTeddyDir);
  ASSERT_TRUE(ds.ok()) << ds.status().to_string();
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  GridOrbExtractor extractor(OrbConfig{}, 640, 480);
  FrameFeatures fa(1000, 640, 480), fb(1000, 640, 480);
  Eigen::Isometry3d T_world_cam[2];
  hal::RgbdFrame frame;
  cv::Mat gray;
  const auto& gt = ds->groundtruth();
  for (int k = 0; k < 2; ++k) {
    const size_t index = k == 0 ? 20 : 30;
    ASSERT_TRUE(ds->load_frame(index, &frame).ok());
    const int64_t t = ds->frame_time_ns(index);
    auto it = std::lower_bound(gt.begin(), gt.end(), t,
                               [](const core::StampedPose& p, int64_t x) { return p.t_ns < x; });
    ASSERT_TRUE(it != gt.begin() && it != gt.end());
    const double alpha =
        static_cast<double>(t - (it - 1)->t_ns) / static_cast<double>(it->t_ns - (it - 1)->t_ns);
    T_world_cam[k] = core::se3_interpolate((it - 1)->T_world_body, it->T_world_body, alpha);
    cv::cvtColor(frame.bgr, gray, cv::COLOR_BGR2GRAY);
    ASSERT_TRUE(extractor.extract(gray, frame.depth_m, K, k == 0 ? &fa : &fb).ok());
  }
  LshMatcher lsh(1000, LshConfig{});
  lsh.build(fb);
  std::vector<FeatureMatch> matches(1000);
  const int m = lsh.match(fa, matches.data(), 1000);
  std::vector<Correspondence> c;
  for (int k = 0; k < m; ++k) {
    const Feature& a = fa.feature(matches[static_cast<size_t>(k)].query);
    const Feature& b = fb.feature(matches[static_cast<size_t>(k)].train);
    if (a.depth_m <= 0) continue;
    Correspondence x;
    x.p_world = T_world_cam[0] * a.p_cam_m;
    x.uv_px = Eigen::Vector2d(b.u_px, b.v_px);
    x.depth_m = b.depth_m;
    x.octave = b.octave;
    c.push_back(x);
  }
  ASSERT_GT(c.size(), 60u);
  PoseRansac ransac(1000);
  std::vector<uint8_t> mask(c.size());
  const Eigen::Isometry3d T_true = T_world_cam[1].inverse();
  for (bool p3p : {false, true}) {
    PoseRansacConfig cfg;
    if (p3p) cfg.min_depth_fraction = 2.0;  // force P3P
    const PoseRansacResult r = ransac.solve(c.data(), static_cast<int>(c.size()), K, cfg, mask.data());
    ASSERT_TRUE(r.ok);
    EXPECT_EQ(r.used_p3p, p3p);
    const double rot = rotation_error_deg(r.T_cam_world, T_true),
                 pos = translation_error_m(r.T_cam_world, T_true);
    std::printf(
        "teddy 20 -> 30 %s: %zu LSH correspondences, %d inliers, %d iterations; error %.4f m, %.3f deg\n",
        p3p ? "P3P" : "3D-3D", c.size(), r.inliers, r.iterations, pos, rot);
    EXPECT_LT(pos, 0.02);
    EXPECT_LT(rot, 1.0);
    EXPECT_GT(r.inliers, 0.6 * static_cast<double>(c.size()));
  }
}

}  // namespace
}  // namespace hwr::estimation
