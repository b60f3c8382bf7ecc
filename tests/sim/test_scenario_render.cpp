// Scenario views (needs the renderer): at every stop the weld seam is in view and not hidden
// behind anything, and along the whole walk the camera never stares into emptiness or into a
// surface right in front of it.

#include <gtest/gtest.h>

#include <cmath>

#include "hwr/sim/scenario.hpp"

namespace hwr::sim {
namespace {

class PresetViews : public ::testing::TestWithParam<std::string> {};

TEST_P(PresetViews, GivenStopsWhenRayCastToTheSeamThenNothingOccludesIt) {
  auto s = builtin_scenario(GetParam());
  ASSERT_TRUE(s.ok());
  auto traj = Trajectory::build(s->trajectory);
  ASSERT_TRUE(traj.ok());
  auto renderer = Renderer::create(s->scene);
  ASSERT_TRUE(renderer.ok()) << renderer.status().to_string();
  const Renderer& r = *renderer.value();
  const Eigen::Isometry3d T_imu_cam = camera_T_imu_cam(s->camera);
  const SceneGroundTruth truth = scene_ground_truth(s->scene);
  int checked = 0;
  for (const TrajectoryStop& stop : traj->stops()) {
    const Waypoint& w = s->trajectory.waypoints[stop.waypoint_index];
    if (!w.has_look_at) continue;
    const SeamTruth* seam = &truth.seams.front();
    for (const SeamTruth& sm : truth.seams) {
      const auto mid = [](const SeamTruth& x) {
        return Eigen::Vector2d((0.5 * (x.start_scene + x.end_scene)).head<2>());
      };
      if ((mid(sm) - w.look_at_xy_m).norm() < (mid(*seam) - w.look_at_xy_m).norm()) seam = &sm;
    }
    const double t = 0.5 * (stop.t_dwell_begin_s + stop.t_dwell_end_s);
    const Eigen::Vector3d c = (traj->evaluate(t).T_scene_imu * T_imu_cam).translation();
    for (double a : {0.1, 0.5, 0.9}) {
      const Eigen::Vector3d p = (1 - a) * seam->start_scene + a * seam->end_scene;
      const double hit = r.cast_ray(c, p - c);
      // The first surface is at the seam (a butt joint's ray may drop into the root gap: <= 3 cm).
      EXPECT_NEAR(hit, (p - c).norm(), 0.03) << GetParam() << " " << seam->name << " at " << a;
    }
    ++checked;
  }
  EXPECT_GE(checked, 3);
}

TEST_P(PresetViews, GivenTheWalkWhenSampledEverySecondThenViewsAreNeitherEmptyNorBlocked) {
  auto s = builtin_scenario(GetParam());
  ASSERT_TRUE(s.ok());
  auto traj = Trajectory::build(s->trajectory);
  ASSERT_TRUE(traj.ok());
  auto renderer = Renderer::create(s->scene);
  ASSERT_TRUE(renderer.ok());
  const Renderer& r = *renderer.value();
  const Eigen::Isometry3d T_imu_cam = camera_T_imu_cam(s->camera);
  const hal::PinholeIntrinsics& K = s->camera.intrinsics;
  double worst_valid = 1.0, nearest = 1e9;
  for (double t = 0; t <= traj->duration_s(); t += 1.0) {
    const Eigen::Isometry3d T = traj->evaluate(t).T_scene_imu * T_imu_cam;
    int valid = 0, total = 0;
    for (int v = 20; v < K.height; v += 40) {
      for (int u = 20; u < K.width; u += 40) {
        const Eigen::Vector3d ray_cam((u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0);
        const double d = r.cast_ray(T.translation(), T.linear() * ray_cam);
        const double z = d / ray_cam.norm();  // depth along the optical axis
        valid += (z <= s->render.max_range_m) ? 1 : 0;
        nearest = std::min(nearest, z);
        ++total;
      }
    }
    worst_valid = std::min(worst_valid, static_cast<double>(valid) / total);
  }
  // Depth for most of every image (indoors the far end of the 20 m hall is beyond the 12 m depth
  // range; outdoors the sky has none), and the camera never closer than 0.4 m to a surface.
  EXPECT_GT(worst_valid, GetParam().rfind("lab", 0) == 0 ? 0.7 : 0.5) << GetParam();
  EXPECT_GT(nearest, 0.4) << GetParam();
  std::printf("%s: worst depth coverage %.2f, nearest surface %.2f m\n", GetParam().c_str(), worst_valid,
              nearest);
}

INSTANTIATE_TEST_SUITE_P(Sim, PresetViews,
                         ::testing::Values("lab", "outdoor", "lab-revisit", "outdoor-revisit"),
                         [](const ::testing::TestParamInfo<std::string>& p) {
                           std::string n = p.param;
                           for (char& c : n) c = (c == '-') ? '_' : c;
                           return n;
                         });

}  // namespace
}  // namespace hwr::sim
