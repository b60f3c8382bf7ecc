// Texture quality for the visual front end: ORB (OpenCV, 1000 features) on rendered 640x480 views
// of every material near and far, and of both weld joint types, must find >= 300 keypoints
// spread over >= 70 % of the 8x6 grid cells that show a surface.

#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "hwr/sim/renderer.hpp"
#include "sim_test_util.hpp"

namespace hwr::sim {
namespace {

using testing::look_at;
using testing::vga;

struct OrbCoverage {
  int keypoints = 0;
  int surface_cells = 0;
  int covered_cells = 0;
};

// Cells of an 8x6 grid; a cell shows a surface when most of its pixels have depth.
OrbCoverage orb_coverage(const cv::Mat& bgr, const cv::Mat& depth) {
  cv::Mat gray;
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  std::vector<cv::KeyPoint> keypoints;
  cv::ORB::create(1000)->detect(gray, keypoints);
  constexpr int kCols = 8, kRows = 6;
  const int cw = bgr.cols / kCols, ch = bgr.rows / kRows;
  int counts[kRows][kCols] = {};
  for (const cv::KeyPoint& k : keypoints) {
    const int cx = std::min(static_cast<int>(k.pt.x) / cw, kCols - 1);
    const int cy = std::min(static_cast<int>(k.pt.y) / ch, kRows - 1);
    ++counts[cy][cx];
  }
  OrbCoverage c;
  c.keypoints = static_cast<int>(keypoints.size());
  for (int y = 0; y < kRows; ++y) {
    for (int x = 0; x < kCols; ++x) {
      if (cv::countNonZero(depth(cv::Rect(x * cw, y * ch, cw, ch))) * 2 < cw * ch) continue;
      ++c.surface_cells;
      c.covered_cells += counts[y][x] > 0 ? 1 : 0;
    }
  }
  return c;
}

void expect_orb_friendly(const Renderer& renderer, const Eigen::Isometry3d& T, const std::string& what) {
  cv::Mat bgr, depth;
  RenderOptions options;
  options.max_range_m = 30.0;
  renderer.render(T, vga(), options, &bgr, &depth);
  const OrbCoverage c = orb_coverage(bgr, depth);
  EXPECT_GE(c.surface_cells, 24) << what << ": the view should mostly show surfaces";
  EXPECT_GE(c.keypoints, 300) << what;
  EXPECT_GE(c.covered_cells, 0.7 * c.surface_cells)
      << what << ": " << c.covered_cells << " of " << c.surface_cells << " cells have keypoints";
}

const char* material_name(Material m) {
  switch (m) {
    case Material::kConcrete:
      return "concrete";
    case Material::kPaintedWall:
      return "painted_wall";
    case Material::kSteel:
      return "steel";
    case Material::kRustySteel:
      return "rusty_steel";
    case Material::kWood:
      return "wood";
    case Material::kCardboard:
      return "cardboard";
    case Material::kPipe:
      return "pipe";
    case Material::kCount:
      break;
  }
  return "?";
}

class OrbPerMaterial : public ::testing::TestWithParam<Material> {};

// A large box of the material seen face-on from 0.6 m and obliquely from 3.5 m; its face looks
// towards -x, which the default light (from above, slightly from +x) only grazes: a dim case.
TEST_P(OrbPerMaterial, NearAndFarViewsHaveWellSpreadCorners) {
  SceneSpec spec;
  spec.name = std::string("orb_") + material_name(GetParam());
  spec.has_room = false;
  spec.ground_material = GetParam();
  BoxSpec wall;
  wall.name = "slab";
  wall.size_m = Eigen::Vector3d(1.0, 12.0, 6.0);
  wall.T_scene_box.translation() = Eigen::Vector3d(4.5, 0.0, 3.0);
  wall.material = GetParam();
  spec.boxes.push_back(wall);
  auto created = Renderer::create(spec);
  ASSERT_TRUE(created.ok()) << created.status().to_string();
  const Renderer& r = **created;
  expect_orb_friendly(r, look_at({3.4, 0.1, 1.6}, {4.0, 0.15, 1.55}), spec.name + " face-on at 0.6 m");
  expect_orb_friendly(r, look_at({0.5, -1.5, 2.0}, {4.0, 0.5, 1.4}), spec.name + " oblique at 3.5 m");
  // The ground of the same material from standing height, 1.5-4 m.
  expect_orb_friendly(r, look_at({0.0, 0.0, 1.5}, {-1.5, -0.3, 0.0}), spec.name + " ground");
}

INSTANTIATE_TEST_SUITE_P(AllMaterials, OrbPerMaterial,
                         ::testing::Values(Material::kConcrete, Material::kPaintedWall, Material::kSteel,
                                           Material::kRustySteel, Material::kWood, Material::kCardboard,
                                           Material::kPipe),
                         [](const ::testing::TestParamInfo<Material>& p) {
                           return std::string(material_name(p.param));
                         });

TEST(OrbJoints, FilletAndButtJointViews) {
  SceneSpec spec;
  spec.name = "orb_joints";
  spec.has_room = false;
  WeldJointSpec tee;
  tee.name = "tee";
  tee.type = WeldJointSpec::Type::kFillet;
  tee.T_scene_joint.translation() = Eigen::Vector3d(0.0, 0.0, tee.thickness_m);
  spec.joints.push_back(tee);
  WeldJointSpec butt;
  butt.name = "butt";
  butt.type = WeldJointSpec::Type::kButt;
  butt.T_scene_joint.translation() = Eigen::Vector3d(3.0, 0.0, butt.thickness_m);
  spec.joints.push_back(butt);
  auto created = Renderer::create(spec);
  ASSERT_TRUE(created.ok()) << created.status().to_string();
  const Renderer& r = **created;
  // The welder's view: 0.5 m from the seam, looking down at 45 degrees; plates fill the middle.
  expect_orb_friendly(r, look_at({0.3, -0.55, 0.45}, {0.3, -0.1, 0.02}), "fillet joint");
  expect_orb_friendly(r, look_at({3.3, -0.45, 0.4}, {3.3, 0.0, 0.0}), "butt joint");
  // Close-up of the plates only: steel fills the whole image.
  cv::Mat bgr, depth;
  const Eigen::Isometry3d T = look_at({0.3, -0.15, 0.25}, {0.3, -0.14, 0.0});
  r.render(T, vga(), {}, &bgr, &depth);
  const OrbCoverage c = orb_coverage(bgr, depth);
  EXPECT_GE(c.keypoints, 300) << "steel close-up";
}

}  // namespace
}  // namespace hwr::sim
