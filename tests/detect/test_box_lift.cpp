// Lifting a model's 2D box to a 3D detection with the depth (detect/box_lift.hpp), on depth images
// ray-cast analytically (depth_render.hpp) with the camera at the world origin. Oracles: the plates'
// known depths and poses, and the back-projection of the box's pixels (eq. 3).

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "depth_render.hpp"
#include "hwr/core/alloc_counter.hpp"
#include "hwr/detect/box_lift.hpp"

namespace hwr::detect {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

// A 1 cm plate whose front face (towards the camera) is at depth front_z_m, centred on (x, y).
testing::RenderBox plate(double x_m, double y_m, double front_z_m, double half_x_m, double half_y_m, int id) {
  testing::RenderBox b;
  b.T_world_box.translation() = Eigen::Vector3d(x_m, y_m, front_z_m + 0.005);
  b.half_size_m = Eigen::Vector3d(half_x_m, half_y_m, 0.005);
  b.id = id;
  return b;
}

cv::Mat render(const testing::RenderScene& scene, const testing::RenderOptions& o = {}) {
  return testing::render_depth(scene, testing::vga_intrinsics(), Eigen::Isometry3d::Identity(), o).depth_m;
}

BoxLifter make_lifter(const BoxLiftConfig& config = {}) {
  auto l = BoxLifter::create(config, testing::vga_intrinsics());
  EXPECT_TRUE(l.ok()) << l.status().message();
  return std::move(l.value());
}

// The camera-frame point at depth z_m on the ray of pixel (u, v) (eq. 3).
Eigen::Vector3d at_pixel(double u, double v, double z_m) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  return Eigen::Vector3d((u - K.cx) / K.fx * z_m, (v - K.cy) / K.fy * z_m, z_m);
}

TEST(BoxLift, GivenAFrontalPlateFillingTheBoxThenTheBoxIsCentredOnItsDepthWithZTowardsTheCamera) {
  testing::RenderScene scene;
  scene.boxes.push_back(plate(0, 0, 1.5, 5.0, 5.0, 1));
  const cv::Mat depth = render(scene);
  BoxLifter lifter = make_lifter();
  Detection d;
  // Pixels 200..399 x 120..279; every second one from the first: columns 200..398, rows 120..278.
  const auto r = lifter.lift(depth, cv::Rect2f(200, 120, 200, 160), &d);
  ASSERT_TRUE(r.ok()) << r.status().message();
  ASSERT_EQ(r.value(), LiftOutcome::kLifted);
  const Eigen::Vector3d centre = d.T_cam_box.translation();
  EXPECT_LT((centre - at_pixel(299, 199, 1.5)).norm(), 0.002) << centre.transpose();
  EXPECT_GT(d.T_cam_box.linear().col(2).dot(-Eigen::Vector3d::UnitZ()), std::cos(0.5 * kDeg));
  EXPECT_GT(d.T_cam_box.linear().col(0).dot(Eigen::Vector3d::UnitX()),
            std::cos(0.5 * kDeg));  // the long side
  EXPECT_NEAR(d.T_cam_box.linear().determinant(), 1.0, 1e-9);
  // The 2 / 98 % points of an even spread: 96 % of the half width seen (198 px at 1.5 m).
  const double half_x = 0.5 * 198.0 / 525.0 * 1.5, half_y = 0.5 * 158.0 / 525.0 * 1.5;
  EXPECT_NEAR(d.half_size_m.x(), 0.96 * half_x, 0.02 * half_x);
  EXPECT_NEAR(d.half_size_m.y(), 0.96 * half_y, 0.02 * half_y);
  EXPECT_DOUBLE_EQ(d.half_size_m.z(), BoxLiftConfig{}.min_half_size_m);  // a flat plate
  // The seam: the box's x-axis end to end, neither end observed; both normals the plate's.
  EXPECT_LT((d.seam_cam[0] - (centre - d.half_size_m.x() * d.T_cam_box.linear().col(0))).norm(), 1e-12);
  EXPECT_LT((d.seam_cam[1] - (centre + d.half_size_m.x() * d.T_cam_box.linear().col(0))).norm(), 1e-12);
  EXPECT_FALSE(d.end_observed[0]);
  EXPECT_FALSE(d.end_observed[1]);
  EXPECT_LT((d.plate_normal_cam[0] - d.T_cam_box.linear().col(2)).norm(), 1e-12);
  // Its image rectangle: the corners projected, inside the model's box by the quantiles' 4 %.
  EXPECT_NEAR(d.box_px.x, 204, 3);
  EXPECT_NEAR(d.box_px.x + d.box_px.width, 395, 3);
  EXPECT_NEAR(d.box_px.y, 123, 3);
  EXPECT_NEAR(d.box_px.y + d.box_px.height, 276, 3);
}

