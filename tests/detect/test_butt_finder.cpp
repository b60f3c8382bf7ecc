// Butt joints in the geometric seam detector (detect/raised_regions.hpp, butt_finder.hpp) on depth and
// colour images ray-cast analytically (depth_render.hpp: point-sampled, Lambert-shaded as the
// simulator's). Oracles: the butt's true seam, built in the simulator's joint convention (make_butt),
// and scenes with no butt at all: one plate, textured plates, a bench's edge, a crate.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "depth_render.hpp"
#include "hwr/core/alloc_counter.hpp"
#include "hwr/detect/butt_finder.hpp"
#include "hwr/detect/geometric_seam_detector.hpp"
#include "hwr/detect/raised_regions.hpp"
#include "hwr/detect/seam_metrics.hpp"

namespace hwr::detect {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;
constexpr double kBenchTop = 0.85;

// A 2.4 x 1.0 m bench (top at 0.85 m, as the simulator's) on the floor.
testing::RenderScene bench_scene() {
  testing::RenderScene scene;
  scene.has_floor = true;
  testing::RenderBox bench;
  bench.T_world_box.translation() = Eigen::Vector3d(0.0, 0.0, 0.5 * kBenchTop);
  bench.half_size_m = Eigen::Vector3d(1.2, 0.5, 0.5 * kBenchTop);
  bench.id = 1;
  bench.albedo = 0.55;
  bench.texture = testing::Texture::kScratched;  // planks' grooves and grain: lines on the support
  bench.texture_seed = 11;
  scene.boxes.push_back(bench);
  return scene;
}

struct ButtScene {
  testing::RenderScene scene;
  testing::ButtJoint joint;
};

// A butt on the bench, its seam centred on the bench's centre along yaw: 0.6 m long, two 0.3 m wide
// plates (the simulator's butt_n2: 10 mm, a 3 mm root gap).
ButtScene bench_with_butt(double yaw_rad, double length_m = 0.6, double gap_m = 0.003) {
  ButtScene s;
  s.scene = bench_scene();
  const Eigen::Vector3d dir(std::cos(yaw_rad), std::sin(yaw_rad), 0.0);
  const double t = 0.010;
  s.joint = testing::make_butt(Eigen::Vector3d(0.0, 0.0, kBenchTop + t) - 0.5 * length_m * dir, yaw_rad,
                               length_m, 0.3, t, gap_m, 2, 3);
  s.scene.boxes.push_back(s.joint.left);
  s.scene.boxes.push_back(s.joint.right);
  return s;
}

// The camera 1.5 m above the floor, distance_m from the bench's centre (horizontally) towards
// azimuth_deg (0: from -y), looking at it.
Eigen::Isometry3d bench_camera(double distance_m, double azimuth_deg = 0.0) {
  const double a = azimuth_deg * kDeg;
  return testing::look_at(Eigen::Vector3d(distance_m * std::sin(a), -distance_m * std::cos(a), 1.5),
                          Eigen::Vector3d(0.0, 0.0, kBenchTop));
}

// Depth with the simulator's stereo noise and 1 % dropouts, colour with 2 levels of pixel noise.
testing::RenderedDepth render(const testing::RenderScene& scene, const hal::PinholeIntrinsics& K,
                              const Eigen::Isometry3d& T_world_cam, uint32_t seed = 1) {
  testing::RenderOptions o;
  o.add_noise = true;
  o.noise_seed = seed;
  o.nan_fraction = 0.01;
  o.nan_seed = 100 + seed;
  o.colour = true;
  o.pixel_noise_seed = 200 + seed;
  return testing::render_depth(scene, K, T_world_cam, o);
}

std::unique_ptr<GeometricSeamDetector> make_detector(const hal::PinholeIntrinsics& K,
                                                     const GeometricSeamConfig& config = {}) {
  auto d = GeometricSeamDetector::create(config, K);
  EXPECT_TRUE(d.ok()) << d.status().message();
  return d.ok() ? std::move(d.value()) : nullptr;
}

KeyframeView view_of(const testing::RenderedDepth& r, const hal::PinholeIntrinsics& K,
                     const Eigen::Isometry3d& T_world_cam, bool with_colour = true) {
  KeyframeView v;
  v.keyframe_id = 3;
  v.t_ns = 456;
  v.K = K;
  v.depth_m = &r.depth_m;
  v.bgr = with_colour ? &r.bgr : nullptr;
  v.T_world_cam = T_world_cam;
  return v;
}

int count_kind(const DetectionList& out, SeamKind kind) {
  int n = 0;
  for (int i = 0; i < out.size(); ++i) n += out[i].kind == kind ? 1 : 0;
  return n;
}

int count_supporting(const DetectionList& out) {
  int n = 0;
  for (int i = 0; i < out.size(); ++i) n += out[i].support_only ? 1 : 0;
  return n;
}

const Detection* first_of_kind(const DetectionList& out, SeamKind kind) {
  for (int i = 0; i < out.size(); ++i)
    if (out[i].kind == kind) return &out[i];
  return nullptr;
}

// The detected seam against the true one: the larger distance of its ends from the true line, and
// each detected end's distance to the nearer true end.
struct SeamErrors {
  double lateral_m = 0;
  std::array<double, 2> end_m{0, 0};
};

SeamErrors seam_errors(const Detection& d, const testing::ButtJoint& j) {
  SeamErrors e;
  const Eigen::Vector3d u = (j.end_world - j.start_world).normalized();
  for (int k = 0; k < 2; ++k) {
    e.lateral_m = std::max(e.lateral_m, distance_to_line_m(d.seam_world[k], j.start_world, u));
    e.end_m[k] = std::min((d.seam_world[k] - j.start_world).norm(), (d.seam_world[k] - j.end_world).norm());
  }
  return e;
}

// A butt on the floor (the simulator's floor_butt_e: 1.0 m long, 0.4 m plates, 15 mm, 3 mm gap), its
// seam centred at the origin along yaw.
ButtScene floor_butt(double yaw_rad) {
  ButtScene s;
  s.scene.has_floor = true;
  const Eigen::Vector3d dir(std::cos(yaw_rad), std::sin(yaw_rad), 0.0);
  s.joint =
      testing::make_butt(Eigen::Vector3d(0.0, 0.0, 0.015) - 0.5 * dir, yaw_rad, 1.0, 0.4, 0.015, 0.003, 2, 3);
  s.scene.boxes = {s.joint.left, s.joint.right};
  return s;
}

// The seam crosses the image at an angle in all of these views: a seam exactly along a pixel row can
// fall between the rows' centres, and a point-sampled image (the simulator's) then does not show it.
// Lateral error: the line is found to a fraction of a pixel, and a pixel across the seam spans 5-10 mm
// of the plates at these ranges and angles (2.9-4.8 mm per pixel, foreshortened by the 20-35 deg
// elevation).
TEST(ButtFinder, GivenAButtAtSeveralYawsAndRangesWithNoiseThenItsSeamIsFoundWithinMillimetres) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  auto detector = make_detector(K);
  ASSERT_NE(detector, nullptr);
  struct View {
    bool on_floor;
    double yaw_deg, distance_m, azimuth_deg;
  };
  for (const View& view :
       {View{false, 8.0, 1.2, 0.0}, View{false, 25.0, 1.5, -10.0}, View{false, -15.0, 1.8, 20.0},
        View{false, 60.0, 1.4, 0.0}, View{true, 84.0, 2.0, 0.0}, View{true, -20.0, 2.0, 15.0}}) {
    const ButtScene s =
        view.on_floor ? floor_butt(view.yaw_deg * kDeg) : bench_with_butt(view.yaw_deg * kDeg);
    const double length = (s.joint.end_world - s.joint.start_world).norm();
    const Eigen::Isometry3d T =
        view.on_floor ? testing::look_at({view.distance_m * std::sin(view.azimuth_deg * kDeg),
                                          -view.distance_m * std::cos(view.azimuth_deg * kDeg), 1.5},
                                         {0.0, 0.0, 0.0})
                      : bench_camera(view.distance_m, view.azimuth_deg);
    const testing::RenderedDepth r = render(s.scene, K, T);
    DetectionList out(8);
    ASSERT_TRUE(detector->detect(view_of(r, K, T), &out).ok());
    const std::string what = std::string(view.on_floor ? "floor" : "bench") + " yaw " +
                             std::to_string(view.yaw_deg) + " at " + std::to_string(view.distance_m) +
                             " m: " + std::to_string(detector->last_stats().raised_regions) +
                             " raised regions";
    ASSERT_EQ(count_kind(out, SeamKind::kButt), 1) << what;
    EXPECT_EQ(count_kind(out, SeamKind::kFillet), 0) << what;
    const Detection& d = *first_of_kind(out, SeamKind::kButt);
    EXPECT_EQ(d.source, DetectionSource::kGeometry);
    EXPECT_FALSE(d.support_only) << what;
    EXPECT_EQ(d.keyframe_id, 3);
    EXPECT_EQ(d.t_ns, 456);
    EXPECT_GT(d.confidence, 0.0f);
    EXPECT_TRUE(d.end_observed[0] && d.end_observed[1]) << what;
    const SeamErrors e = seam_errors(d, s.joint);
    EXPECT_LT(e.lateral_m, 0.005) << what;
    EXPECT_LT(e.end_m[0], 0.01) << what;
    EXPECT_LT(e.end_m[1], 0.01) << what;
    EXPECT_NEAR(d.length_m(), length, 0.015) << what;
    for (int k = 0; k < 2; ++k) {
      EXPECT_LT((d.seam_world[k] - T * d.seam_cam[k]).norm(), 1e-12);
      // The plates' normal: world up, within a degree.
      EXPECT_GT((T.linear() * d.plate_normal_cam[k]).z(), std::cos(1.0 * kDeg)) << what;
    }
    // The box holds both plates' centres and lies along the seam; its image rectangle is in the image.
    const Eigen::Isometry3d T_box_world = d.T_world_box.inverse();
    for (const testing::RenderBox* plate : {&s.joint.left, &s.joint.right}) {
      const Eigen::Vector3d c = T_box_world * plate->T_world_box.translation();
      EXPECT_TRUE(std::fabs(c.x()) <= d.half_size_m.x() && std::fabs(c.y()) <= d.half_size_m.y() &&
                  std::fabs(c.z()) <= d.half_size_m.z())
          << what;
    }
    EXPECT_GT(std::fabs(d.T_world_box.linear().col(0).dot(s.joint.end_world - s.joint.start_world)),
              0.99 * length);
    EXPECT_GT(d.box_px.area(), 100.0f);
  }
}

