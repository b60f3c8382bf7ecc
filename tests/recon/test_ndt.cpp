// The hand-written NDT (issue #4 item 3). Oracles: a known transform between two copies of a
// noise-free synthetic room (exact recovery); central differences of evaluate() (gradient and
// Hessian); closed-form degenerate inputs (too few points, one voxel, one plane, clouds apart);
// the same cloud with NaNs spliced in; one thread against four; the allocation counter.

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "hwr/core/alloc_counter.hpp"
#include "hwr/core/so3.hpp"
#include "hwr/recon/ndt.hpp"

namespace hwr::recon {
namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

constexpr double kDeg = M_PI / 180.0;

struct Cloud {
  std::vector<float> xyz;  // packed, stride 3
  int size() const { return static_cast<int>(xyz.size() / 3); }
  PointsView view() const { return {xyz.data(), size(), 3}; }
  void add(const Eigen::Vector3d& p) {
    xyz.push_back(static_cast<float>(p.x()));
    xyz.push_back(static_cast<float>(p.y()));
    xyz.push_back(static_cast<float>(p.z()));
  }
};

// A rectangle o + u a + v b (u, v in [0, 1]) sampled on a grid of `spacing_m`.
void add_patch(Cloud* c, const Eigen::Vector3d& o, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
               double spacing_m) {
  const int na = std::max(1, static_cast<int>(std::round(a.norm() / spacing_m)));
  const int nb = std::max(1, static_cast<int>(std::round(b.norm() / spacing_m)));
  for (int i = 0; i < na; ++i) {
    for (int j = 0; j < nb; ++j) c->add(o + (i + 0.5) / na * a + (j + 0.5) / nb * b);
  }
}

// The 6 faces of a box with corner o and edges a, b, h.
void add_box(Cloud* c, const Eigen::Vector3d& o, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
             const Eigen::Vector3d& h, double spacing_m) {
  add_patch(c, o, a, b, spacing_m);
  add_patch(c, o + h, a, b, spacing_m);
  add_patch(c, o, a, h, spacing_m);
  add_patch(c, o + b, a, h, spacing_m);
  add_patch(c, o, b, h, spacing_m);
  add_patch(c, o + a, b, h, spacing_m);
}

// A 8 x 6 x 3 m room (floor, ceiling, walls), a ramp, a slanted board and a few rotated boxes: every
// direction is constrained. The room is offset from the voxel grid (`kOff`): a wall lying exactly on
// voxel faces is a discontinuity of kDirect7's neighbourhoods (ndt.hpp).
const Eigen::Vector3d kOff(0.013, -0.021, -0.17);
Cloud room(double spacing_m, uint32_t seed = 7) {
  Cloud c;
  add_box(&c, kOff + Eigen::Vector3d(-4, -3, 0), {8, 0, 0}, {0, 6, 0}, {0, 0, 3}, spacing_m);
  add_patch(&c, kOff + Eigen::Vector3d(-3.5, -2.5, 0), {2.5, 0, 1.0}, {0, 1.5, 0}, spacing_m);  // ramp
  add_patch(&c, kOff + Eigen::Vector3d(1.0, 1.0, 0.2), {1.2, -1.0, 0.3}, {0.2, 0.3, 1.8},
            spacing_m);  // board
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  for (int k = 0; k < 5; ++k) {
    const Eigen::Matrix3d R = core::so3_exp(Eigen::Vector3d(0.3 * u(rng), 0.3 * u(rng), 3.0 * u(rng)));
    const Eigen::Vector3d o = kOff + Eigen::Vector3d(-3 + 6 * u(rng), -2 + 4 * u(rng), 0.0);
    add_box(&c, o, R * Eigen::Vector3d(0.4 + 0.6 * u(rng), 0, 0),
            R * Eigen::Vector3d(0, 0.4 + 0.6 * u(rng), 0), R * Eigen::Vector3d(0, 0, 0.3 + 1.2 * u(rng)),
            spacing_m);
  }
  return c;
}

Cloud transformed(const Cloud& c, const Eigen::Isometry3d& T) {
  Cloud out;
  for (int i = 0; i < c.size(); ++i) out.add(T * c.view().at(i).cast<double>());
  return out;
}

Eigen::Isometry3d pose(const Eigen::Vector3d& t, const Eigen::Vector3d& rotvec) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = core::so3_exp(rotvec);
  T.translation() = t;
  return T;
}

