// The geometric seam detector (detect/geometric_seam_detector.hpp, fillet_finder.hpp) on depth
// images ray-cast analytically (depth_render.hpp). Oracles: the fillet's true seam, built in the
// simulator's joint convention (make_fillet), and scenes with no joint at all.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "depth_render.hpp"
#include "hwr/core/alloc_counter.hpp"
#include "hwr/detect/geometric_seam_detector.hpp"
#include "hwr/detect/seam_metrics.hpp"

namespace hwr::detect {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

// A bench (top at 0.85 m, as the simulator's) on the floor; a fillet on it, seam from x = -0.3 to
// 0.3 m along world x at y = 0.1 m, the base towards the camera (world -y), 1 cm plates.
struct BenchScene {
  testing::RenderScene scene;
  testing::FilletJoint joint;
};

BenchScene bench_with_fillet(double length_m = 0.6, double yaw_rad = 0.0) {
  BenchScene s;
  s.scene.has_floor = true;
  testing::RenderBox bench;
  bench.T_world_box.translation() = Eigen::Vector3d(0.0, 0.0, 0.425);
  bench.half_size_m = Eigen::Vector3d(1.2, 0.4, 0.425);
  bench.id = 1;
  s.scene.boxes.push_back(bench);
  const double t = 0.01;
  s.joint = testing::make_fillet(Eigen::Vector3d(-0.5 * length_m * std::cos(yaw_rad),
                                                 0.1 - 0.5 * length_m * std::sin(yaw_rad), 0.85 + t),
                                 yaw_rad, length_m, 0.3, 0.2, t, 2, 3);
  s.scene.boxes.push_back(s.joint.base);
  s.scene.boxes.push_back(s.joint.web);
  return s;
}

Eigen::Isometry3d bench_camera(double distance_m = 1.3) {
  return testing::look_at(Eigen::Vector3d(0.0, -distance_m, 1.55), Eigen::Vector3d(0.0, 0.0, 0.9));
}

std::unique_ptr<GeometricSeamDetector> make_detector(const hal::PinholeIntrinsics& K,
                                                     const GeometricSeamConfig& config = {}) {
  auto d = GeometricSeamDetector::create(config, K);
  EXPECT_TRUE(d.ok()) << d.status().message();
  return d.ok() ? std::move(d.value()) : nullptr;
}

KeyframeView view_of(const cv::Mat& depth, const hal::PinholeIntrinsics& K,
                     const Eigen::Isometry3d& T_world_cam) {
  KeyframeView v;
  v.keyframe_id = 7;
  v.t_ns = 123;
  v.K = K;
  v.depth_m = &depth;
  v.T_world_cam = T_world_cam;
  return v;
}

double distance_to_line(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return distance_to_line_m(p, a, (b - a).normalized());
}

// Errors of a detected seam against the truth: lateral (the detected ends' distance to the true
// line, the larger) and each end's distance to the nearer true end.
struct SeamErrors {
  double lateral_m = 0;
  std::array<double, 2> end_m{0, 0};
};

SeamErrors seam_errors(const Detection& d, const testing::FilletJoint& j) {
  SeamErrors e;
  for (int k = 0; k < 2; ++k) {
    e.lateral_m = std::max(e.lateral_m, distance_to_line(d.seam_world[k], j.start_world, j.end_world));
    e.end_m[k] = std::min((d.seam_world[k] - j.start_world).norm(), (d.seam_world[k] - j.end_world).norm());
  }
  return e;
}

TEST(GeometricSeamDetector, GivenANoiseFreeFilletOnABenchThenOneSeamAlongItWithBothEnds) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  for (double yaw_deg : {0.0, 25.0, -40.0}) {
    const BenchScene s = bench_with_fillet(0.6, yaw_deg * kDeg);
    const Eigen::Isometry3d T_world_cam = bench_camera();
    const testing::RenderedDepth r = testing::render_depth(s.scene, K, T_world_cam);
    auto detector = make_detector(K);
    ASSERT_NE(detector, nullptr);
    DetectionList out(8);
    ASSERT_TRUE(detector->detect(view_of(r.depth_m, K, T_world_cam), &out).ok());
    ASSERT_EQ(out.size(), 1) << "yaw " << yaw_deg << ": planes " << detector->last_stats().planes
                             << ", candidates " << detector->last_stats().candidates;
    const Detection& d = out[0];
    EXPECT_EQ(d.kind, SeamKind::kFillet);
    EXPECT_EQ(d.source, DetectionSource::kGeometry);
    EXPECT_EQ(d.keyframe_id, 7);
    EXPECT_EQ(d.t_ns, 123);
    EXPECT_GT(d.confidence, 0.5f);
    EXPECT_TRUE(d.end_observed[0] && d.end_observed[1]);
    const SeamErrors e = seam_errors(d, s.joint);
    EXPECT_LT(e.lateral_m, 0.0005) << "yaw " << yaw_deg;
    EXPECT_LT(e.end_m[0], 0.004) << "yaw " << yaw_deg;
    EXPECT_LT(e.end_m[1], 0.004) << "yaw " << yaw_deg;
    EXPECT_NEAR(d.length_m(), 0.6, 0.006);
    for (int k = 0; k < 2; ++k) EXPECT_LT((d.seam_world[k] - T_world_cam * d.seam_cam[k]).norm(), 1e-12);
    // The box holds both plates' centres; its image rectangle lies inside the image.
    const Eigen::Isometry3d T_box_world = d.T_world_box.inverse();
    for (const testing::RenderBox* plate : {&s.joint.base, &s.joint.web}) {
      const Eigen::Vector3d c = T_box_world * plate->T_world_box.translation();
      EXPECT_TRUE(std::fabs(c.x()) <= d.half_size_m.x() && std::fabs(c.y()) <= d.half_size_m.y() &&
                  std::fabs(c.z()) <= d.half_size_m.z());
    }
    EXPECT_GT(d.box_px.area(), 100.0f);
    EXPECT_GE(d.box_px.x, 0.0f);
    EXPECT_LE(d.box_px.x + d.box_px.width, K.width - 1.0f);
  }
}