// Seen along the seam, the rays into the gap reach the bench: its line is deeper than the plates
// beside it. With no colour image the depth dip alone finds it.
TEST(ButtFinder, GivenAButtSeenAlongItsSeamAndNoColourImageThenTheDepthDipFindsIt) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  auto detector = make_detector(K);
  ASSERT_NE(detector, nullptr);
  const ButtScene s = bench_with_butt(88.0 * kDeg, 0.6, 0.003);
  const Eigen::Isometry3d T = bench_camera(1.3);
  const testing::RenderedDepth r = render(s.scene, K, T);
  DetectionList out(8);
  ASSERT_TRUE(detector->detect(view_of(r, K, T, /*with_colour=*/false), &out).ok());
  ASSERT_EQ(count_kind(out, SeamKind::kButt), 1);
  const SeamErrors e = seam_errors(*first_of_kind(out, SeamKind::kButt), s.joint);
  EXPECT_LT(e.lateral_m, 0.004);
}

// One plate (as wide as the butt's two), plain, speckled or scratched and brushed (texture lines
// along and across it), on the textured bench: raised, but no line crosses it. A texture line may
// reach the supporting bar (it cannot make a seam alone: seam_fusion.hpp), rarely: 1 of these 12
// views.
TEST(ButtFinder, GivenASinglePlateOrATexturedPlateOnABenchThenNoButtIsFound) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  auto detector = make_detector(K);
  ASSERT_NE(detector, nullptr);
  int raised = 0, supporting = 0;
  for (const testing::Texture texture :
       {testing::Texture::kPlain, testing::Texture::kSpeckled, testing::Texture::kScratched}) {
    for (uint32_t seed = 1; seed <= 4; ++seed) {
      testing::RenderScene scene = bench_scene();
      testing::RenderBox plate;
      plate.T_world_box.linear() =
          Eigen::AngleAxisd((10.0 * seed - 15.0) * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
      plate.T_world_box.translation() = Eigen::Vector3d(0.0, 0.0, kBenchTop + 0.005);
      plate.half_size_m = Eigen::Vector3d(0.3, 0.3, 0.005);
      plate.id = 2;
      plate.texture = texture;
      plate.texture_seed = seed;
      scene.boxes.push_back(plate);
      const Eigen::Isometry3d T = bench_camera(1.2 + 0.2 * seed, 5.0 * seed);
      const testing::RenderedDepth r = render(scene, K, T, seed);
      DetectionList out(8);
      ASSERT_TRUE(detector->detect(view_of(r, K, T), &out).ok());
      EXPECT_EQ(out.size() - count_supporting(out), 0)
          << "texture " << static_cast<int>(texture) << " seed " << seed;
      supporting += count_supporting(out);
      raised += detector->last_stats().raised_regions;
    }
  }
  EXPECT_GE(raised, 10);  // the plate was seen as raised (the line search had something to reject)
  EXPECT_LE(supporting, 2);
}

