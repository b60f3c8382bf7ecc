// PlaneSegmenter on analytic depth (depth_render.hpp): planes against the scene's true faces, labels
// against the renderer's id image, errors, no allocation. Also the renderer's own closed forms.
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "depth_render.hpp"
#include "hwr/core/alloc_counter.hpp"
#include "hwr/detect/plane_segmentation.hpp"

namespace hwr::detect {
namespace {

constexpr double kDeg = M_PI / 180.0;

// A plane of the scene in the world (a box face or the floor), id = the object carrying it.
struct TruePlane {
  int id = 0;
  Eigen::Vector3d normal_world, point_world;
};

// The true plane in the camera frame with fit_plane's convention: normal towards the camera, n.p = d.
PlaneFit in_camera(const TruePlane& t, const Eigen::Isometry3d& T_world_cam) {
  const Eigen::Isometry3d T_cam_world = T_world_cam.inverse();
  PlaneFit f;
  f.normal = T_cam_world.linear() * t.normal_world;
  const Eigen::Vector3d p = T_cam_world * t.point_world;
  if (f.normal.dot(p) > 0.0) f.normal = -f.normal;
  f.d = f.normal.dot(p);
  f.ok = true;
  return f;
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) / kDeg;
}

// Floor (id 0), a frontal wall (id 1) at 2.95 m and a board (id 2) tilted 30 deg towards the camera,
// 6 mm thick, floating at 1.9 m; the camera 1.2 m up looking 11 deg down.
struct ThreePlaneScene {
  testing::RenderScene scene;
  std::vector<TruePlane> truth;
  Eigen::Isometry3d T_world_cam = testing::look_at({0.0, 0.0, 1.2}, {3.0, 0.0, 0.6});
};

ThreePlaneScene three_plane_scene() {
  ThreePlaneScene s;
  s.scene.has_floor = true;
  s.scene.floor_z_m = 0.0;
  s.truth.push_back({0, Eigen::Vector3d::UnitZ(), Eigen::Vector3d::Zero()});
  testing::RenderBox wall;
  wall.T_world_box.translation() = Eigen::Vector3d(3.0, 0.0, 1.0);
  wall.half_size_m = Eigen::Vector3d(0.05, 2.5, 1.2);
  wall.id = 1;
  s.scene.boxes.push_back(wall);
  s.truth.push_back({1, -Eigen::Vector3d::UnitX(), Eigen::Vector3d(2.95, 0.0, 0.0)});
  testing::RenderBox board;
  board.T_world_box.linear() = Eigen::AngleAxisd(-30.0 * kDeg, Eigen::Vector3d::UnitY()).toRotationMatrix();
  board.T_world_box.translation() = Eigen::Vector3d(1.9, 0.45, 0.45);
  board.half_size_m = Eigen::Vector3d(0.35, 0.3, 0.003);
  board.id = 2;
  s.scene.boxes.push_back(board);
  const Eigen::Vector3d board_up = board.T_world_box.linear() * Eigen::Vector3d::UnitZ();
  s.truth.push_back({2, board_up, board.T_world_box * Eigen::Vector3d(0.0, 0.0, 0.003)});
  return s;
}

struct Pipeline {
  OrganizedCloud cloud;
  PlaneSegmenter segmenter;
};

Pipeline make_pipeline(const hal::PinholeIntrinsics& K, const PlaneSegmentationConfig& config = {}) {
  auto cloud = OrganizedCloud::create(OrganizedCloudConfig{}, K);
  EXPECT_TRUE(cloud.ok()) << cloud.status().to_string();
  auto seg = PlaneSegmenter::create(config, DepthNoiseModel{}, cloud->width(), cloud->height());
  EXPECT_TRUE(seg.ok()) << seg.status().to_string();
  return Pipeline{std::move(cloud).value(), std::move(seg).value()};
}

// Per object id: how many of its valid grid points carry each plane label (-1 included).
std::map<int, std::map<int, int>> label_counts(const Pipeline& p, const cv::Mat& id) {
  std::map<int, std::map<int, int>> counts;
  const int stride = p.cloud.stride_px();
  for (int y = 0; y < p.cloud.height(); ++y) {
    for (int x = 0; x < p.cloud.width(); ++x) {
      if (!p.cloud.valid(x, y)) continue;
      const int object = id.at<int>(y * stride, x * stride);
      ++counts[object][p.segmenter.point_label(p.cloud, x, y)];
    }
  }
  return counts;
}

// The plane holding most of the object's points (-1: none) and the fraction it holds.
int majority_plane(const std::map<int, int>& counts, double* fraction) {
  int best = -1, best_count = 0, total = 0;
  for (const auto& [label, count] : counts) {
    total += count;
    if (label >= 0 && count > best_count) {
      best = label;
      best_count = count;
    }
  }
  *fraction = total > 0 ? static_cast<double>(best_count) / total : 0.0;
  return best;
}

TEST(DepthRender, GivenAFrontalWallThenEveryPixelSeesItsDistanceAndNoiseHasTheModelSigma) {
  hal::PinholeIntrinsics K = testing::vga_intrinsics();
  K.width = 160;
  K.height = 120;
  K.fx = K.fy = 131.25;
  K.cx = 79.5;
  K.cy = 59.5;
  const Eigen::Isometry3d T_world_cam = testing::look_at({0.0, 0.0, 1.0}, {5.0, 0.0, 1.0});
  // Camera x right = world -y, y down = world -z, z forward = world +x.
  EXPECT_LT((T_world_cam.linear().col(0) - Eigen::Vector3d(0, -1, 0)).norm(), 1e-12);
  EXPECT_LT((T_world_cam.linear().col(1) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-12);
  EXPECT_LT((T_world_cam.linear().col(2) - Eigen::Vector3d(1, 0, 0)).norm(), 1e-12);

  testing::RenderScene scene;
  testing::RenderBox wall;
  wall.T_world_box.translation() = Eigen::Vector3d(2.1, 0.0, 1.0);
  wall.half_size_m = Eigen::Vector3d(0.1, 3.0, 3.0);
  wall.id = 5;
  scene.boxes.push_back(wall);
  // A small box above the optical axis, x in [1.45, 1.55], z in [1.25, 1.35]: its front face at depth
  // 1.45 from the row of its top edge, then its bottom face (seen from below) down to the row of
  // the bottom face's far edge.
  testing::RenderBox above;
  above.T_world_box.translation() = Eigen::Vector3d(1.5, 0.0, 1.3);
  above.half_size_m = Eigen::Vector3d(0.05, 0.05, 0.05);
  above.id = 6;
  scene.boxes.push_back(above);
  const testing::RenderedDepth r = testing::render_depth(scene, K, T_world_cam);
  int above_rows_lo = K.height, above_rows_hi = -1;
  for (int v = 0; v < K.height; ++v) {
    for (int u = 0; u < K.width; ++u) {
      const int id = r.id.at<int>(v, u);
      if (id == 6) {
        above_rows_lo = std::min(above_rows_lo, v);
        above_rows_hi = std::max(above_rows_hi, v);
        const float z = r.depth_m.at<float>(v, u);
        EXPECT_TRUE(z >= 1.45f - 1e-6f && z <= 1.55f + 1e-6f) << z;
      } else {
        ASSERT_EQ(id, 5);
        EXPECT_NEAR(r.depth_m.at<float>(v, u), 2.0, 1e-6);
      }
    }
  }
  EXPECT_EQ(above_rows_lo, static_cast<int>(std::ceil(K.cy - K.fy * 0.35 / 1.45)));
  EXPECT_EQ(above_rows_hi, static_cast<int>(std::floor(K.cy - K.fy * 0.25 / 1.55)));

  testing::RenderOptions noisy;
  noisy.add_noise = true;
  noisy.nan_fraction = 0.1;
  scene.boxes.pop_back();
  const testing::RenderedDepth n = testing::render_depth(scene, K, T_world_cam, noisy);
  double sum2 = 0.0;
  int finite = 0;
  for (int v = 0; v < K.height; ++v) {
    for (int u = 0; u < K.width; ++u) {
      const float z = n.depth_m.at<float>(v, u);
      if (!std::isfinite(z)) continue;
      sum2 += (z - 2.0) * (z - 2.0);
      ++finite;
    }
  }
  const int pixels = K.width * K.height;
  EXPECT_NEAR(1.0 - static_cast<double>(finite) / pixels, 0.1, 0.01);
  EXPECT_NEAR(std::sqrt(sum2 / finite), DepthNoiseModel{}.sigma_m(2.0),
              0.03 * DepthNoiseModel{}.sigma_m(2.0));
}

TEST(PlaneSegmenter, GivenAFloorAWallAndATiltedBoardThenThreePlanesWithTheirPoses) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  const ThreePlaneScene s = three_plane_scene();
  const testing::RenderedDepth r = testing::render_depth(s.scene, K, s.T_world_cam);
  Pipeline p = make_pipeline(K);
  ASSERT_TRUE(p.cloud.build(r.depth_m).ok());
  ASSERT_TRUE(p.segmenter.segment(p.cloud).ok());
  ASSERT_EQ(p.segmenter.plane_count(), 3);
  for (int i = 1; i < p.segmenter.plane_count(); ++i) {
    EXPECT_GE(p.segmenter.plane(i - 1).cells, p.segmenter.plane(i).cells);
  }

  const auto counts = label_counts(p, r.id);
  std::vector<int> matched;
  for (const TruePlane& t : s.truth) {
    double fraction = 0.0;
    const int plane = majority_plane(counts.at(t.id), &fraction);
    ASSERT_GE(plane, 0) << "object " << t.id;
    matched.push_back(plane);
    EXPECT_GE(fraction, 0.95) << "object " << t.id;
    const PlaneFit truth = in_camera(t, s.T_world_cam);
    const PlaneFit& fit = p.segmenter.plane(plane).fit;
    EXPECT_LT(angle_deg(fit.normal, truth.normal), 0.5) << "object " << t.id;
    EXPECT_NEAR(fit.d, truth.d, 0.001) << "object " << t.id;
    // Cells along the board's 6 mm edge face are taken in (within the noise model's bound).
    EXPECT_LT(fit.rms_m, 0.001) << "object " << t.id;
  }
  EXPECT_NE(matched[0], matched[1]);
  EXPECT_NE(matched[0], matched[2]);
  EXPECT_NE(matched[1], matched[2]);

  // Cell labels and bounding boxes agree: every labelled cell is inside its plane's box, and a
  // plane's cell count is the number of cells carrying its label.
  std::vector<int> cells(3, 0);
  for (int cy = 0; cy < p.segmenter.cells_y(); ++cy) {
    for (int cx = 0; cx < p.segmenter.cells_x(); ++cx) {
      const int l = p.segmenter.cell_label(cx, cy);
      if (l < 0) continue;
      ++cells[static_cast<size_t>(l)];
      const PlaneRegion& region = p.segmenter.plane(l);
      EXPECT_TRUE(cx >= region.min_cx && cx <= region.max_cx && cy >= region.min_cy && cy <= region.max_cy);
    }
  }
  for (int i = 0; i < 3; ++i) EXPECT_EQ(cells[static_cast<size_t>(i)], p.segmenter.plane(i).cells);
}

TEST(PlaneSegmenter, GivenDepthNoiseAndDropoutsThenEachObjectsPlaneIsWithin2DegreesAnd3mm) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  const ThreePlaneScene s = three_plane_scene();
  Pipeline p = make_pipeline(K);
  for (uint32_t seed : {1u, 2u, 3u}) {
    testing::RenderOptions options;
    options.add_noise = true;
    options.noise_seed = seed;
    options.nan_fraction = 0.02;
    options.nan_seed = 100 + seed;
    const testing::RenderedDepth r = testing::render_depth(s.scene, K, s.T_world_cam, options);
    ASSERT_TRUE(p.cloud.build(r.depth_m).ok());
    ASSERT_TRUE(p.segmenter.segment(p.cloud).ok());
    ASSERT_GE(p.segmenter.plane_count(), 3) << "seed " << seed;
    const auto counts = label_counts(p, r.id);
    std::vector<int> matched;
    for (const TruePlane& t : s.truth) {
      double fraction = 0.0;
      const int plane = majority_plane(counts.at(t.id), &fraction);
      ASSERT_GE(plane, 0) << "seed " << seed << " object " << t.id;
      matched.push_back(plane);
      EXPECT_GE(fraction, 0.8) << "seed " << seed << " object " << t.id;
      const PlaneFit truth = in_camera(t, s.T_world_cam);
      const PlaneFit& fit = p.segmenter.plane(plane).fit;
      EXPECT_LT(angle_deg(fit.normal, truth.normal), 2.0) << "seed " << seed << " object " << t.id;
      EXPECT_NEAR(fit.d, truth.d, 0.003) << "seed " << seed << " object " << t.id;
    }
    EXPECT_NE(matched[0], matched[1]);
    EXPECT_NE(matched[0], matched[2]);
    EXPECT_NE(matched[1], matched[2]);
  }
}

