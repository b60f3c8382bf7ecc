// Renderer geometry against closed-form oracles: z-depth of planes at every pixel, ray distances
// to boxes and pipes, invalid specs, buffer reuse and packet-width invariance; area sampling, shadows
// and ambient occlusion against what they should do to a pixel's light.

#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "hwr/sim/renderer.hpp"
#include "sim_test_util.hpp"

namespace hwr::sim {
namespace {

using testing::look_at;
using testing::pose;

// fx != fy and cy off-centre, so that swapped axes or a centred principal point would show.
hal::PinholeIntrinsics vga() { return testing::vga(525.0, 520.0, 241.0); }

// Scene-frame direction of pixel (u, v), scaled so that its camera z component is 1.
Eigen::Vector3d pixel_ray(const Eigen::Isometry3d& T_scene_cam, const hal::PinholeIntrinsics& K, int u,
                          int v) {
  return T_scene_cam.linear() * Eigen::Vector3d((u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0);
}

SceneSpec ground_only() {
  SceneSpec s;
  s.name = "ground_only";
  s.has_room = false;
  s.ground_extent_m = 30.0;
  return s;
}

std::unique_ptr<Renderer> make(const SceneSpec& spec) {
  auto r = Renderer::create(spec);
  EXPECT_TRUE(r.ok()) << r.status().to_string();
  return r.ok() ? std::move(r).value() : nullptr;
}

// The pixel whose centre is nearest to a scene point's image, and a pixel's mean of B, G, R.
cv::Point nearest_pixel(const Eigen::Isometry3d& T_scene_cam, const hal::PinholeIntrinsics& K,
                        const Eigen::Vector3d& p_scene) {
  const Eigen::Vector3d p = T_scene_cam.inverse() * p_scene;
  return cv::Point(static_cast<int>(std::lround(K.fx * p.x() / p.z() + K.cx)),
                   static_cast<int>(std::lround(K.fy * p.y() / p.z() + K.cy)));
}

double grey_at(const cv::Mat& bgr, cv::Point q) {
  const cv::Vec3b p = bgr.at<cv::Vec3b>(q);
  return (p[0] + p[1] + p[2]) / 3.0;
}

// GIVEN a camera 1.5 m above an infinite-looking ground, tilted down
// WHEN rendering
// THEN every pixel whose ray meets z = 0 within range has depth -c_z / d_z (d with camera z = 1),
//      all others are 0.
TEST(RenderDepth, GroundPlaneMatchesAnalyticZDepthAtEveryPixel) {
  auto renderer = make(ground_only());
  ASSERT_TRUE(renderer);
  const hal::PinholeIntrinsics K = vga();
  const Eigen::Isometry3d T = look_at({0.37, -0.21, 1.5}, {4.3, 1.9, 0.35});
  RenderOptions options;
  cv::Mat bgr, depth;
  renderer->render(T, K, options, &bgr, &depth);
  ASSERT_EQ(depth.type(), CV_32FC1);
  ASSERT_EQ(bgr.type(), CV_8UC3);
  int seen = 0, sky = 0;
  for (int v = 0; v < K.height; ++v) {
    for (int u = 0; u < K.width; ++u) {
      const Eigen::Vector3d d = pixel_ray(T, K, u, v);
      const double z = d.z() < 0 ? -T.translation().z() / d.z() : std::numeric_limits<double>::infinity();
      const float got = depth.at<float>(v, u);
      if (z >= options.min_range_m && z <= options.max_range_m) {
        ASSERT_NEAR(got, z, 1e-5 * z) << "pixel (" << u << ", " << v << ")";
        ++seen;
      } else {
        ASSERT_EQ(got, 0.0f) << "pixel (" << u << ", " << v << ") expected beyond range, z = " << z;
        ++sky;
      }
    }
  }
  EXPECT_GT(seen, K.width * K.height / 2);
  EXPECT_GT(sky, 1000);  // the horizon is in view
}

// The inside of the room is convex: the first surface along a ray is the nearest of the six
// bounding planes.
double room_exit_depth(const SceneSpec& s, const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  double t = std::numeric_limits<double>::infinity();
  const double lo[3] = {s.room_min_xy.x(), s.room_min_xy.y(), 0.0};
  const double hi[3] = {s.room_max_xy.x(), s.room_max_xy.y(), s.room_height_m};
  for (int k = 0; k < 3; ++k) {
    if (d[k] > 0) t = std::min(t, (hi[k] - c[k]) / d[k]);
    if (d[k] < 0) t = std::min(t, (lo[k] - c[k]) / d[k]);
  }
  return t;
}

TEST(RenderDepth, RoomWallsFloorAndCeilingMatchAnalyticZDepth) {
  SceneSpec spec;
  spec.name = "empty_room";
  auto renderer = make(spec);
  ASSERT_TRUE(renderer);
  const hal::PinholeIntrinsics K = vga();
  RenderOptions options;
  options.max_range_m = 50.0;
  cv::Mat bgr, depth;
  for (const auto& [eye, target] :
       {std::pair<Eigen::Vector3d, Eigen::Vector3d>{{7.1, 0.4, 1.6}, {10.0, 1.3, 1.2}},
        {{-3.0, -2.0, 1.2}, {-10.0, -6.0, 2.5}},
        {{0.5, 0.5, 2.0}, {3.0, -6.0, 0.3}}}) {
    const Eigen::Isometry3d T = look_at(eye, target);
    renderer->render(T, K, options, &bgr, &depth);
    for (int v = 0; v < K.height; ++v) {
      for (int u = 0; u < K.width; ++u) {
        const double z = room_exit_depth(spec, eye, pixel_ray(T, K, u, v));
        ASSERT_NEAR(depth.at<float>(v, u), z, 1e-5 * z)
            << "pixel (" << u << ", " << v << ") eye " << eye.transpose();
      }
    }
  }
}

TEST(RenderDepth, RangeLimitsBlankDepthButKeepColour) {
  auto renderer = make(ground_only());
  ASSERT_TRUE(renderer);
  const hal::PinholeIntrinsics K = vga();
  const Eigen::Isometry3d T = look_at({0, 0, 1.0}, {1.0, 0, 0.0});
  RenderOptions options;
  options.min_range_m = 1.2;
  options.max_range_m = 2.0;
  options.background_bgr = {0, 0, 0};
  cv::Mat bgr, depth;
  renderer->render(T, K, options, &bgr, &depth);
  int near = 0, far = 0, inside = 0;
  for (int v = 0; v < K.height; ++v) {
    for (int u = 0; u < K.width; ++u) {
      const Eigen::Vector3d d = pixel_ray(T, K, u, v);
      if (d.z() >= 0) continue;
      const double z = -1.0 / d.z();
      const float got = depth.at<float>(v, u);
      const cv::Vec3b c = bgr.at<cv::Vec3b>(v, u);
      EXPECT_GT(c[0] + c[1] + c[2], 0) << "ground pixel not shaded";
      if (z < 1.2 - 1e-4) {
        EXPECT_EQ(got, 0.0f);
        ++near;
      } else if (z > 2.0 + 1e-4) {
        EXPECT_EQ(got, 0.0f);
        ++far;
      } else if (z > 1.2 + 1e-4 && z < 2.0 - 1e-4) {
        EXPECT_NEAR(got, z, 1e-5 * z);
        ++inside;
      }
    }
  }
  EXPECT_GT(near, 1000);
  EXPECT_GT(far, 1000);
  EXPECT_GT(inside, 1000);
}

TEST(CastRay, BoxesMatchSlabIntersection) {
  SceneSpec spec = ground_only();
  // Far apart and above the ground so that rays from near one box see only that box.
  for (int i = 0; i < 4; ++i) {
    BoxSpec b;
    b.name = "box" + std::to_string(i);
    b.size_m = Eigen::Vector3d(0.3 + 0.4 * i, 1.1 - 0.2 * i, 0.5 + 0.1 * i);
    b.T_scene_box = pose({-15.0 + 10.0 * i, 3.0 * i - 4.0, 5.0}, {0.3 * i, -0.2, 0.7 - 0.1 * i});
    spec.boxes.push_back(b);
  }
  auto renderer = make(spec);
  ASSERT_TRUE(renderer);
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  int hits = 0;
  for (const BoxSpec& box : spec.boxes) {
    for (int k = 0; k < 500; ++k) {
      Eigen::Vector3d dir(uni(rng), uni(rng), uni(rng));
      if (dir.norm() < 0.1) continue;
      dir.normalize();
      const Eigen::Vector3d aim = box.T_scene_box * Eigen::Vector3d(0.45 * uni(rng) * box.size_m.x(),
                                                                    0.45 * uni(rng) * box.size_m.y(),
                                                                    0.45 * uni(rng) * box.size_m.z());
      const Eigen::Vector3d origin = aim - 2.5 * dir;
      const double expected = testing::ray_box_slab(box.size_m, box.T_scene_box, origin, aim - origin,
                                                    /*exit_if_inside=*/false);
      ASSERT_TRUE(std::isfinite(expected));
      const Eigen::Vector3d unnormalised = (aim - origin) * (0.2 + 3.0 * std::abs(uni(rng)));
      EXPECT_NEAR(renderer->cast_ray(origin, unnormalised), expected, 1e-5) << box.name;
      ++hits;
    }
  }
  EXPECT_GT(hits, 1500);
  // Misses go to infinity (pointing up, away from everything).
  EXPECT_TRUE(std::isinf(renderer->cast_ray({0, 0, 1}, {0, 0, 1})));
  EXPECT_TRUE(std::isinf(renderer->cast_ray({0, 0, 1}, {0, 0, 0})));
  // The ground from above.
  EXPECT_NEAR(renderer->cast_ray({1.0, 2.0, 3.0}, {0.0, 0.0, -2.0}), 3.0, 1e-6);
}

TEST(CastRay, PipeWithinTessellationBound) {
  SceneSpec spec = ground_only();
  for (const double r : {0.03, 0.1, 0.4}) {
    PipeSpec p;
    p.name = "pipe" + std::to_string(spec.pipes.size());
    p.radius_m = r;
    p.length_m = 2.0;
    p.T_scene_pipe = pose({-10.0 + 10.0 * spec.pipes.size(), 2.0, 4.0}, {0.4, 1.2, -0.3});
    spec.pipes.push_back(p);
  }
  auto renderer = make(spec);
  ASSERT_TRUE(renderer);
  for (const PipeSpec& p : spec.pipes) {
    const Eigen::Matrix3d R = p.T_scene_pipe.linear();
    const Eigen::Vector3d c = p.T_scene_pipe.translation();
    double max_err = 0.0;
    for (int k = 0; k < 720; ++k) {
      // Radial ray towards the axis: the inscribed polygon lies between r cos(pi / n) and r.
      const double phi = 2.0 * M_PI * (k + 0.37) / 720.0;
      const double s = -0.9 + 1.8 * k / 720.0;
      const Eigen::Vector3d radial = R * Eigen::Vector3d(std::cos(phi), std::sin(phi), 0.0);
      const Eigen::Vector3d origin = c + R.col(2) * s + 1.5 * radial;
      const double got = renderer->cast_ray(origin, -radial);
      const double exact = 1.5 - p.radius_m;
      const double err = got - exact;
      ASSERT_GE(err, -2e-6) << p.name << " phi " << phi;
      ASSERT_LE(err, 1e-3) << p.name << " phi " << phi;  // the < 1 mm surface error requirement
      max_err = std::max(max_err, err);
    }
    EXPECT_GT(max_err, 1e-6) << "the oracle should see the facets";
    // End caps are exact: along the axis from beyond the end, off-centre.
    const Eigen::Vector3d off = R * Eigen::Vector3d(0.5 * p.radius_m, -0.2 * p.radius_m, 0.0);
    EXPECT_NEAR(renderer->cast_ray(c + off + R.col(2) * 2.0, -R.col(2)), 2.0 - 0.5 * p.length_m, 1e-5);
    EXPECT_NEAR(renderer->cast_ray(c + off - R.col(2) * 2.0, R.col(2)), 2.0 - 0.5 * p.length_m, 1e-5);
  }
}

TEST(CastRay, IBeamProfile) {
  SceneSpec spec = ground_only();
  IBeamSpec beam;
  beam.name = "beam";
  beam.T_scene_beam = pose({0.0, 0.0, 3.0}, Eigen::Vector3d::Zero());
  spec.beams.push_back(beam);
  auto renderer = make(spec);
  ASSERT_TRUE(renderer);
  // From above: the top flange at z = 3 + h/2.
  EXPECT_NEAR(renderer->cast_ray({0.3, 0.05, 5.0}, {0, 0, -1}), 2.0 - 0.5 * beam.height_m, 1e-5);
  // From the side at mid height: the web at y = t_w / 2.
  EXPECT_NEAR(renderer->cast_ray({0.3, 1.0, 3.0}, {0, -1, 0}), 1.0 - 0.5 * beam.web_thickness_m, 1e-5);
  // From the side just below the top flange's underside: still the web.
  const double z_under = 3.0 + 0.5 * beam.height_m - beam.flange_thickness_m - 0.002;
  EXPECT_NEAR(renderer->cast_ray({0.3, 1.0, z_under}, {0, -1, 0}), 1.0 - 0.5 * beam.web_thickness_m, 1e-5);
  // From the side within the flange thickness: the flange edge at y = b / 2.
  const double z_flange = 3.0 + 0.5 * beam.height_m - 0.5 * beam.flange_thickness_m;
  EXPECT_NEAR(renderer->cast_ray({0.3, 1.0, z_flange}, {0, -1, 0}), 1.0 - 0.5 * beam.flange_width_m, 1e-5);
}

TEST(RendererCreate, InvalidSpecsNameTheObject) {
  {
    SceneSpec s = ground_only();
    WeldJointSpec j;
    j.name = "tee_7";
    j.thickness_m = -0.01;
    s.joints.push_back(j);
    auto r = Renderer::create(s);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), core::ErrorCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("tee_7"), std::string::npos) << r.status().message();
    EXPECT_NE(r.status().message().find("thickness_m"), std::string::npos) << r.status().message();
  }
  {
    SceneSpec s = ground_only();
    WeldJointSpec j;
    j.name = "butt_2";
    j.type = WeldJointSpec::Type::kButt;
    j.base_width_m = 0.0;
    s.joints.push_back(j);
    auto r = Renderer::create(s);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("butt_2"), std::string::npos) << r.status().message();
  }
  {
    SceneSpec s = ground_only();
    BoxSpec b;
    b.name = "crate_3";
    b.size_m = {1.0, -2.0, 1.0};
    s.boxes.push_back(b);
    auto r = Renderer::create(s);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("crate_3"), std::string::npos) << r.status().message();
  }
  {
    SceneSpec s = ground_only();
    PipeSpec p;
    p.name = "riser";
    p.radius_m = std::nan("");
    s.pipes.push_back(p);
    auto r = Renderer::create(s);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("riser"), std::string::npos) << r.status().message();
  }
  {
    SceneSpec s = ground_only();
    IBeamSpec b;
    b.name = "girder";
    b.flange_thickness_m = 0.2;  // two flanges taller than the beam
    s.beams.push_back(b);
    auto r = Renderer::create(s);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("girder"), std::string::npos) << r.status().message();
  }
  {
    SceneSpec s = ground_only();
    BoxSpec b;
    b.name = "sheared";
    b.T_scene_box.linear() << 1, 0.5, 0, 0, 1, 0, 0, 0, 1;
    s.boxes.push_back(b);
    auto r = Renderer::create(s);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("sheared"), std::string::npos) << r.status().message();
  }
}

