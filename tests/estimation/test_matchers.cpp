// ProjectionMatcher, LshMatcher and ExactMatcher (estimation/projection_matcher.hpp, lsh_matcher.hpp,
// exact_matcher.hpp): synthetic
// cases with a known answer, and real TUM teddy frame pairs checked against the motion-capture
// ground truth (a match is right when frame i's depth point, moved by the true relative pose,
// lands within kRightPx of the matched feature of frame j). The ground truth itself is good to a
// few pixels here: shifting its time by 10 ms moves the mean reprojection offset by ~2 px, and
// correct matches spread over 0-8 px, wrong ones anywhere in the search radius or image.

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
#include "hwr/estimation/descriptor.hpp"
#include "hwr/estimation/exact_matcher.hpp"
#include "hwr/estimation/lsh_matcher.hpp"
#include "hwr/estimation/orb_extractor.hpp"
#include "hwr/estimation/projection_matcher.hpp"
#include "hwr/hal/tum_dataset.hpp"

namespace hwr::estimation {
namespace {

using hal::testing::kTeddyDir;
constexpr double kRightPx = 8.0;
// Ten frames apart the ground truth's relative error grows (projection matches with the true pose
// spread to 3-15 px there); wrong LSH matches land tens to hundreds of pixels away.
constexpr double kLshRightPx = 15.0;

// Ground truth T_world_cam at t_ns, interpolated between the bracketing mocap samples.
bool gt_pose_at(const std::vector<core::StampedPose>& gt, int64_t t_ns, Eigen::Isometry3d* T_world_cam) {
  auto it = std::lower_bound(gt.begin(), gt.end(), t_ns,
                             [](const core::StampedPose& p, int64_t t) { return p.t_ns < t; });
  if (it == gt.begin() || it == gt.end()) return false;
  const auto& b = *it;
  const auto& a = *(it - 1);
  const double alpha = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  *T_world_cam = core::se3_interpolate(a.T_world_body, b.T_world_body, alpha);
  return true;
}

struct TeddyView {
  FrameFeatures features{1000, 640, 480};
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
};

void load_view(size_t index, TeddyView* view) {
  auto ds = hal::TumDataset::open(kTeddyDir);
  ASSERT_TRUE(ds.ok()) << ds.status().to_string();
  hal::RgbdFrame frame;
  ASSERT_TRUE(ds->load_frame(index, &frame).ok());
  ASSERT_TRUE(gt_pose_at(ds->groundtruth(), ds->frame_time_ns(index), &view->T_world_cam));
  cv::Mat gray;
  cv::cvtColor(frame.bgr, gray, cv::COLOR_BGR2GRAY);
  // 1000 features per view, whatever the tracker's default: the match-count floors below were set
  // for it, and FLANN's LSH tables are randomly seeded, so a smaller margin would be flaky.
  OrbConfig orb;
  orb.max_features = 1000;
  GridOrbExtractor extractor(orb, 640, 480);
  ASSERT_TRUE(extractor.extract(gray, frame.depth_m, hal::tum_fr3_intrinsics(), &view->features).ok());
}

// Pixel distance between frame a's feature (moved with its depth and the true relative pose) and
// frame b's feature; < 0 when a's feature has no depth.
double true_error_px(const TeddyView& a, int ia, const TeddyView& b, int ib) {
  const Feature& fa = a.features.feature(ia);
  if (fa.depth_m <= 0) return -1;
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  const Eigen::Vector3d p = b.T_world_cam.inverse() * (a.T_world_cam * fa.p_cam_m);
  const double u = K.fx * p.x() / p.z() + K.cx, v = K.fy * p.y() / p.z() + K.cy;
  return std::hypot(u - b.features.feature(ib).u_px, v - b.features.feature(ib).v_px);
}

void random_descriptor(std::mt19937& rng, uint8_t* d) {
  for (int k = 0; k < kOrbDescriptorBytes; ++k) d[k] = static_cast<uint8_t>(rng() & 0xff);
}

void flip_bits(std::mt19937& rng, uint8_t* d, int bits) {
  for (int b = 0; b < bits; ++b) {
    const int k = static_cast<int>(rng() % kOrbDescriptorBits);
    d[k / 8] ^= static_cast<uint8_t>(1u << (k % 8));
  }
}

// n random train descriptors; query k < copies is a copy of train (k * 7) % modulus with flips(k)
// bits flipped, the rest of the n queries random.
template <class Flips>
void descriptor_pair(std::mt19937& rng, int n, int copies, int modulus, Flips flips, FrameFeatures* train,
                     FrameFeatures* query) {
  const Feature f;
  for (int i = 0; i < n; ++i) {
    uint8_t d[kOrbDescriptorBytes];
    random_descriptor(rng, d);
    ASSERT_EQ(train->push_back(f, d), i);
  }
  for (int k = 0; k < n; ++k) {
    uint8_t d[kOrbDescriptorBytes];
    if (k < copies) {
      const int t = (k * 7) % modulus;
      std::copy(train->descriptor(t), train->descriptor(t) + kOrbDescriptorBytes, d);
      flip_bits(rng, d, flips(k));
    } else {
      random_descriptor(rng, d);
    }
    ASSERT_EQ(query->push_back(f, d), k);
  }
}

TEST(ProjectionMatcher, SyntheticPointsFindTheirFeatures) {
  std::mt19937 rng(7);
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  Eigen::Isometry3d T_cam_world = Eigen::Isometry3d::Identity();
  T_cam_world.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1, 0.1).normalized()).toRotationMatrix();
  T_cam_world.translation() = Eigen::Vector3d(0.1, -0.2, 0.3);
  const int n = 300;
  FrameFeatures frame(n, 640, 480);
  std::vector<std::array<uint8_t, kOrbDescriptorBytes>> point_desc(n);
  std::vector<MapPointRef> points(n);
  std::uniform_real_distribution<double> U(30, 610), V(30, 450), Z(0.5, 6.0), J(-2.0, 2.0);
  for (int i = 0; i < n; ++i) {
    // A feature at a pixel, the point 2 px off its line of sight (prediction error).
    Feature f;
    f.u_px = static_cast<float>(U(rng));
    f.v_px = static_cast<float>(V(rng));
    f.octave = i % 4;
    uint8_t d[kOrbDescriptorBytes];
    random_descriptor(rng, d);
    ASSERT_EQ(frame.push_back(f, d), i);
    std::copy(d, d + kOrbDescriptorBytes, point_desc[static_cast<size_t>(i)].begin());
    flip_bits(rng, point_desc[static_cast<size_t>(i)].data(), 10);
    const double z = Z(rng);
    const Eigen::Vector3d p_cam((f.u_px + J(rng) - K.cx) * z / K.fx, (f.v_px + J(rng) - K.cy) * z / K.fy, z);
    points[static_cast<size_t>(i)] = {T_cam_world.inverse() * p_cam,
                                      point_desc[static_cast<size_t>(i)].data(), f.octave};
  }
  frame.build_grid();
  ProjectionMatcher matcher(n, n);
  std::vector<FeatureMatch> out(n);
  core::AllocationScope scope;
  const int m =
      matcher.match(points.data(), n, T_cam_world, K, frame, ProjectionMatchConfig{}, out.data(), n);
  EXPECT_EQ(scope.allocations(), 0u);
  int right = 0;
  for (int k = 0; k < m; ++k)
    right += out[static_cast<size_t>(k)].query == out[static_cast<size_t>(k)].train ? 1 : 0;
  // Random features can be closer than the radius; the ratio test drops a few ambiguous ones.
  EXPECT_GE(m, 0.9 * n);
  EXPECT_EQ(right, m);
  for (int k = 0; k < m; ++k) EXPECT_LE(out[static_cast<size_t>(k)].distance, 10);