TEST(PlaneSegmenter, GivenAFilletJointThenItsBaseAndWebArePerpendicularPlanesMeetingOnTheTrueSeam) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  // add_fillet(cx 1.6, cy 0, top_z 0.7, facing 180 deg): yaw = facing + 90 deg, start = centre - L/2 x.
  const double L = 0.8, bw = 0.3, ww = 0.25, t = 0.01, yaw = 270.0 * kDeg;
  const Eigen::Vector3d x_dir(std::cos(yaw), std::sin(yaw), 0.0);
  const Eigen::Vector3d start = Eigen::Vector3d(1.6, 0.0, 0.7 + t) - 0.5 * L * x_dir;
  const testing::FilletJoint joint = testing::make_fillet(start, yaw, L, bw, ww, t, 1, 2);
  EXPECT_LT((joint.end_world - joint.start_world - L * x_dir).norm(), 1e-12);
  testing::RenderScene scene;
  scene.boxes = {joint.base, joint.web};
  const Eigen::Isometry3d T_world_cam = testing::look_at({0.2, 0.0, 1.5}, {1.6, 0.0, 0.8});
  const testing::RenderedDepth r = testing::render_depth(scene, K, T_world_cam);

  Pipeline p = make_pipeline(K);
  ASSERT_TRUE(p.cloud.build(r.depth_m).ok());
  ASSERT_TRUE(p.segmenter.segment(p.cloud).ok());
  const auto counts = label_counts(p, r.id);
  // Base top: world +z through the seam; web seam face: joint -y (towards the viewer, world -x).
  const Eigen::Vector3d y_joint = joint.T_world_joint.linear().col(1);
  const std::vector<TruePlane> truth = {{1, Eigen::Vector3d::UnitZ(), start}, {2, -y_joint, start}};
  EXPECT_LT((-y_joint - Eigen::Vector3d(-1, 0, 0)).norm(), 1e-12);
  std::vector<int> matched;
  for (const TruePlane& tp : truth) {
    double fraction = 0.0;
    const int plane = majority_plane(counts.at(tp.id), &fraction);
    ASSERT_GE(plane, 0) << "object " << tp.id;
    matched.push_back(plane);
    EXPECT_GE(fraction, 0.9) << "object " << tp.id;
    const PlaneFit expected = in_camera(tp, T_world_cam);
    const PlaneFit& fit = p.segmenter.plane(plane).fit;
    EXPECT_LT(angle_deg(fit.normal, expected.normal), 0.5) << "object " << tp.id;
    // d is the offset at the camera, 1.5 m of lever arm from the plate: the base's 4-5 rows of cells
    // take in a little of the web and the 1 cm front edge (within the noise model), which tilts
    // the plane by ~0.2 deg and moves d by a few mm. Where the plane was seen it is within 1 mm.
    EXPECT_NEAR(expected.signed_distance(fit.centroid), 0.0, 0.001) << "object " << tp.id;
    EXPECT_NEAR(fit.d, expected.d, 0.006) << "object " << tp.id;
    // The true seam's ends lie on both faces.
    const Eigen::Isometry3d T_cam_world = T_world_cam.inverse();
    EXPECT_NEAR(fit.signed_distance(T_cam_world * joint.start_world), 0.0, 0.001);
    EXPECT_NEAR(fit.signed_distance(T_cam_world * joint.end_world), 0.0, 0.001);
  }
  ASSERT_NE(matched[0], matched[1]);
  EXPECT_NEAR(angle_deg(p.segmenter.plane(matched[0]).fit.normal, p.segmenter.plane(matched[1]).fit.normal),
              90.0, 0.5);
}