// No plates: the bench's edge (a step down to the floor, the top's grooves beside it), a crate on the
// floor (box edges), the bench seen from afar.
TEST(ButtFinder, GivenABenchEdgeOrACrateThenNoButtIsFound) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  auto detector = make_detector(K);
  ASSERT_NE(detector, nullptr);
  DetectionList out(8);
  const testing::RenderScene bench = bench_scene();
  for (const Eigen::Isometry3d& T : {bench_camera(1.0), bench_camera(1.6, 30.0), bench_camera(2.8, -20.0)}) {
    const testing::RenderedDepth r = render(bench, K, T);
    ASSERT_TRUE(detector->detect(view_of(r, K, T), &out).ok());
    EXPECT_EQ(out.size(), 0);
  }
  testing::RenderScene crate_scene;
  crate_scene.has_floor = true;
  testing::RenderBox crate;
  crate.T_world_box.translation() = Eigen::Vector3d(0.0, 0.0, 0.25);
  crate.T_world_box.linear() = Eigen::AngleAxisd(20 * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  crate.half_size_m = Eigen::Vector3d(0.4, 0.3, 0.25);
  crate.texture = testing::Texture::kScratched;
  crate_scene.boxes.push_back(crate);
  for (const double distance_m : {1.5, 2.5}) {
    const Eigen::Isometry3d T = testing::look_at({0.0, -distance_m, 1.5}, {0.0, 0.0, 0.25});
    const testing::RenderedDepth r = render(crate_scene, K, T);
    ASSERT_TRUE(detector->detect(view_of(r, K, T), &out).ok());
    EXPECT_EQ(out.size(), 0) << distance_m;
  }
}