double translation_error_m(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.inverse() * b).translation().norm();
}
double rotation_error_rad(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return core::so3_log((a.inverse() * b).linear()).norm();
}

NdtAligner make_aligner(const NdtConfig& config = {}) {
  auto a = NdtAligner::create(config);
  EXPECT_TRUE(a.ok()) << a.status().to_string();
  return std::move(a.value());
}

// The target is the room; the source the same points seen from a pose T_true (source = T_true^-1 *
// target), so T_target_source = T_true exactly.
struct Pair {
  Cloud target, source;
  Eigen::Isometry3d T_true;
};
Pair room_pair(double spacing_m, const Eigen::Isometry3d& T_true) {
  Pair p;
  p.target = room(spacing_m);
  p.source = transformed(p.target, T_true.inverse());
  p.T_true = T_true;
  return p;
}

TEST(Ndt, GivenTwoCopiesOfANoiseFreeRoomThenTheKnownTransformIsRecovered) {
  const Pair p = room_pair(0.08, pose({0.4, -0.3, 0.1}, {0.02, -0.03, 8 * kDeg}));
  NdtAligner ndt = make_aligner();
  const NdtResult r = ndt.align(p.target.view(), p.source.view(), Eigen::Isometry3d::Identity());
  ASSERT_TRUE(r.converged) << ndt_failure_name(r.failure);
  EXPECT_EQ(r.failure, NdtFailure::kNone);
  EXPECT_EQ(r.levels, 3);
  EXPECT_LT(translation_error_m(r.T_target_source, p.T_true), 1e-3);
  EXPECT_LT(rotation_error_rad(r.T_target_source, p.T_true), 0.01 * kDeg);
  EXPECT_GT(r.inlier_ratio, 0.95);
  EXPECT_GT(r.fitness, 0.0);
  EXPECT_GT(r.score, 0.0);
}

// The pose of ndt.hpp's parameterisation, T(x) p = Exp(phi) (p - c) + c + t, and back.
Eigen::Isometry3d pose_of(const Vector6d& x, const Eigen::Vector3d& c) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = core::so3_exp(x.tail<3>());
  T.translation() = c - T.linear() * c + x.head<3>();
  return T;
}
Vector6d x_of(const Eigen::Isometry3d& T, const Eigen::Vector3d& c) {
  Vector6d x;
  x.tail<3>() = core::so3_log(T.linear());
  x.head<3>() = T.translation() - c + T.linear() * c;
  return x;
}

double max_abs(const Eigen::MatrixXd& m) { return m.cwiseAbs().maxCoeff(); }

// kDirect7's neighbourhoods change where a point crosses a voxel face, a jump in the cost that
// finite differences would see; the source keeps only points 5 mm or more from every face at the
// evaluated pose (the perturbations below move points by less than 2 mm).
Cloud away_from_faces(const Cloud& source, const Eigen::Isometry3d& T, double resolution_m) {
  Cloud out;
  for (int i = 0; i < source.size(); ++i) {
    const Eigen::Vector3d q = T * source.view().at(i).cast<double>();
    const Eigen::Vector3d frac = q / resolution_m - (q / resolution_m).array().floor().matrix();
    const double margin = resolution_m * std::min(frac.minCoeff(), 1.0 - frac.maxCoeff());
    if (margin > 5e-3) out.add(source.view().at(i).cast<double>());
  }
  return out;
}