TEST(RendererCreate, TriangleCountOfPrimitives) {
  SceneSpec s = ground_only();
  auto ground = make(s);
  ASSERT_TRUE(ground);
  EXPECT_EQ(ground->triangle_count(), 2u);
  s.boxes.emplace_back();
  s.beams.emplace_back();
  WeldJointSpec j;
  s.joints.push_back(j);
  auto r = make(s);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->triangle_count(), 2u + 12u + 3u * 12u + 2u * 12u);
  s.has_room = true;
  auto room = make(s);
  ASSERT_TRUE(room);
  EXPECT_EQ(room->triangle_count(), r->triangle_count() + 5u * 2u);  // 4 walls and the ceiling
}

SceneSpec cluttered() {
  SceneSpec s;
  s.name = "cluttered";
  s.texture_seed = 3;
  for (int i = 0; i < 6; ++i) {
    BoxSpec b;
    b.name = "b" + std::to_string(i);
    b.size_m = Eigen::Vector3d(0.6, 0.5 + 0.1 * i, 0.4 + 0.2 * i);
    b.T_scene_box = pose({1.5 + 0.8 * i, -1.5 + 0.6 * i, 0.2 + 0.1 * i}, {0, 0, 0.3 * i});
    b.material = static_cast<Material>(i % static_cast<int>(Material::kCount));
    s.boxes.push_back(b);
  }
  PipeSpec p;
  p.name = "p";
  p.T_scene_pipe = pose({3.0, 1.0, 1.0}, {M_PI / 2, 0, 0});
  s.pipes.push_back(p);
  WeldJointSpec j;
  j.name = "j";
  j.T_scene_joint = pose({2.0, 0.0, 0.01}, {0, 0, 0.5});
  s.joints.push_back(j);
  return s;
}