// The raised-region cue alone: the butt's plates are one region a plate's thickness above the bench,
// the bench alone has none.
TEST(RaisedRegionFinder, GivenPlatesOnABenchThenOneRegionAtTheirThicknessAndNoneOnTheBareBench) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  auto cloud = OrganizedCloud::create({}, K);
  ASSERT_TRUE(cloud.ok());
  auto planes = PlaneSegmenter::create({}, DepthNoiseModel{}, cloud->width(), cloud->height());
  ASSERT_TRUE(planes.ok());
  auto raised = RaisedRegionFinder::create({}, DepthNoiseModel{}, cloud->width(), cloud->height());
  ASSERT_TRUE(raised.ok()) << raised.status().message();
  const Eigen::Isometry3d T = bench_camera(1.5);
  const Eigen::Vector3d up_cam = T.linear().transpose() * Eigen::Vector3d::UnitZ();
  {
    const ButtScene s = bench_with_butt(20 * kDeg);
    const testing::RenderedDepth r = render(s.scene, K, T);
    ASSERT_TRUE(cloud->build(r.depth_m).ok());
    ASSERT_TRUE(planes->segment(*cloud).ok());
    ASSERT_EQ(raised->find(*cloud, *planes, up_cam), 1);
    const RaisedRegion& region = raised->region(0);
    EXPECT_NEAR(region.thickness_m, 0.010, 0.0015);
    // The support is the bench top: its plane in the world at z = 0.85 m.
    const Eigen::Vector3d support_point_world = T * region.support.centroid;
    EXPECT_NEAR(support_point_world.z(), kBenchTop, 0.002);
    EXPECT_GT((T.linear() * region.support.normal).z(), std::cos(0.5 * kDeg));
    EXPECT_NEAR(region.area_m2, 0.6 * 0.603, 0.08);
    EXPECT_GT(region.support_fraction, 0.6);
    // Its grid points are the plates' (the renderer's ids 2 and 3), bar the blurred border.
    int on_plates = 0, points = 0;
    for (int y = region.min_y; y <= region.max_y; ++y) {
      for (int x = region.min_x; x <= region.max_x; ++x) {
        if (raised->region_label(x, y) != 0 || !raised->inner(x, y)) continue;
        ++points;
        const int id = r.id.at<int>(y * cloud->stride_px(), x * cloud->stride_px());
        on_plates += id == 2 || id == 3 ? 1 : 0;
      }
    }
    EXPECT_GT(on_plates, 0.98 * points);
  }
  {
    const testing::RenderedDepth r = render(bench_scene(), K, T);
    ASSERT_TRUE(cloud->build(r.depth_m).ok());
    ASSERT_TRUE(planes->segment(*cloud).ok());
    EXPECT_EQ(raised->find(*cloud, *planes, up_cam), 0);
  }
}