TEST(Ndt, GivenAPoseAndPivotThenGradientAndHessianMatchCentralDifferences) {
  const Cloud target_cloud = room(0.15);
  NdtConfig config;
  auto target = NdtTarget::create(config);
  ASSERT_TRUE(target.ok());
  ASSERT_TRUE(target->build(target_cloud.view(), 1.0).ok());
  NdtAligner ndt = make_aligner(config);
  const Eigen::Vector3d c(0.7, -0.4, 1.1);
  Vector6d x0;
  x0 << 0.05, 0.02, -0.04, 0.02, -0.01, 0.05;  // off the optimum: the gradient is not zero
  const Cloud source = away_from_faces(
      transformed(target_cloud, pose({0.1, 0.05, -0.02}, {0.01, 0.02, 0.03}).inverse()), pose_of(x0, c), 1.0);
  ASSERT_GT(source.size(), target_cloud.size() / 2);
  Vector6d g;
  Matrix6d H;
  const double f0 = ndt.evaluate(*target, source.view(), x0, &g, &H, c);
  ASSERT_LT(f0, 0.0);
  // f at the left perturbation T(dx) * T(x0).
  auto f_at = [&](const Vector6d& dx) {
    return ndt.evaluate(*target, source.view(), x_of(pose_of(dx, c) * pose_of(x0, c), c), nullptr, nullptr,
                        c);
  };
  EXPECT_NEAR(f_at(Vector6d::Zero()), f0, 1e-9 * std::abs(f0));

  Vector6d g_num;
  Matrix6d H_num;
  const double h1 = 1e-6, h2 = 2e-5;
  for (int i = 0; i < 6; ++i) {
    const Vector6d ei = Vector6d::Unit(i);
    g_num(i) = (f_at(h1 * ei) - f_at(-h1 * ei)) / (2 * h1);
    for (int j = 0; j < 6; ++j) {
      const Vector6d ej = Vector6d::Unit(j);
      H_num(i, j) =
          (f_at(h2 * (ei + ej)) - f_at(h2 * (ei - ej)) - f_at(h2 * (ej - ei)) + f_at(-h2 * (ei + ej))) /
          (4 * h2 * h2);
    }
  }
  EXPECT_GT(g.norm(), 1.0);
  EXPECT_LT(max_abs(g - g_num), 1e-4 * max_abs(g))
      << "analytic " << g.transpose() << "\nnumeric  " << g_num.transpose();
  EXPECT_LT(max_abs(H - H_num), 1e-4 * max_abs(H)) << "analytic\n" << H << "\nnumeric\n" << H_num;
  // Without the pivot, at x = 0 on a pre-moved source: the plain derivatives in x.
  const Cloud moved =
      away_from_faces(transformed(source, pose_of(x0, c)), Eigen::Isometry3d::Identity(), 1.0);
  Vector6d g0;
  Matrix6d H0;
  ndt.evaluate(*target, moved.view(), Vector6d::Zero(), &g0, &H0);
  for (int i = 0; i < 6; ++i) {
    const Vector6d ei = Vector6d::Unit(i);
    g_num(i) = (ndt.evaluate(*target, moved.view(), h1 * ei, nullptr, nullptr) -
                ndt.evaluate(*target, moved.view(), -h1 * ei, nullptr, nullptr)) /
               (2 * h1);
  }
  EXPECT_LT(max_abs(g0 - g_num), 1e-4 * max_abs(g0));
}

TEST(Ndt, GivenAConvergedAlignmentThenItsScoreAndHessianAreEvaluatesAboutTheOrigin) {
  const Pair p = room_pair(0.12, pose({0.2, 0.1, 0.0}, {0.0, 0.0, 3 * kDeg}));
  NdtAligner ndt = make_aligner();
  const NdtResult r = ndt.align(p.target.view(), p.source.view(), Eigen::Isometry3d::Identity());
  ASSERT_TRUE(r.converged);
  auto target = NdtTarget::create(NdtConfig{});
  ASSERT_TRUE(target->build(p.target.view(), 0.5).ok());
  Matrix6d H;
  const double f =
      ndt.evaluate(*target, p.source.view(), x_of(r.T_target_source, Eigen::Vector3d::Zero()), nullptr, &H);
  EXPECT_NEAR(-f, r.score, 1e-9 * r.score);
  EXPECT_LT(max_abs(H - r.hessian), 1e-6 * max_abs(H));
}

TEST(Ndt, GivenTooFewSourcePointsThenNotConvergedWithThatReason) {
  const Cloud target = room(0.15);
  Cloud source;
  for (int i = 0; i < 5; ++i) source.add(target.view().at(i * 100).cast<double>());
  NdtAligner ndt = make_aligner();
  const Eigen::Isometry3d guess = pose({0.1, 0, 0}, {0, 0, 0.1});
  const NdtResult r = ndt.align(target.view(), source.view(), guess);
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(r.failure, NdtFailure::kTooFewSourcePoints);
  EXPECT_TRUE(r.T_target_source.isApprox(guess));
}

TEST(Ndt, GivenATargetInsideOneVoxelThenTooFewTargetVoxels) {
  Cloud target;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.05, 0.45);  // inside [0, 0.5)^3 at 2, 1 and 0.5 m
  for (int i = 0; i < 2000; ++i) target.add({u(rng), u(rng), u(rng)});
  NdtAligner ndt = make_aligner();
  const NdtResult r = ndt.align(target.view(), target.view(), Eigen::Isometry3d::Identity());
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(r.failure, NdtFailure::kTooFewTargetVoxels);
  EXPECT_TRUE(r.T_target_source.matrix().allFinite());
}