TEST(RenderBuffers, SecondRenderReusesCallerBuffers) {
  auto renderer = make(cluttered());
  ASSERT_TRUE(renderer);
  const hal::PinholeIntrinsics K = vga();
  cv::Mat bgr, depth;
  renderer->render(look_at({0, 0, 1.5}, {3, 0, 0.5}), K, {}, &bgr, &depth);
  ASSERT_EQ(bgr.rows, K.height);
  ASSERT_EQ(bgr.cols, K.width);
  const uchar* bgr_data = bgr.data;
  const uchar* depth_data = depth.data;
  renderer->render(look_at({0, 0.2, 1.4}, {3, 0.5, 0.5}), K, {}, &bgr, &depth);
  EXPECT_EQ(bgr.data, bgr_data);
  EXPECT_EQ(depth.data, depth_data);
  // A buffer of the wrong type is replaced.
  cv::Mat wrong(K.height, K.width, CV_16UC1);
  renderer->render(look_at({0, 0, 1.5}, {3, 0, 0.5}), K, {}, nullptr, &wrong);
  EXPECT_EQ(wrong.type(), CV_32FC1);
}

TEST(RenderBuffers, EveryPacketWidthRendersTheSameImage) {
  auto renderer = make(cluttered());
  ASSERT_TRUE(renderer);
  const hal::PinholeIntrinsics K = vga();
  const Eigen::Isometry3d T = look_at({-0.5, 0.3, 1.6}, {3, 0, 0.4});
  RenderOptions options;
  options.packet_width = 1;
  cv::Mat bgr_ref, depth_ref;
  renderer->render(T, K, options, &bgr_ref, &depth_ref);
  for (const int width : {4, 8, 16, 0}) {
    options.packet_width = width;
    cv::Mat bgr, depth;
    renderer->render(T, K, options, &bgr, &depth);
    // Width 1 runs the scalar shader, wider packets the SIMD one: they are written to give the
    // same bytes. Embree's packet kernels may still round a hit distance differently in the last
    // bit, or decide a ray grazing an edge differently, so a few pixels may differ.
    int depth_off = 0, colour_off = 0;
    for (int v = 0; v < K.height; ++v) {
      for (int u = 0; u < K.width; ++u) {
        depth_off += depth_ref.at<float>(v, u) != depth.at<float>(v, u) ? 1 : 0;
        colour_off += bgr_ref.at<cv::Vec3b>(v, u) != bgr.at<cv::Vec3b>(v, u) ? 1 : 0;
      }
    }
    EXPECT_LE(depth_off, K.width * K.height / 1000) << "packet width " << width;
    EXPECT_LE(colour_off, K.width * K.height / 1000) << "packet width " << width;
  }
  EXPECT_GE(renderer->native_packet_width(), 1);
}