  // A feature is matched once: a second point with a worse descriptor near feature 0 loses.
  std::array<uint8_t, kOrbDescriptorBytes> worse;
  std::copy(frame.descriptor(0), frame.descriptor(0) + kOrbDescriptorBytes, worse.begin());
  flip_bits(rng, worse.data(), 30);
  points.push_back({points[0].p_world, worse.data(), points[0].octave_hint});
  ProjectionMatcher matcher2(n + 1, n);
  const int m2 =
      matcher2.match(points.data(), n + 1, T_cam_world, K, frame, ProjectionMatchConfig{}, out.data(), n);
  int owners_of_0 = 0;
  for (int k = 0; k < m2; ++k) {
    if (out[static_cast<size_t>(k)].train == 0) {
      ++owners_of_0;
      EXPECT_EQ(out[static_cast<size_t>(k)].query, 0);
    }
  }
  EXPECT_EQ(owners_of_0, 1);
  // Points behind the camera or outside the image match nothing.
  MapPointRef behind = points[1];
  behind.p_world = T_cam_world.inverse() * Eigen::Vector3d(0, 0, -2);
  EXPECT_EQ(matcher.match(&behind, 1, T_cam_world, K, frame, ProjectionMatchConfig{}, out.data(), n), 0);
}

TEST(ProjectionMatcher, TeddyFramesFiveApartWithGroundTruthPose) {
  HWR_REQUIRE_DATASET(kTeddyDir);
  TeddyView a, b;
  load_view(20, &a);
  load_view(25, &b);
  std::vector<MapPointRef> points;
  std::vector<int> feature_of_point;
  for (int i = 0; i < a.features.size(); ++i) {
    const Feature& f = a.features.feature(i);
    if (f.depth_m <= 0) continue;
    points.push_back({a.T_world_cam * f.p_cam_m, a.features.descriptor(i), f.octave});
    feature_of_point.push_back(i);
  }
  ASSERT_GT(points.size(), 300u);
  ProjectionMatcher matcher(1000, 1000);
  std::vector<FeatureMatch> out(1000);
  const Eigen::Isometry3d T_cam_world = b.T_world_cam.inverse();
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  uint64_t allocations = 0;
  int m = 0;
  {
    core::AllocationScope scope;
    m = matcher.match(points.data(), static_cast<int>(points.size()), T_cam_world, K, b.features,
                      ProjectionMatchConfig{}, out.data(), 1000);
    allocations = scope.allocations();
  }
  EXPECT_EQ(allocations, 0u);
  int right = 0;
  std::vector<int> trains;
  std::vector<double> errors;
  for (int k = 0; k < m; ++k) {
    const FeatureMatch& fm = out[static_cast<size_t>(k)];
    const double e = true_error_px(a, feature_of_point[static_cast<size_t>(fm.query)], b, fm.train);
    right += e >= 0 && e <= kRightPx ? 1 : 0;
    errors.push_back(e);
    trains.push_back(fm.train);
  }
  std::sort(trains.begin(), trains.end());
  EXPECT_EQ(std::adjacent_find(trains.begin(), trains.end()), trains.end()) << "a feature matched twice";
  std::sort(errors.begin(), errors.end());
  ASSERT_GT(m, 0);
  const double median = errors[errors.size() / 2];
  std::printf(
      "projection matching teddy 20 -> 25: %zu points, %d matches, %d within %.0f px of the truth, median "
      "%.2f px, max %.1f px\n",
      points.size(), m, right, kRightPx, median, errors.back());
  EXPECT_GE(m, 0.4 * static_cast<double>(points.size()));
  EXPECT_GE(right, 0.95 * m);
  EXPECT_LT(median, 3.0);
}