TEST(Ndt, GivenAFinestLevelWithoutGaussiansThenNotConvergedWhateverTheCoarserLevelsReached) {
  // 8 cm spacing: the 1 m and 0.5 m levels converge, 2 cm voxels hold one point each.
  const Pair p = room_pair(0.08, pose({0.1, -0.05, 0.0}, {0.0, 0.0, 2 * kDeg}));
  NdtConfig config;
  config.resolutions_m = {1.0, 0.5, 0.02, 0.0};
  NdtAligner ndt = make_aligner(config);
  const NdtResult r = ndt.align(p.target.view(), p.source.view(), Eigen::Isometry3d::Identity());
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(r.failure, NdtFailure::kTooFewTargetVoxels);
  EXPECT_EQ(r.levels, 2);
  EXPECT_TRUE(r.T_target_source.matrix().allFinite());
}

TEST(Ndt, GivenASinglePlaneThenDegenerate) {
  Cloud target;
  const Eigen::Matrix3d R = core::so3_exp(Eigen::Vector3d(0.3, -0.2, 0.5));
  add_patch(&target, R * Eigen::Vector3d(-5, -5, 0), R * Eigen::Vector3d(10, 0, 0),
            R * Eigen::Vector3d(0, 10, 0), 0.08);
  const Eigen::Isometry3d T_true = pose({0.1, -0.1, 0.05}, {0.02, 0.01, 0.03});
  const Cloud source = transformed(target, T_true.inverse());
  NdtAligner ndt = make_aligner();
  const NdtResult r = ndt.align(target.view(), source.view(), Eigen::Isometry3d::Identity());
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(r.failure, NdtFailure::kDegenerate) << ndt_failure_name(r.failure);
  EXPECT_TRUE(r.T_target_source.matrix().allFinite());
  EXPECT_TRUE(r.hessian.allFinite());
}

TEST(Ndt, GivenCloudsFarApartThenNoCorrespondences) {
  const Cloud target = room(0.15);
  NdtAligner ndt = make_aligner();
  const NdtResult r = ndt.align(target.view(), target.view(), pose({100, 0, 0}, {0, 0, 0}));
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(r.failure, NdtFailure::kNoCorrespondences);
  EXPECT_TRUE(r.T_target_source.matrix().allFinite());
}

TEST(Ndt, GivenNonFinitePointsThenTheyAreSkippedAndCounted) {
  const Pair p = room_pair(0.12, pose({0.2, -0.1, 0.05}, {0.0, 0.02, 5 * kDeg}));
  // The same clouds as CloudPoint-like records (stride 4) with NaN and inf points spliced in.
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  auto spliced = [&](const Cloud& c, int* bad) {
    std::vector<float> out;
    *bad = 0;
    for (int i = 0; i < c.size(); ++i) {
      if (i % 97 == 0) {
        out.insert(out.end(), {nan, 1.0f, 2.0f, 0.0f, 0.5f, inf, 0.5f, 0.0f});
        *bad += 2;
      }
      const Eigen::Vector3f q = c.view().at(i);
      out.insert(out.end(), {q.x(), q.y(), q.z(), 0.0f});
    }
    return out;
  };
  int bad_target = 0, bad_source = 0;
  const std::vector<float> target4 = spliced(p.target, &bad_target);
  const std::vector<float> source4 = spliced(p.source, &bad_source);
  const PointsView target_view{target4.data(), static_cast<int>(target4.size() / 4), 4};
  const PointsView source_view{source4.data(), static_cast<int>(source4.size() / 4), 4};
  NdtAligner ndt = make_aligner();
  const NdtResult clean = ndt.align(p.target.view(), p.source.view(), Eigen::Isometry3d::Identity());
  const NdtResult dirty = ndt.align(target_view, source_view, Eigen::Isometry3d::Identity());
  ASSERT_TRUE(clean.converged);
  ASSERT_TRUE(dirty.converged);
  EXPECT_EQ(dirty.nonfinite_points, bad_source);
  EXPECT_EQ(clean.nonfinite_points, 0);
  EXPECT_EQ(dirty.iterations, clean.iterations);
  EXPECT_EQ(dirty.correspondences, clean.correspondences);
  EXPECT_LT((dirty.T_target_source.matrix() - clean.T_target_source.matrix()).cwiseAbs().maxCoeff(), 1e-9);
  auto target = NdtTarget::create(NdtConfig{});
  ASSERT_TRUE(target->build(target_view, 0.5).ok());
  EXPECT_EQ(target->skipped_points(), bad_target);
}