TEST(RenderBuffers, DepthOnlyAndColourOnlyAgreeWithFullRender) {
  auto renderer = make(cluttered());
  ASSERT_TRUE(renderer);
  const hal::PinholeIntrinsics K = vga();
  const Eigen::Isometry3d T = look_at({0.2, -0.4, 1.2}, {3, 0.5, 0.6});
  cv::Mat bgr, depth, bgr_only, depth_only;
  renderer->render(T, K, {}, &bgr, &depth);
  renderer->render(T, K, {}, &bgr_only, nullptr);
  renderer->render(T, K, {}, nullptr, &depth_only);
  EXPECT_EQ(cv::norm(bgr, bgr_only, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(depth, depth_only, cv::NORM_INF), 0.0);
}

// GIVEN the ground's far edge (30 m) in front of a black background, seen by a level camera so
//       that the edge lies 0.2 px below the centre of row 260 in the middle columns
// WHEN rendering with the pixel centre only and with area sampling
// THEN with the centre only row 260 is black (its centre misses the ground) and row 261 is ground;
//      with area sampling one of row 260's five samples (+3/8 px) lands on the ground, so the row
//      holds about a fifth of the ground's light, row 259 stays black, and depth is unchanged.
TEST(RenderAreaSampling, GivenAnEdgeAFifthOfAPixelIntoARowThenTheRowHoldsAFifthOfTheLight) {
  SceneSpec spec = ground_only();
  spec.ground_extent_m = 30.0;
  auto renderer = make(spec);
  ASSERT_TRUE(renderer);
  const hal::PinholeIntrinsics K = vga();  // fy 520, cy 241
  // Row v sees the ground out to 30 m when (v - cy) / fy >= h / 30: the edge at v = 260.2.
  const double h = (260.2 - K.cy) * 30.0 / K.fy;
  const Eigen::Isometry3d T = look_at({0, 0, h}, {10, 0, h});
  RenderOptions options;
  options.background_bgr = {0, 0, 0};
  options.max_range_m = 50.0;
  cv::Mat centre_bgr, centre_depth, area_bgr, area_depth;
  renderer->render(T, K, options, &centre_bgr, &centre_depth);
  options.area_sampling = true;
  renderer->render(T, K, options, &area_bgr, &area_depth);
  EXPECT_EQ(cv::norm(centre_depth, area_depth, cv::NORM_INF), 0.0);
  auto grey = [](const cv::Mat& bgr, int v, int u) {
    const cv::Vec3b p = bgr.at<cv::Vec3b>(v, u);
    return (p[0] + p[1] + p[2]) / 3.0;
  };
  double ratio_sum = 0.0;
  int columns = 0;
  for (int u = 300; u <= 340; ++u) {
    ASSERT_EQ(grey(centre_bgr, 260, u), 0.0) << "column " << u;
    ASSERT_GT(grey(centre_bgr, 261, u), 20.0) << "column " << u;
    ASSERT_EQ(grey(area_bgr, 259, u), 0.0) << "column " << u;
    ASSERT_GT(grey(area_bgr, 260, u), 0.0) << "column " << u;
    ratio_sum += grey(area_bgr, 260, u) / grey(area_bgr, 261, u);
    ++columns;
  }
  EXPECT_NEAR(ratio_sum / columns, 0.2, 0.1);
}

// Area sampling averages the same shading over the pixel: a textured view keeps its mean colour
// and loses some of its pixel-to-pixel variation (the texture is low-pass filtered); a depth-only
// render is the same as without it.
TEST(RenderAreaSampling, GivenATexturedViewThenTheMeanIsKeptAndTheImageIsSmoother) {
  auto renderer = make(cluttered());
  ASSERT_TRUE(renderer);
  const hal::PinholeIntrinsics K = vga();
  const Eigen::Isometry3d T = look_at({-0.5, 0.3, 1.6}, {3, 0, 0.4});
  RenderOptions options;
  cv::Mat centre, area, depth_centre, depth_area;
  renderer->render(T, K, options, &centre, &depth_centre);
  options.area_sampling = true;
  renderer->render(T, K, options, &area, nullptr);
  renderer->render(T, K, options, nullptr, &depth_area);
  EXPECT_EQ(cv::norm(depth_centre, depth_area, cv::NORM_INF), 0.0);
  const cv::Scalar mean_centre = cv::mean(centre), mean_area = cv::mean(area);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean_area[c], mean_centre[c], 2.0) << "channel " << c;
  auto step_energy = [](const cv::Mat& bgr) {
    double sum = 0.0;
    for (int v = 0; v < bgr.rows; ++v)
      for (int u = 1; u < bgr.cols; ++u)
        sum += cv::norm(cv::Vec3d(bgr.at<cv::Vec3b>(v, u)) - cv::Vec3d(bgr.at<cv::Vec3b>(v, u - 1)),
                        cv::NORM_L1);
    return sum;
  };
  EXPECT_LT(step_energy(area), 0.9 * step_energy(centre));
}

