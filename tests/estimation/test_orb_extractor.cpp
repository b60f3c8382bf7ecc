// GridOrbExtractor and FrameFeatures (estimation/orb_extractor.hpp, frame_features.hpp) on a real
// TUM teddy frame: feature budget, spread over the image, depth and eq. (3) back-projection
// against the depth image, rotation invariance, error handling; the radius grid against brute force.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "hal/hal_test_util.hpp"
#include "hwr/core/alloc_counter.hpp"
#include "hwr/estimation/descriptor.hpp"
#include "hwr/estimation/frame_features.hpp"
#include "hwr/estimation/orb_extractor.hpp"
#include "hwr/hal/tum_dataset.hpp"

namespace hwr::estimation {
namespace {

using hal::testing::kTeddyDir;

struct TeddyImages {
  cv::Mat gray, depth_m;
};

TeddyImages load_teddy(size_t index) {
  TeddyImages out;
  auto ds = hal::TumDataset::open(kTeddyDir);
  if (!ds.ok()) {
    ADD_FAILURE() << ds.status().to_string();
    return out;
  }
  hal::RgbdFrame frame;
  const core::Status st = ds->load_frame(index, &frame);
  if (!st.ok()) {
    ADD_FAILURE() << st.to_string();
    return out;
  }
  cv::cvtColor(frame.bgr, out.gray, cv::COLOR_BGR2GRAY);
  out.depth_m = frame.depth_m.clone();
  return out;
}

TEST(FrameFeatures, RadiusQueryMatchesBruteForce) {
  FrameFeatures ff(500, 640, 480);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> U(0.f, 640.f), V(0.f, 480.f);
  std::uniform_int_distribution<int> oct(0, 7);
  uint8_t desc[kOrbDescriptorBytes] = {};
  for (int i = 0; i < 500; ++i) {
    Feature f;
    f.u_px = U(rng);
    f.v_px = V(rng);
    f.octave = oct(rng);
    desc[0] = static_cast<uint8_t>(i);
    ASSERT_EQ(ff.push_back(f, desc), i);
  }
  Feature extra;
  EXPECT_EQ(ff.push_back(extra, desc), -1) << "full";
  EXPECT_EQ(ff.descriptor(7)[0], 7);
  EXPECT_EQ(ff.descriptors().rows, 500);
  EXPECT_EQ(ff.descriptors().ptr<uint8_t>(9)[0], 9);

  std::vector<int> got(500), want;
  for (int pass = 0; pass < 2; ++pass) {  // pass 0: linear scan (grid stale), pass 1: grid
    if (pass == 1) ff.build_grid();
    EXPECT_EQ(ff.grid_valid(), pass == 1);
    for (int q = 0; q < 200; ++q) {
      const float u = U(rng) * 1.1f - 32.f, v = V(rng) * 1.1f - 24.f, r = 3.f + static_cast<float>(q % 50);
      const int lo = q % 3 == 0 ? -1 : q % 4, hi = q % 3 == 0 ? -1 : q % 4 + 2;
      want.clear();
      for (int i = 0; i < ff.size(); ++i) {
        const Feature& f = ff.feature(i);
        if ((lo >= 0 && f.octave < lo) || (hi >= 0 && f.octave > hi)) continue;
        if (std::hypot(f.u_px - u, f.v_px - v) <= r) want.push_back(i);
      }
      const int n = ff.features_in_radius(u, v, r, lo, hi, got.data(), 500);
      std::vector<int> g(got.begin(), got.begin() + n);
      std::sort(g.begin(), g.end());
      EXPECT_EQ(g, want) << "query " << q;
    }
  }
  // max_out truncates.
  EXPECT_EQ(ff.features_in_radius(320, 240, 1000, -1, -1, got.data(), 10), 10);
  core::AllocationScope scope;
  int sink = 0;
  for (int q = 0; q < 100; ++q)
    sink += ff.features_in_radius(100.f + q, 200.f, 30.f, -1, -1, got.data(), 500);
  EXPECT_EQ(scope.allocations(), 0u);
  EXPECT_GT(sink, 0);
  ff.clear();
  EXPECT_EQ(ff.size(), 0);
  EXPECT_EQ(ff.features_in_radius(320, 240, 1000, -1, -1, got.data(), 500), 0);
}

TEST(GridOrbExtractor, TeddyFrameBudgetSpreadAndDepth) {
  HWR_REQUIRE_DATASET(kTeddyDir);
  const TeddyImages img = load_teddy(20);
  ASSERT_FALSE(img.gray.empty());
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  OrbConfig cfg;
  GridOrbExtractor extractor(cfg, 640, 480);
  FrameFeatures ff(cfg.max_features, 640, 480);
  ASSERT_TRUE(extractor.extract(img.gray, img.depth_m, K, &ff).ok());

  EXPECT_LE(ff.size(), cfg.max_features);
  EXPECT_GE(ff.size(), 0.8 * cfg.max_features);
  ASSERT_EQ(ff.scale_per_octave.size(), static_cast<size_t>(cfg.levels));
  EXPECT_NEAR(ff.scale_per_octave[3], std::pow(1.2f, 3.f), 1e-5);
  EXPECT_TRUE(ff.grid_valid());

  // Spread: 40 px cells where FAST (at the retry threshold) finds texture must hold a feature.
  std::vector<cv::KeyPoint> corners;
  cv::FAST(img.gray, corners, cfg.min_fast_threshold, true);
  const int cols = 640 / 40, rows = 480 / 40;
  std::vector<int> texture(static_cast<size_t>(cols * rows), 0), held(static_cast<size_t>(cols * rows), 0);
  for (const auto& kp : corners) {
    // Only the area where keypoints can be (19 px from the border).
    if (kp.pt.x < 19 || kp.pt.y < 19 || kp.pt.x >= 640 - 19 || kp.pt.y >= 480 - 19) continue;
    ++texture[static_cast<size_t>(static_cast<int>(kp.pt.y) / 40 * cols + static_cast<int>(kp.pt.x) / 40)];
  }
  int with_depth = 0;
  std::vector<int> per_octave(static_cast<size_t>(cfg.levels), 0);
  for (int i = 0; i < ff.size(); ++i) {
    const Feature& f = ff.feature(i);
    ASSERT_GE(f.octave, 0);
    ASSERT_LT(f.octave, cfg.levels);
    ++per_octave[static_cast<size_t>(f.octave)];
    EXPECT_GE(f.u_px, 18.f);
    EXPECT_LT(f.u_px, 640.f - 18.f);
    EXPECT_GE(f.angle_deg, 0.f);
    EXPECT_LT(f.angle_deg, 360.f);
    EXPECT_GT(f.response, 0.f);
    ++held[static_cast<size_t>(static_cast<int>(f.v_px) / 40 * cols + static_cast<int>(f.u_px) / 40)];
    if (f.depth_m > 0) {
      ++with_depth;
      // Depth is the depth image's value at the nearest pixel; p_cam_m follows eq. (3).
      const int px = static_cast<int>(std::lround(f.u_px)), py = static_cast<int>(std::lround(f.v_px));
      EXPECT_FLOAT_EQ(f.depth_m, img.depth_m.at<float>(py, px));
      EXPECT_GE(f.depth_m, cfg.min_depth_m);
      EXPECT_LE(f.depth_m, cfg.max_depth_m);
      EXPECT_NEAR(f.p_cam_m.z(), f.depth_m, 1e-6);
      EXPECT_NEAR(K.fx * f.p_cam_m.x() / f.p_cam_m.z() + K.cx, f.u_px, 1e-3);
      EXPECT_NEAR(K.fy * f.p_cam_m.y() / f.p_cam_m.z() + K.cy, f.v_px, 1e-3);
    } else {
      EXPECT_EQ(f.p_cam_m, Eigen::Vector3d::Zero());
    }
  }
  int textured = 0, covered = 0;
  for (size_t c = 0; c < texture.size(); ++c) {
    if (texture[c] < 5) continue;
    ++textured;
    covered += held[c] > 0 ? 1 : 0;
  }
  std::printf("teddy #20: %d features, %d with depth, %d/%d textured cells covered; per octave:", ff.size(),
              with_depth, covered, textured);
  for (int n : per_octave) std::printf(" %d", n);
  std::printf("\n");
  ASSERT_GT(textured, 50);
  EXPECT_GE(covered, 0.7 * textured);
  EXPECT_GE(with_depth, 0.6 * ff.size());
  // Every level contributes (the pyramid is used).
  for (int l = 0; l < cfg.levels; ++l) EXPECT_GT(per_octave[static_cast<size_t>(l)], 0) << "level " << l;
  // No two features of the same level at the same place.
  for (int i = 0; i < ff.size(); ++i) {
    for (int j = i + 1; j < ff.size(); ++j) {
      const Feature &a = ff.feature(i), &b = ff.feature(j);
      if (a.octave == b.octave) {
        ASSERT_FALSE(a.u_px == b.u_px && a.v_px == b.v_px) << i << " " << j;
      }
    }
  }
}

TEST(GridOrbExtractor, DeterministicAndCountsAllocations) {
  HWR_REQUIRE_DATASET(kTeddyDir);
  const TeddyImages img = load_teddy(30);
  ASSERT_FALSE(img.gray.empty());
  OrbConfig cfg;
  GridOrbExtractor extractor(cfg, 640, 480);
  FrameFeatures a(cfg.max_features, 640, 480), b(cfg.max_features, 640, 480);
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  ASSERT_TRUE(extractor.extract(img.gray, img.depth_m, K, &a).ok());  // warm-up
  uint64_t allocations = 0, bytes = 0;
  {
    core::AllocationScope scope;
    ASSERT_TRUE(extractor.extract(img.gray, img.depth_m, K, &b).ok());
    allocations = scope.allocations();
    bytes = scope.bytes();
  }
  // OpenCV's FAST and ORB descriptor code allocate inside (pyramid copy, row buffers); everything
  // the extractor owns is preallocated. Reported, bounded so that a regression shows.
  std::printf("GridOrbExtractor::extract steady state: %llu allocations, %llu bytes (OpenCV internals)\n",
              static_cast<unsigned long long>(allocations), static_cast<unsigned long long>(bytes));
  EXPECT_LT(allocations, 2000u);
  // The FAST thresholds adapt from frame to frame: a second extractor given the same two frames
  // gives the same features.
  GridOrbExtractor again(cfg, 640, 480);
  ASSERT_TRUE(again.extract(img.gray, img.depth_m, K, &a).ok());
  ASSERT_TRUE(again.extract(img.gray, img.depth_m, K, &a).ok());
  ASSERT_EQ(a.size(), b.size());
  for (int i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.feature(i).u_px, b.feature(i).u_px);
    EXPECT_EQ(a.feature(i).octave, b.feature(i).octave);
    EXPECT_EQ(hamming_distance(a.descriptor(i), b.descriptor(i)), 0);
  }
}

// Uniform noise fires FAST almost everywhere: the levels raise their thresholds (bounded by
// max_fast_threshold) and still fill the feature budget; with the control off they stay put.
TEST(GridOrbExtractor, TexturedImageRaisesTheFastThresholdAndKeepsTheBudget) {
  cv::Mat noise(480, 640, CV_8UC1);
  cv::RNG rng(7);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(noise, noise, cv::Size(3, 3), 0.8);
  const cv::Mat no_depth;
  OrbConfig cfg;
  GridOrbExtractor adaptive(cfg, 640, 480);
  FrameFeatures out(cfg.max_features, 640, 480);
  for (int i = 0; i < 15; ++i) ASSERT_TRUE(adaptive.extract(noise, no_depth, {}, &out).ok());
  EXPECT_EQ(out.size(), cfg.max_features);
  EXPECT_GT(adaptive.level_threshold()[0], cfg.fast_threshold);
  for (int t : adaptive.level_threshold()) EXPECT_LE(t, cfg.max_fast_threshold);

  cfg.corners_per_feature = 0;
  GridOrbExtractor fixed(cfg, 640, 480);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(fixed.extract(noise, no_depth, {}, &out).ok());
  EXPECT_EQ(out.size(), cfg.max_features);
  for (int t : fixed.level_threshold()) EXPECT_EQ(t, cfg.fast_threshold);
}

// A dull image (a few squares on grey) keeps the base threshold: nothing to throttle.
TEST(GridOrbExtractor, DullImageKeepsTheBaseThreshold) {
  cv::Mat img(480, 640, CV_8UC1, cv::Scalar(128));
  for (int k = 0; k < 12; ++k)
    cv::rectangle(img, cv::Rect(40 + 45 * k, 60 + 25 * (k % 5), 20, 20), cv::Scalar(k % 2 ? 30 : 230), -1);
  OrbConfig cfg;
  GridOrbExtractor extractor(cfg, 640, 480);
  FrameFeatures out(cfg.max_features, 640, 480);
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(extractor.extract(img, cv::Mat(), {}, &out).ok());
  EXPECT_GT(out.size(), 0);
  for (int t : extractor.level_threshold()) EXPECT_EQ(t, cfg.fast_threshold);
}

// Rotating the image by 180 degrees maps (u, v) to (w - 1 - u, h - 1 - v): the same corners are
// found, their orientation turns by 180 degrees and the steered descriptor stays the same.
TEST(GridOrbExtractor, RotationInvariantOrientationAndDescriptor) {
  HWR_REQUIRE_DATASET(kTeddyDir);
  const TeddyImages img = load_teddy(40);
  ASSERT_FALSE(img.gray.empty());
  cv::Mat rotated;
  cv::rotate(img.gray, rotated, cv::ROTATE_180);
  OrbConfig cfg;
  cfg.levels = 1;  // level 0 only: the pyramid's resampling grid is not rotation-symmetric
  GridOrbExtractor extractor(cfg, 640, 480);
  FrameFeatures a(cfg.max_features, 640, 480), b(cfg.max_features, 640, 480);
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  ASSERT_TRUE(extractor.extract(img.gray, cv::Mat(), K, &a).ok());
  ASSERT_TRUE(extractor.extract(rotated, cv::Mat(), K, &b).ok());
  int pairs = 0, angle_ok = 0, desc_ok = 0;
  std::vector<int> idx(16);
  for (int i = 0; i < a.size(); ++i) {
    const Feature& f = a.feature(i);
    const int n = b.features_in_radius(639.f - f.u_px, 479.f - f.v_px, 0.5f, -1, -1, idx.data(), 16);
    if (n != 1) continue;
    ++pairs;
    double d = std::fmod(b.feature(idx[0]).angle_deg - f.angle_deg + 720.0, 360.0);
    angle_ok += std::abs(d - 180.0) < 2.0 ? 1 : 0;
    desc_ok += hamming_distance(a.descriptor(i), b.descriptor(idx[0])) <= 20 ? 1 : 0;
  }
  std::printf("180 deg rotation: %d pairs, %d angles within 2 deg, %d descriptors within 20 bits\n", pairs,
              angle_ok, desc_ok);
  ASSERT_GT(pairs, 300);
  EXPECT_GE(angle_ok, 0.9 * pairs);
  EXPECT_GE(desc_ok, 0.8 * pairs);
}

TEST(GridOrbExtractor, MissingOrInvalidDepthGivesFeaturesWithoutDepth) {
  HWR_REQUIRE_DATASET(kTeddyDir);
  const TeddyImages img = load_teddy(20);
  ASSERT_FALSE(img.gray.empty());
  OrbConfig cfg;
  GridOrbExtractor extractor(cfg, 640, 480);
  FrameFeatures ref(cfg.max_features, 640, 480), ff(cfg.max_features, 640, 480);
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  ASSERT_TRUE(extractor.extract(img.gray, img.depth_m, K, &ref).ok());
  const cv::Mat nan_depth(480, 640, CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  const cv::Mat zero_depth(480, 640, CV_32FC1, cv::Scalar(0.f));
  const cv::Mat far_depth(480, 640, CV_32FC1, cv::Scalar(cfg.max_depth_m + 1.f));
  for (const cv::Mat* depth : {&img.depth_m, &nan_depth, &zero_depth, &far_depth}) {
    const bool empty = depth == &img.depth_m;
    ASSERT_TRUE(extractor.extract(img.gray, empty ? cv::Mat() : *depth, K, &ff).ok());
    ASSERT_EQ(ff.size(), ref.size()) << "features do not depend on depth";
    for (int i = 0; i < ff.size(); ++i) {
      EXPECT_EQ(ff.feature(i).depth_m, 0.f);
      EXPECT_EQ(ff.feature(i).u_px, ref.feature(i).u_px);
    }
  }
}

TEST(GridOrbExtractor, DepthDiscontinuityRejected) {
  HWR_REQUIRE_DATASET(kTeddyDir);
  const TeddyImages img = load_teddy(20);
  ASSERT_FALSE(img.gray.empty());
  // Synthetic depth: 1 m left of column 320, 2 m from it on.
  cv::Mat depth(480, 640, CV_32FC1, cv::Scalar(1.f));
  depth.colRange(320, 640).setTo(2.f);
  OrbConfig cfg;
  GridOrbExtractor extractor(cfg, 640, 480);
  FrameFeatures ff(cfg.max_features, 640, 480);
  ASSERT_TRUE(extractor.extract(img.gray, depth, hal::tum_fr3_intrinsics(), &ff).ok());
  int near_edge = 0;
  for (int i = 0; i < ff.size(); ++i) {
    const Feature& f = ff.feature(i);
    const long px = std::lround(f.u_px);
    if (px == 319 || px == 320) {
      ++near_edge;
      EXPECT_EQ(f.depth_m, 0.f) << "at the step, u = " << f.u_px;
    } else {
      EXPECT_EQ(f.depth_m, px < 320 ? 1.f : 2.f) << "u = " << f.u_px;
    }
  }
  std::printf("%d features on the depth step\n", near_edge);
}

TEST(GridOrbExtractor, RejectsWrongInputs) {
  OrbConfig cfg;
  GridOrbExtractor extractor(cfg, 640, 480);
  FrameFeatures ff(cfg.max_features, 640, 480);
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  const cv::Mat bgr(480, 640, CV_8UC3, cv::Scalar(0, 0, 0));
  hal::testing::expect_one_line_error(extractor.extract(bgr, cv::Mat(), K, &ff), "CV_8UC1");
  hal::testing::expect_one_line_error(extractor.extract(cv::Mat(), cv::Mat(), K, &ff), "CV_8UC1");
  const cv::Mat small(240, 320, CV_8UC1, cv::Scalar(0));
  hal::testing::expect_one_line_error(extractor.extract(small, cv::Mat(), K, &ff), "320x240");
  const cv::Mat gray(480, 640, CV_8UC1, cv::Scalar(0));
  const cv::Mat depth16(480, 640, CV_16UC1, cv::Scalar(0));
  hal::testing::expect_one_line_error(extractor.extract(gray, depth16, K, &ff), "CV_32FC1");
  hal::PinholeIntrinsics bad;
  const cv::Mat depth(480, 640, CV_32FC1, cv::Scalar(1.f));
  hal::testing::expect_one_line_error(extractor.extract(gray, depth, bad, &ff), "intrinsics");
  // A blank image is valid and has no features.
  ASSERT_TRUE(extractor.extract(gray, depth, K, &ff).ok());
  EXPECT_EQ(ff.size(), 0);
}

}  // namespace
}  // namespace hwr::estimation