TEST(GeometricSeamDetector, GivenStereoLikeNoiseThenTheSeamIsFoundWithinMillimetres) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  const BenchScene s = bench_with_fillet();
  const Eigen::Isometry3d T_world_cam = bench_camera();
  auto detector = make_detector(K);
  ASSERT_NE(detector, nullptr);
  std::vector<double> lateral, ends;
  for (uint32_t seed = 1; seed <= 5; ++seed) {
    testing::RenderOptions o;
    o.add_noise = true;
    o.noise_seed = seed;
    o.nan_fraction = 0.05;
    o.nan_seed = 100 + seed;
    const testing::RenderedDepth r = testing::render_depth(s.scene, K, T_world_cam, o);
    DetectionList out(8);
    ASSERT_TRUE(detector->detect(view_of(r.depth_m, K, T_world_cam), &out).ok());
    ASSERT_EQ(out.size(), 1) << "seed " << seed;
    const SeamErrors e = seam_errors(out[0], s.joint);
    lateral.push_back(e.lateral_m);
    ends.push_back(e.end_m[0]);
    ends.push_back(e.end_m[1]);
  }
  std::sort(lateral.begin(), lateral.end());
  std::sort(ends.begin(), ends.end());
  EXPECT_LT(lateral[lateral.size() / 2], 0.002);
  EXPECT_LT(ends[ends.size() / 2], 0.004);
}