TEST(ButtFinder, GivenBadInputThenClearErrors) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  auto detector = make_detector(K);
  ASSERT_NE(detector, nullptr);
  const ButtScene s = bench_with_butt(20 * kDeg);
  const Eigen::Isometry3d T = bench_camera(1.5);
  const testing::RenderedDepth r = render(s.scene, K, T);
  DetectionList out(8);
  KeyframeView v = view_of(r, K, T);
  // A colour image of the wrong type or size is an error; an empty one is none (depth only).
  const cv::Mat grey(K.height, K.width, CV_8UC1, cv::Scalar(100));
  v.bgr = &grey;
  core::Status st = detector->detect(v, &out);
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message().find("colour"), std::string::npos) << st.message();
  const cv::Mat small(240, 320, CV_8UC3, cv::Scalar(100, 100, 100));
  v.bgr = &small;
  EXPECT_FALSE(detector->detect(v, &out).ok());
  const cv::Mat empty;
  v.bgr = &empty;
  EXPECT_TRUE(detector->detect(v, &out).ok());

  ButtConfig bad;
  bad.segments = 2;
  auto b = ButtFinder::create(bad, DepthNoiseModel{}, K);
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.status().message().find("segments"), std::string::npos) << b.status().message();
  bad = ButtConfig{};
  bad.dark_ratio = 1.5;
  EXPECT_FALSE(ButtFinder::create(bad, DepthNoiseModel{}, K).ok());
  EXPECT_FALSE(ButtFinder::create(ButtConfig{}, DepthNoiseModel{}, hal::PinholeIntrinsics{}).ok());
  RaisedRegionConfig bad_raised;
  bad_raised.window_points = 4;
  auto rr = RaisedRegionFinder::create(bad_raised, DepthNoiseModel{}, 320, 240);
  ASSERT_FALSE(rr.ok());
  EXPECT_NE(rr.status().message().find("window_points"), std::string::npos) << rr.status().message();
  bad_raised = RaisedRegionConfig{};
  bad_raised.max_thickness_m = 0.005;  // below min_thickness_m
  EXPECT_FALSE(RaisedRegionFinder::create(bad_raised, DepthNoiseModel{}, 320, 240).ok());
  GeometricSeamConfig bad_detector;
  bad_detector.butt.min_z = 0.0;
  EXPECT_FALSE(GeometricSeamDetector::create(bad_detector, K).ok());
  bad = ButtConfig{};
  bad.support_z = bad.min_z + 1.0;  // above the bar
  b = ButtFinder::create(bad, DepthNoiseModel{}, K);
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.status().message().find("support_z"), std::string::npos) << b.status().message();
}