TEST(BoxLift, GivenAPlateInFrontOfAFarWallThenTheDepthBandDropsTheWall) {
  testing::RenderScene scene;
  // The plate at 1 m covers pixels ~220..379 x 136..263 of the box 200..399 x 120..279: 64 % of it.
  const Eigen::Vector3d c = at_pixel(299.5, 199.5, 1.0);
  scene.boxes.push_back(plate(c.x(), c.y(), 1.0, 80.0 / 525.0, 64.0 / 525.0, 1));
  scene.boxes.push_back(plate(0, 0, 2.5, 10.0, 10.0, 2));
  const cv::Mat depth = render(scene);
  BoxLifter lifter = make_lifter();
  Detection d;
  const auto r = lifter.lift(depth, cv::Rect2f(200, 120, 200, 160), &d);
  ASSERT_TRUE(r.ok() && r.value() == LiftOutcome::kLifted);
  EXPECT_NEAR(d.T_cam_box.translation().z(), 1.0, 1e-6);
  EXPECT_LT((d.T_cam_box.translation() - c).norm(), 0.003);
  EXPECT_DOUBLE_EQ(d.half_size_m.z(), BoxLiftConfig{}.min_half_size_m);  // nothing of the wall
  EXPECT_NEAR(d.half_size_m.x(), 0.96 * 80.0 / 525.0, 0.01);
}

TEST(BoxLift, GivenATiltedPlateWithStereoNoiseThenZIsItsNormalWithin1Degree) {
  for (const double tilt_deg : {-40.0, 0.0, 25.0, 55.0}) {
    testing::RenderScene scene;
    testing::RenderBox b = plate(0.05, -0.02, 1.6, 0.5, 0.3, 1);
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(tilt_deg * kDeg, Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(0.5 * tilt_deg * kDeg, Eigen::Vector3d::UnitY()))
                                  .toRotationMatrix();
    b.T_world_box.linear() = R;
    scene.boxes.push_back(b);
    testing::RenderOptions o;
    o.add_noise = true;
    o.nan_fraction = 0.1;
    const cv::Mat depth = render(scene, o);
    BoxLifter lifter = make_lifter();
    Detection d;
    const auto r = lifter.lift(depth, cv::Rect2f(260, 190, 120, 90), &d);
    ASSERT_TRUE(r.ok() && r.value() == LiftOutcome::kLifted) << tilt_deg;
    const Eigen::Vector3d normal_towards_camera = -R.col(2);  // the plate's front face
    EXPECT_GT(d.T_cam_box.linear().col(2).dot(normal_towards_camera), std::cos(1.0 * kDeg)) << tilt_deg;
    // A plane: the noise's thickness only, its 2 / 98 % points +- 2.05 sigma(z) (sigma(1.6 m) = 4.8 mm).
    EXPECT_LT(d.half_size_m.z(), 3.0 * DepthNoiseModel{}.sigma_m(1.6)) << tilt_deg;
  }
}