// A floor fillet (the sim's floor_fillet_c: 1.2 m, 1.5 cm plates, a 30 cm web) from 1.5 to 2.5 m
// with the stereo noise: far away sigma(z) (13 mm at 2.9 m) is near the plates' thickness, and the
// bands and the refit scale with it.
TEST(GeometricSeamDetector, GivenAFloorFilletUpTo2point5mAwayWithNoiseThenItIsFound) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  testing::RenderScene scene;
  scene.has_floor = true;
  const testing::FilletJoint j = testing::make_fillet({-0.6, 0.2, 0.015}, 0.0, 1.2, 0.4, 0.3, 0.015, 2, 3);
  scene.boxes = {j.base, j.web};
  auto detector = make_detector(K);
  ASSERT_NE(detector, nullptr);
  for (double distance_m : {1.5, 2.0, 2.5}) {
    const Eigen::Isometry3d T = testing::look_at({0, -distance_m, 1.45}, {0, 0, 0.1});
    testing::RenderOptions o;
    o.add_noise = true;
    const testing::RenderedDepth r = testing::render_depth(scene, K, T, o);
    DetectionList out(8);
    ASSERT_TRUE(detector->detect(view_of(r.depth_m, K, T), &out).ok());
    ASSERT_EQ(out.size(), 1) << distance_m;
    const SeamErrors e = seam_errors(out[0], j);
    EXPECT_LT(e.lateral_m, 0.01) << distance_m;
  }
}

TEST(GeometricSeamDetector, GivenASeamRunningOutOfTheImageThenThatEndIsNotObserved) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  const BenchScene s = bench_with_fillet(1.8);
  const Eigen::Isometry3d T_world_cam =
      testing::look_at(Eigen::Vector3d(0.5, -1.0, 1.45), Eigen::Vector3d(0.5, 0.1, 0.9));
  const testing::RenderedDepth r = testing::render_depth(s.scene, K, T_world_cam);
  auto detector = make_detector(K);
  ASSERT_NE(detector, nullptr);
  DetectionList out(8);
  ASSERT_TRUE(detector->detect(view_of(r.depth_m, K, T_world_cam), &out).ok());
  ASSERT_EQ(out.size(), 1);
  const Detection& d = out[0];
  // The seam runs from x = -0.9 to 0.9 m; the camera at x = 0.5 m sees its +x end, not its -x end.
  const int minus_end = d.seam_world[0].x() < d.seam_world[1].x() ? 0 : 1;
  EXPECT_FALSE(d.end_observed[minus_end]);
  EXPECT_TRUE(d.end_observed[1 - minus_end]);
  EXPECT_LT((d.seam_world[1 - minus_end] - s.joint.end_world).norm(), 0.01);
  EXPECT_LT(distance_to_line(d.seam_world[minus_end], s.joint.start_world, s.joint.end_world), 0.003);
}

TEST(GeometricSeamDetector, GivenClutterWithoutAJointThenNothingIsDetected) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  auto detector = make_detector(K);
  ASSERT_NE(detector, nullptr);
  DetectionList out(8);
  {
    // A bare bench: its front face meets the floor in a concave corner, but it is 0.85 m tall and
    // its top face recedes behind its edge.
    BenchScene s = bench_with_fillet();
    s.scene.boxes.resize(1);
    const Eigen::Isometry3d T = bench_camera();
    const testing::RenderedDepth r = testing::render_depth(s.scene, K, T);
    ASSERT_TRUE(detector->detect(view_of(r.depth_m, K, T), &out).ok());
    EXPECT_EQ(out.size(), 0);
  }
  {
    // A 40 cm crate on the floor, seen from 1.6 m: a concave corner with the floor, a web-high front,
    // but no free top edge.
    testing::RenderScene scene;
    scene.has_floor = true;
    testing::RenderBox crate;
    crate.T_world_box.translation() = Eigen::Vector3d(0.0, 0.0, 0.2);
    crate.T_world_box.linear() = Eigen::AngleAxisd(10 * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    crate.half_size_m = Eigen::Vector3d(0.3, 0.3, 0.2);
    scene.boxes.push_back(crate);
    for (const double distance_m : {1.6, 3.3}) {
      // From 3.3 m (rays ~20 deg below horizontal, noise 17 mm) the top face recedes ~9 cm behind the
      // front face's edge: farther than 5 cm, but not twice its own run.
      const Eigen::Isometry3d T =
          testing::look_at(Eigen::Vector3d(0.0, -distance_m, 1.4), Eigen::Vector3d(0.0, 0.0, 0.2));
      testing::RenderOptions o;
      o.add_noise = distance_m > 2.0;
      const testing::RenderedDepth r = testing::render_depth(scene, K, T, o);
      ASSERT_TRUE(detector->detect(view_of(r.depth_m, K, T), &out).ok());
      EXPECT_EQ(out.size(), 0) << distance_m;
    }
  }
  {
    // A wall standing on the floor, its top above the image.
    testing::RenderScene scene;
    scene.has_floor = true;
    testing::RenderBox wall;
    wall.T_world_box.translation() = Eigen::Vector3d(0.0, 1.0, 1.5);
    wall.half_size_m = Eigen::Vector3d(3.0, 0.1, 1.5);
    scene.boxes.push_back(wall);
    const Eigen::Isometry3d T =
        testing::look_at(Eigen::Vector3d(0.0, -0.8, 1.2), Eigen::Vector3d(0.0, 0.9, 0.3));
    const testing::RenderedDepth r = testing::render_depth(scene, K, T);
    ASSERT_TRUE(detector->detect(view_of(r.depth_m, K, T), &out).ok());
    EXPECT_EQ(out.size(), 0);
  }
}