// GIVEN a butt found confidently (bench, 1.5 m)
// WHEN the bar is raised above its line's significance, with the supporting bar below it or at the
//      bar
// THEN the same seam comes out as a supporting detection (Detection::support_only), or not at all.
TEST(ButtFinder, GivenALineBetweenTheSupportingBarAndTheBarThenItIsASupportingDetection) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  const ButtScene s = bench_with_butt(20 * kDeg);
  const Eigen::Isometry3d T = bench_camera(1.5);
  const testing::RenderedDepth r = render(s.scene, K, T);
  DetectionList out(8);
  auto detector = make_detector(K);
  ASSERT_NE(detector, nullptr);
  ASSERT_TRUE(detector->detect(view_of(r, K, T), &out).ok());
  ASSERT_EQ(count_kind(out, SeamKind::kButt), 1);
  const Detection confident = *first_of_kind(out, SeamKind::kButt);
  ASSERT_FALSE(confident.support_only);
  GeometricSeamConfig high;
  high.butt.min_z = 100.0;  // far above any line's significance
  high.butt.support_z = 3.5;
  auto supported = make_detector(K, high);
  ASSERT_NE(supported, nullptr);
  ASSERT_TRUE(supported->detect(view_of(r, K, T), &out).ok());
  ASSERT_EQ(count_kind(out, SeamKind::kButt), 1);
  const Detection& d = *first_of_kind(out, SeamKind::kButt);
  EXPECT_TRUE(d.support_only);
  for (int k = 0; k < 2; ++k) EXPECT_LT((d.seam_world[k] - confident.seam_world[k]).norm(), 1e-9);
  high.butt.support_z = high.butt.min_z;  // no supporting detections
  auto strict = make_detector(K, high);
  ASSERT_NE(strict, nullptr);
  ASSERT_TRUE(strict->detect(view_of(r, K, T), &out).ok());
  EXPECT_EQ(count_kind(out, SeamKind::kButt), 0);
}

TEST(ButtFinder, GivenACreatedDetectorThenDetectingAButtWithColourAllocatesNothing) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  const ButtScene s = bench_with_butt(25 * kDeg);
  const Eigen::Isometry3d T = bench_camera(1.5, -10.0);
  const testing::RenderedDepth r = render(s.scene, K, T);
  auto detector = make_detector(K);
  ASSERT_NE(detector, nullptr);
  DetectionList out(8);
  const KeyframeView v = view_of(r, K, T);
  ASSERT_TRUE(detector->detect(v, &out).ok());
  core::AllocationScope scope;
  ASSERT_TRUE(detector->detect(v, &out).ok());
  EXPECT_EQ(scope.allocations(), 0u);
  EXPECT_EQ(count_kind(out, SeamKind::kButt), 1);
}

}  // namespace
}  // namespace hwr::detect