TEST(Ndt, GivenOffsetsUpToHalfAMetreAndTenDegreesThenEveryAlignmentConverges) {
  const Cloud target = room(0.15);
  NdtAligner ndt = make_aligner();
  int failures = 0, runs = 0;
  for (int axis = 0; axis < 3; ++axis) {
    for (double sign : {-1.0, 1.0}) {
      for (int rot_axis = 0; rot_axis < 3; ++rot_axis) {
        Eigen::Vector3d t = Eigen::Vector3d::Zero(), w = Eigen::Vector3d::Zero();
        t(axis) = 0.5 * sign;
        w(rot_axis) = 10 * kDeg * (axis == rot_axis ? -sign : sign);
        const Eigen::Isometry3d T_true = pose(t, w);
        const Cloud source = transformed(target, T_true.inverse());
        const NdtResult r = ndt.align(target.view(), source.view(), Eigen::Isometry3d::Identity());
        const double et = translation_error_m(r.T_target_source, T_true);
        const double er = rotation_error_rad(r.T_target_source, T_true);
        ++runs;
        if (!r.converged || et > 1e-3 || er > 0.01 * kDeg) {
          ++failures;
          ADD_FAILURE() << "offset t " << t.transpose() << " w[deg] " << (w / kDeg).transpose() << ": "
                        << ndt_failure_name(r.failure) << ", error " << et << " m " << er / kDeg << " deg";
        }
      }
    }
  }
  EXPECT_EQ(failures, 0) << "of " << runs;
}

TEST(Ndt, GivenOffsetsOfOneMetreAndFifteenDegreesThenAResampledRoomAligns) {
  // The source samples the room on another grid (not the target's points): the answer carries NDT's
  // own small bias, hence the looser tolerance than the exact-recovery test.
  const Cloud target = room(0.15);
  const Cloud resampled = room(0.15 * 1.07);
  NdtAligner ndt = make_aligner();
  std::mt19937 rng(11);
  std::normal_distribution<double> nd(0, 1);
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d t_dir(nd(rng), nd(rng), nd(rng)), w_dir(nd(rng), nd(rng), nd(rng));
    const Eigen::Isometry3d T_true = pose(1.0 * t_dir.normalized(), 15 * kDeg * w_dir.normalized());
    const Cloud source = transformed(resampled, T_true.inverse());
    const NdtResult r = ndt.align(target.view(), source.view(), Eigen::Isometry3d::Identity());
    EXPECT_TRUE(r.converged) << k << ": " << ndt_failure_name(r.failure);
    EXPECT_LT(translation_error_m(r.T_target_source, T_true), 5e-3) << k;
    EXPECT_LT(rotation_error_rad(r.T_target_source, T_true), 0.1 * kDeg) << k;
  }
}