TEST(LshMatcher, SyntheticDescriptorsMatchTheirCopies) {
  std::mt19937 rng(11);
  const int n = 600;
  FrameFeatures train(n, 640, 480), query(n, 640, 480);
  // Query k is a noisy copy of train (k * 7) % n for the first half; random for the rest.
  ASSERT_NO_FATAL_FAILURE(descriptor_pair(
      rng, n, n / 2, n, [](int) { return 12; }, &train, &query));
  LshMatcher lsh(n, LshConfig{});
  lsh.build(train);
  EXPECT_EQ(lsh.indexed(), n);
  std::vector<FeatureMatch> out(n);
  const int m = lsh.match(query, out.data(), n);
  int right = 0;
  for (int k = 0; k < m; ++k) {
    const FeatureMatch& fm = out[static_cast<size_t>(k)];
    ASSERT_LT(fm.query, n / 2) << "a random descriptor passed the ratio test";
    right += fm.train == (fm.query * 7) % n ? 1 : 0;
    EXPECT_EQ(fm.distance, hamming_distance(query.descriptor(fm.query), train.descriptor(fm.train)));
  }
  EXPECT_EQ(right, m);
  EXPECT_GE(m, 0.9 * n / 2);
  LshMatcher empty(n, LshConfig{});
  EXPECT_EQ(empty.match(query, out.data(), n), 0) << "before build()";
}

TEST(LshMatcher, TeddyFramesTenApart) {
  HWR_REQUIRE_DATASET(kTeddyDir);
  TeddyView a, b;
  load_view(20, &a);
  load_view(30, &b);
  LshMatcher lsh(1000, LshConfig{});
  std::vector<FeatureMatch> out(1000);
  lsh.build(b.features);  // warm-up
  uint64_t build_allocs = 0, match_allocs = 0;
  int m = 0;
  {
    core::AllocationScope scope;
    lsh.build(b.features);
    build_allocs = scope.allocations();
  }
  {
    core::AllocationScope scope;
    m = lsh.match(a.features, out.data(), 1000);
    match_allocs = scope.allocations();
  }
  int checked = 0, right = 0, agree_brute = 0;
  for (int k = 0; k < m; ++k) {
    const FeatureMatch& fm = out[static_cast<size_t>(k)];
    const double e = true_error_px(a, fm.query, b, fm.train);
    if (e >= 0) {
      ++checked;
      right += e <= kLshRightPx ? 1 : 0;
    }
    // The brute-force nearest neighbour (the oracle LSH approximates) is the same feature, or one at
    // the same distance.
    int best = 257;
    for (int j = 0; j < b.features.size(); ++j) {
      best = std::min(best, hamming_distance(a.features.descriptor(fm.query), b.features.descriptor(j)));
    }
    agree_brute += fm.distance == best ? 1 : 0;
  }
  std::printf(
      "LSH teddy 20 -> 30: %d matches, %d/%d with depth within %.0f px of the truth, %d equal to "
      "brute force; allocations: build %llu, match %llu\n",
      m, right, checked, kLshRightPx, agree_brute, static_cast<unsigned long long>(build_allocs),
      static_cast<unsigned long long>(match_allocs));
  EXPECT_GE(m, 150);
  ASSERT_GT(checked, 100);
  EXPECT_GE(right, 0.85 * checked);
  EXPECT_GE(agree_brute, 0.9 * m);
}