// GIVEN a 0.5 m cube on the ground, a light falling at 1 in 2 towards +x, a camera looking down
// WHEN rendering with and without shadows
// THEN a ground point 0.15 m beyond the cube's lit-away side (its ray to the light meets the cube
//      0.3 m up) keeps only the ambient share of its light, ambient / (ambient + diffuse n.l), while
//      points on the lit side and out of the shadow's reach are unchanged to the byte; a shadow
//      range shorter than the way to the cube casts none; depth is unchanged.
TEST(RenderLight, GivenACubeOnTheGroundThenItsShadowKeepsTheAmbientLightOnlyAndOnlyWithinRange) {
  SceneSpec spec = ground_only();
  BoxSpec box;
  box.name = "cube";
  box.size_m = Eigen::Vector3d::Constant(0.5);
  box.T_scene_box = pose({0, 0, 0.25}, {0, 0, 0});
  spec.boxes.push_back(box);
  auto renderer = make(spec);
  ASSERT_TRUE(renderer);
  const hal::PinholeIntrinsics K = vga();
  const Eigen::Isometry3d T = look_at({0.2, -2.0, 3.0}, {0.2, 0, 0});
  RenderOptions options;
  options.light_dir_scene = Eigen::Vector3d(0.5, 0, -1);
  options.ambient = 0.4;
  cv::Mat plain, shadowed, short_range, depth_plain, depth_shadowed;
  renderer->render(T, K, options, &plain, &depth_plain);
  options.shadows = true;
  renderer->render(T, K, options, &shadowed, &depth_shadowed);
  options.shadow_range_m = 0.2;  // the cube is 0.34 m away along the light from (0.4, 0, 0)
  renderer->render(T, K, options, &short_range, nullptr);
  EXPECT_EQ(cv::norm(depth_plain, depth_shadowed, cv::NORM_INF), 0.0);
  auto pixel = [&](const Eigen::Vector3d& p_scene) { return nearest_pixel(T, K, p_scene); };
  const double n_dot_l = 1.0 / std::sqrt(1.25);
  const double expected = 0.4 / (0.4 + 0.6 * n_dot_l);
  double ratio_sum = 0.0;
  int n = 0;
  for (double y = -0.2; y <= 0.2; y += 0.02) {
    const cv::Point in_shadow = pixel({0.4, y, 0}), lit_side = pixel({-0.4, y, 0}),
                    beyond = pixel({0.8, y, 0});
    ASSERT_GT(grey_at(plain, in_shadow), 30.0);
    ratio_sum += grey_at(shadowed, in_shadow) / grey_at(plain, in_shadow);
    ++n;
    EXPECT_EQ(plain.at<cv::Vec3b>(lit_side), shadowed.at<cv::Vec3b>(lit_side)) << "y " << y;
    EXPECT_EQ(plain.at<cv::Vec3b>(beyond), shadowed.at<cv::Vec3b>(beyond)) << "y " << y;
    EXPECT_EQ(plain.at<cv::Vec3b>(in_shadow), short_range.at<cv::Vec3b>(in_shadow)) << "y " << y;
  }
  EXPECT_NEAR(ratio_sum / n, expected, 0.03);
}