TEST(PlaneSegmenter, GivenMaxPlanesTwoThenTheTwoLargestRegionsAreKept) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  const ThreePlaneScene s = three_plane_scene();
  const testing::RenderedDepth r = testing::render_depth(s.scene, K, s.T_world_cam);
  Pipeline all = make_pipeline(K);
  PlaneSegmentationConfig two;
  two.max_planes = 2;
  Pipeline kept = make_pipeline(K, two);
  ASSERT_TRUE(all.cloud.build(r.depth_m).ok());
  ASSERT_TRUE(all.segmenter.segment(all.cloud).ok());
  ASSERT_TRUE(kept.cloud.build(r.depth_m).ok());
  ASSERT_TRUE(kept.segmenter.segment(kept.cloud).ok());
  ASSERT_EQ(all.segmenter.plane_count(), 3);
  ASSERT_EQ(kept.segmenter.plane_count(), 2);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(kept.segmenter.plane(i).cells, all.segmenter.plane(i).cells);
    EXPECT_LT((kept.segmenter.plane(i).fit.normal - all.segmenter.plane(i).fit.normal).norm(), 1e-12);
  }
  for (int cy = 0; cy < kept.segmenter.cells_y(); ++cy) {
    for (int cx = 0; cx < kept.segmenter.cells_x(); ++cx) {
      const int l = all.segmenter.cell_label(cx, cy);
      EXPECT_EQ(kept.segmenter.cell_label(cx, cy), l < 2 ? l : -1);
    }
  }
}