TEST(GeometricSeamDetector, GivenBadInputThenClearErrorsAndGivenNoDepthThenNoDetections) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  auto detector = make_detector(K);
  ASSERT_NE(detector, nullptr);
  DetectionList out(4);
  KeyframeView v;
  v.K = K;
  EXPECT_FALSE(detector->detect(v, &out).ok());  // no depth
  const cv::Mat wrong_type(K.height, K.width, CV_16UC1, cv::Scalar(1000));
  v.depth_m = &wrong_type;
  EXPECT_FALSE(detector->detect(v, &out).ok());
  const cv::Mat wrong_size(240, 320, CV_32FC1, cv::Scalar(1.0f));
  v.depth_m = &wrong_size;
  EXPECT_FALSE(detector->detect(v, &out).ok());
  const cv::Mat nan_depth(K.height, K.width, CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  v.depth_m = &nan_depth;
  hal::PinholeIntrinsics other = K;
  other.fx = 500.0;
  v.K = other;
  const core::Status s = detector->detect(v, &out);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find("intrinsics"), std::string::npos) << s.message();
  v.K = K;
  EXPECT_TRUE(detector->detect(v, &out).ok());
  EXPECT_EQ(out.size(), 0);
  const cv::Mat zeros(K.height, K.width, CV_32FC1, cv::Scalar(0.0f));
  v.depth_m = &zeros;
  EXPECT_TRUE(detector->detect(v, &out).ok());
  EXPECT_EQ(out.size(), 0);
  EXPECT_FALSE(detector->detect(v, nullptr).ok());

  GeometricSeamConfig bad;
  bad.max_detections = 0;
  EXPECT_FALSE(GeometricSeamDetector::create(bad, K).ok());
  GeometricSeamConfig bad_band;
  bad_band.fillet.band_far_m = 0.005;  // below band_near_m
  const auto e = GeometricSeamDetector::create(bad_band, K);
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.status().message().find("band_near_m"), std::string::npos) << e.status().message();
}

TEST(GeometricSeamDetector, GivenACreatedDetectorThenDetectAllocatesNothing) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  const BenchScene s = bench_with_fillet();
  const Eigen::Isometry3d T_world_cam = bench_camera();
  testing::RenderOptions o;
  o.add_noise = true;
  const testing::RenderedDepth r = testing::render_depth(s.scene, K, T_world_cam, o);
  auto detector = make_detector(K);
  ASSERT_NE(detector, nullptr);
  DetectionList out(8);
  const KeyframeView v = view_of(r.depth_m, K, T_world_cam);
  ASSERT_TRUE(detector->detect(v, &out).ok());
  core::AllocationScope scope;
  ASSERT_TRUE(detector->detect(v, &out).ok());
  EXPECT_EQ(scope.allocations(), 0u);
  EXPECT_EQ(out.size(), 1);
}

}  // namespace
}  // namespace hwr::detect