TEST(BoxLift, GivenTooFewValidDepthPixelsThenNoDetectionAndNoError) {
  testing::RenderScene scene;
  scene.boxes.push_back(plate(0, 0, 1.5, 5.0, 5.0, 1));
  cv::Mat depth = render(scene);
  // Invalid depth in the box's rows, each kind of invalid in turn: NaN, inf, 0, < 0, beyond 3.5 m.
  const float bad[] = {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), 0.0f,
                       -1.0f, 5.0f};
  for (int v = 100; v < 300; ++v) {
    for (int u = 180; u < 420; ++u) depth.at<float>(v, u) = bad[(u + v) % 5];
  }
  BoxLifter lifter = make_lifter();
  Detection d;
  d.confidence = 0.5f;
  auto r = lifter.lift(depth, cv::Rect2f(200, 120, 200, 160), &d);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.value(), LiftOutcome::kTooFewDepth);
  EXPECT_EQ(d.confidence, 0.5f);  // untouched
  // A box of 6 x 6 pixels (9 points at stride 2), one outside the image, an empty one.
  EXPECT_EQ(lifter.lift(depth, cv::Rect2f(10, 10, 6, 6), &d).value(), LiftOutcome::kTooFewDepth);
  EXPECT_EQ(lifter.lift(depth, cv::Rect2f(700, 10, 50, 50), &d).value(), LiftOutcome::kTooFewDepth);
  EXPECT_EQ(lifter.lift(depth, cv::Rect2f(10, 10, 0, 0), &d).value(), LiftOutcome::kTooFewDepth);
  // The same box on valid depth lifts.
  EXPECT_EQ(lifter.lift(render(scene), cv::Rect2f(200, 120, 200, 160), &d).value(), LiftOutcome::kLifted);
}

TEST(BoxLift, GivenBadDepthOrConfigThenInvalidArgumentNamingIt) {
  BoxLifter lifter = make_lifter();
  Detection d;
  const cv::Mat small(240, 320, CV_32FC1, cv::Scalar(1.0f));
  const cv::Mat doubles(480, 640, CV_64FC1, cv::Scalar(1.0));
  EXPECT_EQ(lifter.lift(small, cv::Rect2f(0, 0, 10, 10), &d).status().code(),
            core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(lifter.lift(doubles, cv::Rect2f(0, 0, 10, 10), &d).status().code(),
            core::ErrorCode::kInvalidArgument);
  BoxLiftConfig bad;
  bad.stride_px = 0;
  auto e = BoxLifter::create(bad, testing::vga_intrinsics());
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.status().message().find("stride_px"), std::string::npos);
  bad = BoxLiftConfig{};
  bad.extent_quantile = 0.5;
  EXPECT_FALSE(BoxLifter::create(bad, testing::vga_intrinsics()).ok());
  EXPECT_FALSE(BoxLifter::create(BoxLiftConfig{}, hal::PinholeIntrinsics{}).ok());
}

TEST(BoxLift, GivenTheSameInputTwiceThenTheSameBoxAndLiftAllocatesNothing) {
  testing::RenderScene scene;
  testing::RenderBox b = plate(0.0, 0.0, 1.4, 0.5, 0.3, 1);
  b.T_world_box.linear() = Eigen::AngleAxisd(30 * kDeg, Eigen::Vector3d::UnitX()).toRotationMatrix();
  scene.boxes.push_back(b);
  testing::RenderOptions o;
  o.add_noise = true;
  const cv::Mat depth = render(scene, o);
  BoxLifter lifter = make_lifter();
  Detection first, second;
  ASSERT_EQ(lifter.lift(depth, cv::Rect2f(220, 160, 200, 150), &first).value(), LiftOutcome::kLifted);
  core::AllocationScope scope;
  const auto r = lifter.lift(depth, cv::Rect2f(220, 160, 200, 150), &second);
  EXPECT_EQ(scope.allocations(), 0u);
  ASSERT_EQ(r.value(), LiftOutcome::kLifted);
  EXPECT_TRUE(first.T_cam_box.isApprox(second.T_cam_box, 0.0));
  EXPECT_EQ(first.half_size_m, second.half_size_m);
}

}  // namespace
}  // namespace hwr::detect