// GIVEN a butt joint on the ground (8 mm plates, a 4 mm root gap), seen from 0.25 m above, lit
//       straight down
// WHEN rendering with and without ambient occlusion (32 rays within 5 cm)
// THEN the ground at the bottom of the gap loses most of its ambient light: it sees the sky through
//      a slot 4 mm wide and 8 mm deep, a cosine-weighted share of sin(atan(2 / 8)) = 0.24; the plates'
//      tops, which see the whole sky, are unchanged to the byte.
TEST(RenderLight, GivenAButtGapThenAmbientOcclusionDarkensItsBottomAndLeavesOpenSurfaces) {
  SceneSpec spec = ground_only();
  WeldJointSpec joint;
  joint.name = "butt";
  joint.type = WeldJointSpec::Type::kButt;
  joint.length_m = 0.6;
  joint.base_width_m = 0.2;
  joint.thickness_m = 0.008;
  joint.gap_m = 0.004;
  joint.T_scene_joint = pose({0, 0, 0.008}, {0, 0, 0});  // seam along x from 0 to 0.6, on top
  spec.joints.push_back(joint);
  auto renderer = make(spec);
  ASSERT_TRUE(renderer);
  const hal::PinholeIntrinsics K = vga();
  const Eigen::Isometry3d T = look_at({0.3, -0.01, 0.258}, {0.3, 0, 0});
  RenderOptions options;
  options.light_dir_scene = Eigen::Vector3d(0, 0, -1);
  options.ambient = 0.5;
  cv::Mat plain, occluded;
  renderer->render(T, K, options, &plain, nullptr);
  options.ambient_occlusion_rays = 32;
  renderer->render(T, K, options, &occluded, nullptr);
  auto pixel = [&](const Eigen::Vector3d& p_scene) { return nearest_pixel(T, K, p_scene); };
  double open_sum = 0.0;
  int n = 0;
  for (double x = 0.25; x <= 0.35; x += 0.005) {
    const cv::Point bottom = pixel({x, 0, 0}), top = pixel({x, 0.03, 0.008});
    ASSERT_GT(grey_at(plain, bottom), 30.0);
    // grey = texel * (ambient * open + diffuse): the share of the sky seen from the bottom.
    open_sum += (grey_at(occluded, bottom) / grey_at(plain, bottom) - 0.5) / 0.5;
    ++n;
    EXPECT_EQ(plain.at<cv::Vec3b>(top), occluded.at<cv::Vec3b>(top)) << "x " << x;
  }
  EXPECT_NEAR(open_sum / n, 0.24, 0.08);
}