// ExactMatcher against a brute-force oracle written out here: every match is the query's nearest
// train descriptor, passes the ratio test against the true second nearest, and is the closest query
// of its train feature; every query that the oracle accepts and that owns its train feature is found.
TEST(ExactMatcher, GivenSyntheticDescriptorsThenTheMatchesAreTheOraclesExactly) {
  std::mt19937 rng(5);
  const int n = 500;
  FrameFeatures train(n, 640, 480), query(n, 640, 480);
  // Noisy copies of the first half (some two per train feature, so that ownership matters), then
  // random ones.
  ASSERT_NO_FATAL_FAILURE(descriptor_pair(
      rng, n, 3 * n / 4, n / 2, [](int k) { return 4 + k % 20; }, &train, &query));
  const ExactMatchConfig cfg;
  // The oracle: per query its nearest and second nearest, the tests, then one owner per train.
  std::vector<int> owner(n, -1), owner_d(n, 257);
  for (int q = 0; q < n; ++q) {
    int b1 = 257, b2 = 257, j1 = -1;
    for (int t = 0; t < n; ++t) {
      const int d = hamming_distance(query.descriptor(q), train.descriptor(t));
      if (d < b1) {
        b2 = b1;
        b1 = d;
        j1 = t;
      } else if (d < b2) {
        b2 = d;
      }
    }
    if (b1 > cfg.max_distance || static_cast<float>(b1) >= cfg.ratio * static_cast<float>(b2)) continue;
    if (b1 < owner_d[j1]) {
      owner[j1] = q;
      owner_d[j1] = b1;
    }
  }
  int expected = 0;
  for (int t = 0; t < n; ++t) expected += owner[t] >= 0 ? 1 : 0;

  ExactMatcher exact(n, cfg);
  std::vector<FeatureMatch> out(n);
  EXPECT_EQ(exact.match(query, out.data(), n), 0) << "before build()";
  exact.build(train);
  EXPECT_EQ(exact.indexed(), n);
  exact.match(query, out.data(), n);  // warm-up
  uint64_t allocations = 0;
  int m = 0;
  {
    core::AllocationScope scope;
    m = exact.match(query, out.data(), n);
    allocations = scope.allocations();
  }
  ASSERT_EQ(m, expected);
  ASSERT_GT(m, n / 3);
  for (int k = 0; k < m; ++k) {
    const FeatureMatch& fm = out[static_cast<size_t>(k)];
    EXPECT_EQ(owner[fm.train], fm.query) << "train " << fm.train;
    EXPECT_EQ(fm.distance, owner_d[fm.train]);
    if (k > 0) {
      EXPECT_LT(out[static_cast<size_t>(k - 1)].train, fm.train);
    }
  }
  EXPECT_EQ(allocations, 0u);
  // max_out caps the output; an empty query matches nothing; a single train descriptor has no second
  // neighbour (no ratio test): its closest query within max_distance owns it.
  EXPECT_EQ(exact.match(query, out.data(), 10), 10);
  EXPECT_EQ(exact.match(FrameFeatures(1, 640, 480), out.data(), n), 0);
  FrameFeatures one(1, 640, 480);
  ASSERT_EQ(one.push_back(Feature{}, train.descriptor(0)), 0);
  exact.build(one);
  int closest = -1, closest_d = 257;
  for (int q = 0; q < n; ++q) {
    const int d = hamming_distance(query.descriptor(q), train.descriptor(0));
    if (d < closest_d) {
      closest_d = d;
      closest = q;
    }
  }
  ASSERT_LE(closest_d, cfg.max_distance);
  ASSERT_EQ(exact.match(query, out.data(), n), 1);
  EXPECT_EQ(out[0].train, 0);
  EXPECT_EQ(out[0].query, closest);
  EXPECT_EQ(out[0].distance, closest_d);
}

}  // namespace
}  // namespace hwr::estimation