TEST(PlaneSegmenter, GivenAllNaNDepthThenNoPlanesAndOk) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  Pipeline p = make_pipeline(K);
  const cv::Mat depth(K.height, K.width, CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  ASSERT_TRUE(p.cloud.build(depth).ok());
  EXPECT_EQ(p.cloud.valid_count(), 0);
  ASSERT_TRUE(p.segmenter.segment(p.cloud).ok());
  EXPECT_EQ(p.segmenter.plane_count(), 0);
  for (int cy = 0; cy < p.segmenter.cells_y(); ++cy) {
    for (int cx = 0; cx < p.segmenter.cells_x(); ++cx) EXPECT_EQ(p.segmenter.cell_label(cx, cy), -1);
  }
  EXPECT_EQ(p.segmenter.point_label(p.cloud, 10, 10), -1);
}

TEST(PlaneSegmenter, GivenACloudOfAnotherSizeThenSegmentIsInvalidArgument) {
  hal::PinholeIntrinsics small = testing::vga_intrinsics();
  small.width = 320;
  small.height = 240;
  auto cloud = OrganizedCloud::create(OrganizedCloudConfig{}, small);
  ASSERT_TRUE(cloud.ok());
  auto seg = PlaneSegmenter::create(PlaneSegmentationConfig{}, DepthNoiseModel{}, 320, 240);
  ASSERT_TRUE(seg.ok());
  const core::Status st = seg->segment(*cloud);
  EXPECT_EQ(st.code(), core::ErrorCode::kInvalidArgument);
  EXPECT_NE(st.message().find("160x120"), std::string::npos) << st.message();
}