// Shadow and ambient-occlusion rays are traced in the primary rays' packets: every packet width
// gives the same image as the scalar path (up to the few grazing hits Embree's kernels may decide
// differently, as without them).
TEST(RenderLight, GivenShadowsAndAmbientOcclusionThenEveryPacketWidthRendersTheSameImage) {
  auto renderer = make(cluttered());
  ASSERT_TRUE(renderer);
  const hal::PinholeIntrinsics K = vga();
  const Eigen::Isometry3d T = look_at({-0.5, 0.3, 1.6}, {3, 0, 0.4});
  RenderOptions options;
  options.shadows = true;
  options.ambient_occlusion_rays = 6;
  options.packet_width = 1;
  cv::Mat ref, plain;
  renderer->render(T, K, options, &ref, nullptr);
  renderer->render(T, K, RenderOptions{}, &plain, nullptr);
  EXPECT_GT(cv::norm(ref, plain, cv::NORM_L1), 0.0);  // the options do change the image
  for (const int width : {4, 8, 16, 0}) {
    options.packet_width = width;
    cv::Mat bgr;
    renderer->render(T, K, options, &bgr, nullptr);
    int off = 0;
    for (int v = 0; v < K.height; ++v)
      for (int u = 0; u < K.width; ++u) off += ref.at<cv::Vec3b>(v, u) != bgr.at<cv::Vec3b>(v, u) ? 1 : 0;
    EXPECT_LE(off, K.width * K.height / 1000) << "packet width " << width;
  }
}

}  // namespace
}  // namespace hwr::sim