TEST(Ndt, GivenFourThreadsThenTheResultEqualsOneThread) {
  const Pair p = room_pair(0.1, pose({0.3, 0.2, -0.1}, {0.05, 0.0, -6 * kDeg}));
  NdtConfig config;
  NdtAligner one = make_aligner(config);
  config.num_threads = 4;
  NdtAligner four = make_aligner(config);
  const NdtResult a = one.align(p.target.view(), p.source.view(), Eigen::Isometry3d::Identity());
  const NdtResult b = four.align(p.target.view(), p.source.view(), Eigen::Isometry3d::Identity());
  ASSERT_TRUE(a.converged);
  ASSERT_TRUE(b.converged);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_LT((a.T_target_source.matrix() - b.T_target_source.matrix()).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_NEAR(a.score, b.score, 1e-6 * a.score);
}

TEST(Ndt, GivenATargetVersionThenTheTargetIsReusedUntilTheVersionOrBufferChanges) {
  // Two guesses against one target with a version: the same results as building every time.
  const Pair p = room_pair(0.1, pose({0.3, -0.2, 0.05}, {0.02, -0.01, 5 * kDeg}));
  Cloud target = p.target;  // its buffer is refilled below
  NdtAligner fresh = make_aligner();
  NdtConfig per_level;
  per_level.target_per_level = true;
  NdtAligner cached = make_aligner(per_level);
  const Eigen::Isometry3d guesses[2] = {Eigen::Isometry3d::Identity(),
                                        pose({0.1, 0.1, 0}, {0, 0, -3 * kDeg})};
  for (const Eigen::Isometry3d& g : guesses) {
    const NdtResult a = fresh.align(target.view(), p.source.view(), g);
    const NdtResult b = cached.align(target.view(), p.source.view(), g, 7);
    ASSERT_TRUE(a.converged);
    ASSERT_TRUE(b.converged);
    EXPECT_EQ(a.iterations, b.iterations);
    EXPECT_EQ(a.T_target_source.matrix(), b.T_target_source.matrix());
    EXPECT_EQ(a.score, b.score);
  }
  // The same buffer refilled with the room moved 0.5 m along x.
  const Eigen::Isometry3d shift = pose({0.5, 0, 0}, {0, 0, 0});
  const Cloud shifted = transformed(p.target, shift);
  const float* buffer = target.xyz.data();
  std::copy(shifted.xyz.begin(), shifted.xyz.end(), target.xyz.begin());
  ASSERT_EQ(target.xyz.data(), buffer);
  // Under the old version the aligner keeps its Gaussians (the reuse is real; the caller broke its
  // promise): the pose comes out where the old room was.
  const NdtResult stale = cached.align(target.view(), p.source.view(), p.T_true, 7);
  ASSERT_TRUE(stale.converged);
  EXPECT_LT(translation_error_m(stale.T_target_source, p.T_true), 1e-3);
  // Version 0 builds every time: the aligner that built from the old contents follows the move.
  const NdtResult unversioned = fresh.align(target.view(), p.source.view(), p.T_true);
  ASSERT_TRUE(unversioned.converged);
  EXPECT_LT(translation_error_m(unversioned.T_target_source, shift * p.T_true), 1e-3);
  // A new version builds again: the pose follows the move.
  const NdtResult moved = cached.align(target.view(), p.source.view(), p.T_true, 8);
  ASSERT_TRUE(moved.converged);
  EXPECT_LT(translation_error_m(moved.T_target_source, shift * p.T_true), 1e-3);
  // The same version from another buffer (the original room) builds again: the pose follows it.
  const NdtResult other = cached.align(p.target.view(), p.source.view(), shift * p.T_true, 8);
  ASSERT_TRUE(other.converged);
  EXPECT_LT(translation_error_m(other.T_target_source, p.T_true), 1e-3);
}

TEST(Ndt, GivenTargetsPrebuiltPerLevelThenAlignPrebuiltEqualsAlignOverTheSameLevels) {
  // The room cut into two views (a map held in pieces): one multi-view build per level equals a
  // build of the whole, and aligning over those prebuilt levels equals align() over the room.
  const Pair p = room_pair(0.1, pose({0.35, -0.25, 0.05}, {0.02, -0.01, 6 * kDeg}));
  const int half = p.target.size() / 2;
  const PointsView pieces[2] = {{p.target.xyz.data(), half, 3},
                                {p.target.xyz.data() + 3 * half, p.target.size() - half, 3}};
  NdtConfig config;  // levels 2, 1, 0.5 m
  NdtAligner ndt = make_aligner(config);
  std::vector<NdtTarget> levels;
  for (double r : {2.0, 1.0, 0.5}) {
    auto whole = NdtTarget::create(config);
    auto split = NdtTarget::create(config);
    ASSERT_TRUE(whole.ok() && split.ok());
    ASSERT_TRUE(whole->build(p.target.view(), r).ok());
    ASSERT_TRUE(split->build(pieces, 2, r).ok());
    EXPECT_EQ(split->occupied_voxels(), whole->occupied_voxels()) << r;
    EXPECT_EQ(split->gaussian_voxels(), whole->gaussian_voxels()) << r;
    EXPECT_DOUBLE_EQ(
        ndt.evaluate(*split, p.source.view(), x_of(p.T_true, Eigen::Vector3d::Zero()), nullptr, nullptr),
        ndt.evaluate(*whole, p.source.view(), x_of(p.T_true, Eigen::Vector3d::Zero()), nullptr, nullptr))
        << r;
    levels.push_back(std::move(split).value());
  }
  const NdtTarget* level_ptrs[3] = {&levels[0], &levels[1], &levels[2]};
  const NdtResult a = ndt.align(p.target.view(), p.source.view(), Eigen::Isometry3d::Identity());
  const NdtResult b = ndt.align_prebuilt(level_ptrs, 3, p.source.view(), Eigen::Isometry3d::Identity());
  ASSERT_TRUE(a.converged);
  ASSERT_TRUE(b.converged) << ndt_failure_name(b.failure);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_EQ(a.levels, b.levels);
  EXPECT_EQ(a.score, b.score);
  EXPECT_EQ(a.T_target_source.matrix(), b.T_target_source.matrix());
  // Invalid: no level, a null level.
  EXPECT_EQ(ndt.align_prebuilt(level_ptrs, 0, p.source.view(), p.T_true).failure, NdtFailure::kInvalidInput);
  const NdtTarget* with_null[3] = {&levels[0], nullptr, &levels[2]};
  EXPECT_EQ(ndt.align_prebuilt(with_null, 3, p.source.view(), p.T_true).failure, NdtFailure::kInvalidInput);
  // A multi-view build bounds the views' points together by max_target_points.
  NdtConfig small = config;
  small.max_target_points = p.target.size() - 1;
  auto bounded = NdtTarget::create(small);
  ASSERT_TRUE(bounded.ok());
  EXPECT_EQ(bounded->build(pieces, 2, 0.5).code(), core::ErrorCode::kOutOfRange);
}

TEST(Ndt, GivenACreatedAlignerThenAligningAndBuildingAllocateNothing) {
  const Pair p = room_pair(0.12, pose({0.2, -0.2, 0.05}, {0.02, 0.0, 4 * kDeg}));
  for (int threads : {1, 3}) {
    NdtConfig config;
    config.num_threads = threads;
    NdtAligner ndt = make_aligner(config);
    auto target = NdtTarget::create(config);
    ASSERT_TRUE(target.ok());
    core::AllocationScope scope;
    const NdtResult r = ndt.align(p.target.view(), p.source.view(), Eigen::Isometry3d::Identity());
    ASSERT_TRUE(target->build(p.target.view(), 0.5).ok());
    const NdtResult r2 = ndt.align_level(*target, p.source.view(), r.T_target_source);
    const NdtTarget* level = &target.value();
    const NdtResult r3 = ndt.align_prebuilt(&level, 1, p.source.view(), r.T_target_source);
    EXPECT_EQ(scope.allocations(), 0u) << threads << " threads";
    EXPECT_TRUE(r3.converged);
    EXPECT_TRUE(r.converged);
    EXPECT_TRUE(r2.converged);
    EXPECT_EQ(r2.levels, 1);
    EXPECT_LT(translation_error_m(r2.T_target_source, p.T_true), 1e-3);
  }
}

TEST(Ndt, GivenABadConfigThenCreateSaysWhy) {
  NdtConfig c;
  c.resolutions_m = {0.0, 0.0, 0.0, 0.0};
  EXPECT_EQ(NdtAligner::create(c).status().code(), core::ErrorCode::kInvalidArgument);
  c = NdtConfig{};
  c.resolutions_m = {1.0, -0.5, 0.0, 0.0};
  EXPECT_EQ(NdtAligner::create(c).status().code(), core::ErrorCode::kInvalidArgument);
  c = NdtConfig{};
  c.outlier_ratio = 1.0;
  EXPECT_EQ(NdtAligner::create(c).status().code(), core::ErrorCode::kInvalidArgument);
  c = NdtConfig{};
  c.num_threads = 0;
  EXPECT_EQ(NdtTarget::create(c).status().code(), core::ErrorCode::kInvalidArgument);
  auto target = NdtTarget::create(NdtConfig{});
  ASSERT_TRUE(target.ok());
  const Cloud cloud = room(0.3);
  EXPECT_EQ(target->build(cloud.view(), 0.0).code(), core::ErrorCode::kInvalidArgument);
  NdtConfig small;
  small.max_target_voxels = 10;
  auto tiny = NdtTarget::create(small);
  ASSERT_TRUE(tiny.ok());
  const core::Status st = tiny->build(cloud.view(), 0.5);
  EXPECT_EQ(st.code(), core::ErrorCode::kOutOfRange);
  EXPECT_EQ(tiny->gaussian_voxels(), 0);
}

}  // namespace
}  // namespace hwr::recon