TEST(PlaneSegmenter, GivenABadConfigOrGridThenCreateIsInvalidArgumentNamingTheField) {
  const auto expect_bad = [](const PlaneSegmentationConfig& c, const DepthNoiseModel& n, int w, int h,
                             const std::string& field) {
    auto seg = PlaneSegmenter::create(c, n, w, h);
    ASSERT_FALSE(seg.ok()) << field;
    EXPECT_EQ(seg.status().code(), core::ErrorCode::kInvalidArgument);
    EXPECT_NE(seg.status().message().find(field), std::string::npos) << seg.status().message();
  };
  const DepthNoiseModel noise;
  PlaneSegmentationConfig c;
  c.cell_points = 1;
  expect_bad(c, noise, 320, 240, "cell_points");
  c = {};
  c.cell_min_valid = 0.0;
  expect_bad(c, noise, 320, 240, "cell_min_valid");
  c = {};
  c.cell_min_valid = 1.5;
  expect_bad(c, noise, 320, 240, "cell_min_valid");
  c = {};
  c.cell_max_rms_sigmas = -1.0;
  expect_bad(c, noise, 320, 240, "cell_max_rms_sigmas");
  c = {};
  c.cell_rms_floor_m = std::numeric_limits<double>::quiet_NaN();
  expect_bad(c, noise, 320, 240, "cell_rms_floor_m");
  c = {};
  c.merge_angle_rad = 4.0;
  expect_bad(c, noise, 320, 240, "merge_angle_rad");
  c = {};
  c.merge_offset_sigmas = -0.1;
  expect_bad(c, noise, 320, 240, "merge_offset_sigmas");
  c = {};
  c.merge_offset_floor_m = -0.1;
  expect_bad(c, noise, 320, 240, "merge_offset_floor_m");
  c = {};
  c.min_plane_cells = 0;
  expect_bad(c, noise, 320, 240, "min_plane_cells");
  c = {};
  c.max_planes = 0;
  expect_bad(c, noise, 320, 240, "max_planes");
  DepthNoiseModel bad_noise;
  bad_noise.k_per_m = -1.0;
  expect_bad(PlaneSegmentationConfig{}, bad_noise, 320, 240, "k_per_m");
  expect_bad(PlaneSegmentationConfig{}, noise, 5, 240, "smaller than one cell");
  EXPECT_TRUE(PlaneSegmenter::create(PlaneSegmentationConfig{}, noise, 6, 6).ok());
}

TEST(PlaneSegmenter, GivenACreatedSegmenterThenBuildAndSegmentAllocateNothing) {
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  const ThreePlaneScene s = three_plane_scene();
  testing::RenderOptions options;
  options.add_noise = true;
  const testing::RenderedDepth r = testing::render_depth(s.scene, K, s.T_world_cam, options);
  Pipeline p = make_pipeline(K);
  core::AllocationScope scope;
  ASSERT_TRUE(p.cloud.build(r.depth_m).ok());
  ASSERT_TRUE(p.segmenter.segment(p.cloud).ok());
  ASSERT_TRUE(p.cloud.build(r.depth_m).ok());
  ASSERT_TRUE(p.segmenter.segment(p.cloud).ok());
  EXPECT_EQ(scope.allocations(), 0u);
  EXPECT_GE(p.segmenter.plane_count(), 3);
}

}  // namespace
}  // namespace hwr::detect
