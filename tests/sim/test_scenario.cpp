// Scenarios: presets are walkable and aim the camera at their joints; YAML overrides merge and are
// strict; the resolved YAML round-trips; seeds make the streams reproducible.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>

#include "hwr/sim/gnss_synth.hpp"
#include "hwr/sim/imu_synth.hpp"
#include "hwr/sim/renderer.hpp"
#include "hwr/sim/scenario.hpp"

namespace hwr::sim {
namespace {

ScenarioSpec preset(const std::string& name) {
  auto s = builtin_scenario(name);
  EXPECT_TRUE(s.ok()) << s.status().to_string();
  return s.value();
}

Trajectory trajectory_of(const ScenarioSpec& s) {
  auto t = Trajectory::build(s.trajectory);
  EXPECT_TRUE(t.ok()) << t.status().to_string();
  return std::move(t.value());
}

// Floor footprint (xy bounding box) of an object given its local box and pose; objects whose
// underside is above head height do not block the walk.
struct Footprint {
  std::string name;
  Eigen::Vector2d lo, hi;
  double z_min;
};

Footprint footprint(const std::string& name, const Eigen::Vector3d& half, const Eigen::Isometry3d& T,
                    const Eigen::Vector3d& centre_local = Eigen::Vector3d::Zero()) {
  Footprint f{name, Eigen::Vector2d::Constant(1e9), Eigen::Vector2d::Constant(-1e9), 1e9};
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d c(i & 4 ? half.x() : -half.x(), i & 2 ? half.y() : -half.y(),
                            i & 1 ? half.z() : -half.z());
    const Eigen::Vector3d p = T * (centre_local + c);
    f.lo = f.lo.cwiseMin(p.head<2>());
    f.hi = f.hi.cwiseMax(p.head<2>());
    f.z_min = std::min(f.z_min, p.z());
  }
  return f;
}

std::vector<Footprint> footprints(const SceneSpec& s) {
  std::vector<Footprint> out;
  for (const BoxSpec& b : s.boxes) out.push_back(footprint(b.name, 0.5 * b.size_m, b.T_scene_box));
  for (const IBeamSpec& b : s.beams) {
    out.push_back(
        footprint(b.name, 0.5 * Eigen::Vector3d(b.length_m, b.flange_width_m, b.height_m), b.T_scene_beam));
  }
  for (const PipeSpec& p : s.pipes) {
    out.push_back(
        footprint(p.name, Eigen::Vector3d(p.radius_m, p.radius_m, 0.5 * p.length_m), p.T_scene_pipe));
  }
  for (const PlateTruth& p : scene_ground_truth(s).plates) {
    out.push_back(footprint(p.name, 0.5 * p.size_m, p.T_scene_plate));
  }
  return out;
}

double distance_to(const Footprint& f, const Eigen::Vector2d& p) {
  const Eigen::Vector2d d = (f.lo - p).cwiseMax(p - f.hi).cwiseMax(Eigen::Vector2d::Zero());
  return d.norm();
}

class Presets : public ::testing::TestWithParam<std::string> {};

TEST_P(Presets, GivenPresetWhenWalkedThenTheBodyKeepsClearOfEveryObjectAndStaysInside) {
  const ScenarioSpec s = preset(GetParam());
  ASSERT_TRUE(validate_scenario(s).ok());
  const Trajectory traj = trajectory_of(s);
  const std::vector<Footprint> objects = footprints(s.scene);
  double min_clear = 1e9;
  std::string closest;
  for (double t = 0; t <= traj.duration_s(); t += 0.1) {
    const Eigen::Vector2d p = traj.evaluate(t).T_scene_imu.translation().head<2>();
    for (const Footprint& f : objects) {
      if (f.z_min > 2.0) continue;  // overhead (ducts)
      const double d = distance_to(f, p);
      if (d < min_clear) {
        min_clear = d;
        closest = f.name;
      }
    }
    if (s.scene.has_room) {
      EXPECT_GT((p - s.scene.room_min_xy).minCoeff(), 0.5);
      EXPECT_GT((s.scene.room_max_xy - p).minCoeff(), 0.5);
    }
    EXPECT_LT(p.cwiseAbs().maxCoeff(), s.scene.ground_extent_m - 2.0);
  }
  // A humanoid is ~0.5 m wide: keep 0.4 m between its centre line and anything it walks past.
  EXPECT_GT(min_clear, 0.4) << "closest object: " << closest;
}

TEST_P(Presets, GivenStopsWithTargetsWhenDwellingThenTheJointSeamIsInsideTheImage) {
  const ScenarioSpec s = preset(GetParam());
  const Trajectory traj = trajectory_of(s);
  const Eigen::Isometry3d T_imu_cam = camera_T_imu_cam(s.camera);
  const SceneGroundTruth truth = scene_ground_truth(s.scene);
  const hal::PinholeIntrinsics& K = s.camera.intrinsics;
  int looked = 0;
  for (const TrajectoryStop& stop : traj.stops()) {
    const Waypoint& w = s.trajectory.waypoints[stop.waypoint_index];
    if (!w.has_look_at) continue;
    // The joint the stop looks at: the seam whose midpoint is nearest to look_at.
    const SeamTruth* seam = nullptr;
    double best = 1e9;
    for (const SeamTruth& sm : truth.seams) {
      const double d = (0.5 * (sm.start_scene + sm.end_scene)).head<2>().operator-(w.look_at_xy_m).norm();
      if (d < best) {
        best = d;
        seam = &sm;
      }
    }
    ASSERT_NE(seam, nullptr);
    EXPECT_LT(best, 0.5) << "stop at waypoint " << stop.waypoint_index << " looks at no joint";
    const double t_mid = 0.5 * (stop.t_dwell_begin_s + stop.t_dwell_end_s);
    const Eigen::Isometry3d T_cam_scene = (traj.evaluate(t_mid).T_scene_imu * T_imu_cam).inverse();
    for (double a : {0.0, 0.5, 1.0}) {
      const Eigen::Vector3d p = T_cam_scene * ((1 - a) * seam->start_scene + a * seam->end_scene);
      ASSERT_GT(p.z(), 0.3) << seam->name;
      const double u = K.fx * p.x() / p.z() + K.cx, v = K.fy * p.y() / p.z() + K.cy;
      EXPECT_GT(u, 20.0) << seam->name;
      EXPECT_LT(u, K.width - 20.0) << seam->name;
      EXPECT_GT(v, 20.0) << seam->name;
      EXPECT_LT(v, K.height - 20.0) << seam->name;
      EXPECT_LT(p.z(), 3.5) << seam->name;
    }
    ++looked;
  }
  EXPECT_GE(looked, 3);
}

TEST_P(Presets, GivenPresetWhenWrittenToYamlAndReadBackThenTheTextAndStreamsAreIdentical) {
  const ScenarioSpec s = preset(GetParam());
  const std::string y1 = scenario_to_yaml(s);
  auto back = parse_scenario_yaml(y1, "resolved.yaml");
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(scenario_to_yaml(back.value()), y1);
  EXPECT_EQ(back->name, s.name);
  ASSERT_EQ(back->scene.joints.size(), s.scene.joints.size());
  for (size_t i = 0; i < s.scene.joints.size(); ++i) {
    EXPECT_LT(
        (back->scene.joints[i].T_scene_joint.matrix() - s.scene.joints[i].T_scene_joint.matrix()).norm(),
        1e-12);
  }
  // The IMU stream of the re-read scenario is the same, bit for bit.
  const Trajectory a = trajectory_of(s), b = trajectory_of(back.value());
  const auto ia = synthesize_imu(a, s.imu, s.seed, 20.0, s.start_time_ns);
  const auto ib = synthesize_imu(b, back->imu, back->seed, 20.0, back->start_time_ns);
  ASSERT_EQ(ia.size(), ib.size());
  for (size_t k = 0; k < ia.size(); ++k) {
    EXPECT_EQ(ia[k].sample.t_ns, ib[k].sample.t_ns);
    EXPECT_EQ(ia[k].sample.accel_mps2, ib[k].sample.accel_mps2);
  }
}

INSTANTIATE_TEST_SUITE_P(Sim, Presets, ::testing::Values("lab", "outdoor", "lab-revisit", "outdoor-revisit"),
                         [](const ::testing::TestParamInfo<std::string>& p) {
                           std::string n = p.param;
                           for (char& c : n) c = (c == '-') ? '_' : c;
                           return n;
                         });

TEST(Scenario, GivenRevisitsWhenComparedWithTheirBaseThenOnePlateMovedOneObjectGoneAndTheStartDiffers) {
  const std::vector<std::pair<std::string, std::string>> pairs = {{"lab", "lab-revisit"},
                                                                  {"outdoor", "outdoor-revisit"}};
  for (const auto& [base_name, revisit_name] : pairs) {
    const ScenarioSpec base = preset(base_name), rev = preset(revisit_name);
    EXPECT_EQ(rev.scene.texture_seed, base.scene.texture_seed);
    EXPECT_EQ(rev.gnss.enabled, base.gnss.enabled);
    ASSERT_EQ(rev.scene.joints.size(), base.scene.joints.size());
    int moved = 0;
    for (size_t i = 0; i < base.scene.joints.size(); ++i) {
      moved +=
          (rev.scene.joints[i].T_scene_joint.matrix() - base.scene.joints[i].T_scene_joint.matrix()).norm() >
          0.05;
    }
    EXPECT_EQ(moved, 1) << revisit_name;
    EXPECT_EQ(rev.scene.boxes.size() + 1, base.scene.boxes.size()) << revisit_name;
    // Start somewhere inside the earlier run's area, with a different pose.
    const Trajectory tb = trajectory_of(base), tr = trajectory_of(rev);
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e9), hi = -lo;
    for (double t = 0; t <= tb.duration_s(); t += 0.5) {
      const Eigen::Vector2d p = tb.evaluate(t).T_scene_imu.translation().head<2>();
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const Eigen::Isometry3d s0 = tr.evaluate(0).T_scene_imu, b0 = tb.evaluate(0).T_scene_imu;
    const Eigen::Vector2d p0 = s0.translation().head<2>();
    EXPECT_TRUE((p0.array() > lo.array()).all() && (p0.array() < hi.array()).all()) << revisit_name;
    EXPECT_GT((s0.translation() - b0.translation()).norm(), 2.0);
    const double dyaw = std::acos(std::clamp(s0.linear().col(0).dot(b0.linear().col(0)), -1.0, 1.0));
    EXPECT_GT(dyaw, 0.3) << revisit_name;
  }
}

TEST(Scenario, GivenBaseLabAndOverridesWhenParsedThenOnlyTheOverriddenFieldsChange) {
  const ScenarioSpec lab = preset("lab");
  const std::string yaml =
      "base: lab\n"
      "name: lab-fast\n"
      "seed: 99\n"
      "trajectory:\n"
      "  cruise_speed_mps: 1.0\n"
      "camera:\n"
      "  fx: 600\n"
      "  stereo: {enabled: true}\n"
      "imu:\n"
      "  noise: {enabled: false}\n"
      "render: {area_sampling: true, shadows: true, ambient_occlusion_rays: 12}\n"
      "scene:\n"
      "  boxes:\n"
      "    - name: only_box\n"
      "      size_m: [1, 1, 1]\n"
      "      position_m: [0, 0, 0.5]\n"
      "      rpy_deg: [0, 0, 30]\n"
      "      material: wood\n";
  auto s = parse_scenario_yaml(yaml, "lab-fast.yaml");
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  EXPECT_EQ(s->name, "lab-fast");
  EXPECT_EQ(s->base, "lab");
  EXPECT_EQ(s->seed, 99u);
  EXPECT_EQ(s->trajectory.cruise_speed_mps, 1.0);
  EXPECT_EQ(s->trajectory.waypoints.size(), lab.trajectory.waypoints.size());  // untouched list kept
  EXPECT_EQ(s->camera.intrinsics.fx, 600.0);
  EXPECT_EQ(s->camera.intrinsics.fy, lab.camera.intrinsics.fy);
  EXPECT_TRUE(s->camera.stereo);
  EXPECT_EQ(s->camera.baseline_m, 0.12);
  EXPECT_FALSE(s->imu.noise.enabled);
  EXPECT_EQ(s->imu.noise.gyro_noise_density, lab.imu.noise.gyro_noise_density);
  EXPECT_TRUE(s->render.area_sampling);
  EXPECT_FALSE(lab.render.area_sampling);
  EXPECT_TRUE(s->render.shadows);
  EXPECT_EQ(s->render.ambient_occlusion_rays, 12);
  EXPECT_FALSE(lab.render.shadows);
  EXPECT_EQ(lab.render.ambient_occlusion_rays, 0);
  auto again = parse_scenario_yaml(scenario_to_yaml(s.value()), "lab-fast-resolved.yaml");
  ASSERT_TRUE(again.ok()) << again.status().to_string();
  EXPECT_TRUE(again->render.area_sampling);
  EXPECT_TRUE(again->render.shadows);
  EXPECT_EQ(again->render.shadow_range_m, lab.render.shadow_range_m);
  EXPECT_EQ(again->render.ambient_occlusion_rays, 12);
  EXPECT_EQ(again->render.ambient_occlusion_range_m, lab.render.ambient_occlusion_range_m);
  EXPECT_EQ(s->render.ambient, lab.render.ambient);
  ASSERT_EQ(s->scene.boxes.size(), 1u);  // lists replace
  EXPECT_EQ(s->scene.boxes[0].material, Material::kWood);
  const Eigen::Vector3d x = s->scene.boxes[0].T_scene_box.linear().col(0);
  EXPECT_NEAR(std::atan2(x.y(), x.x()), M_PI / 6, 1e-12);
  EXPECT_EQ(s->scene.joints.size(), lab.scene.joints.size());
  EXPECT_EQ(s->depth_noise.sigma_const_m, lab.depth_noise.sigma_const_m);
}

struct BadCase {
  const char* yaml;
  const char* expect_where;
  const char* expect_key;
};

TEST(Scenario, GivenUnknownKeysOrWrongTypesWhenParsedThenErrorNamesFileLineAndDottedKey) {
  const BadCase cases[] = {
      {"base: lab\ncamera:\n  fxx: 600\n", "bad.yaml:3", "camera.fxx"},
      {"base: lab\ncamera:\n  fx: fast\n", "bad.yaml:3", "camera.fx"},
      {"base: lab\nimu:\n  noise:\n    gyro_noise_density: [1, 2]\n", "bad.yaml:4",
       "imu.noise.gyro_noise_density"},
      {"base: lab\nscene:\n  boxes:\n    - name: a\n      colour: red\n", "bad.yaml:5",
       "scene.boxes[0].colour"},
      {"base: lab\nscene:\n  boxes:\n    - name: a\n      material: glass\n", "bad.yaml:5", "material"},
      {"base: lab\ntrajectory:\n  waypoints:\n    - {xy_m: [0, 0]}\n    - {xy: [1, 0]}\n", "bad.yaml:5",
       "trajectory.waypoints[1]"},
      {"base: nowhere\n", "bad.yaml:1", "base"},
      {"base: lab\nseed: -3\n", "bad.yaml:2", "seed"},
      {"base: lab\ngnss:\n  enabled: maybe\n", "bad.yaml:3", "gnss.enabled"},
  };
  for (const BadCase& c : cases) {
    auto s = parse_scenario_yaml(c.yaml, "bad.yaml");
    ASSERT_FALSE(s.ok()) << c.yaml;
    const std::string m = s.status().message();
    EXPECT_NE(m.find(c.expect_where), std::string::npos) << m;
    EXPECT_NE(m.find(c.expect_key), std::string::npos) << m;
  }
  // Range errors beyond types name the field.
  const std::pair<const char*, const char*> range_cases[] = {
      {"base: lab\ncamera:\n  rate_hz: 0\n", "camera.rate_hz"},
      {"base: lab\nrender: {ambient_occlusion_rays: 65}\n", "render.ambient_occlusion_rays"},
      {"base: lab\nrender: {ambient_occlusion_rays: 8, ambient_occlusion_range_m: 0}\n",
       "render.ambient_occlusion_range_m"},
      {"base: lab\nrender: {shadows: true, shadow_range_m: -1}\n", "render.shadow_range_m"},
  };
  for (const auto& [yaml, key] : range_cases) {
    auto s = parse_scenario_yaml(yaml, "bad.yaml");
    ASSERT_FALSE(s.ok()) << yaml;
    EXPECT_NE(s.status().message().find(key), std::string::npos) << s.status().message();
  }
}

TEST(Scenario, GivenNamesAndFilesWhenLoadedThenPresetsFilesAndErrorsAreTellApart) {
  auto unknown = load_scenario("labb");
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.status().message().find("unknown scenario 'labb'"), std::string::npos);
  EXPECT_NE(unknown.status().message().find("lab, outdoor, lab-revisit, outdoor-revisit"), std::string::npos);
  const std::string path = std::string(HWR_BINARY_DIR) + "/scenario_test_quick.yaml";
  {
    std::ofstream f(path);
    f << "base: outdoor\nduration_s: 12.5\n";
  }
  auto s = load_scenario(path);
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  EXPECT_EQ(s->name, "scenario_test_quick");  // named after the file
  EXPECT_EQ(s->duration_s, 12.5);
  EXPECT_TRUE(s->gnss.enabled);
  std::remove(path.c_str());
  EXPECT_FALSE(load_scenario(path).ok());
}

TEST(Scenario, GivenExampleFilesWhenLoadedThenAllAreValid) {
  for (const char* f : {"lab_short.yaml", "lab_stereo_noisy.yaml", "outdoor_gnss_dropouts.yaml"}) {
    auto s = load_scenario(std::string(HWR_SOURCE_DIR) + "/scenarios/" + f);
    ASSERT_TRUE(s.ok()) << f << ": " << s.status().to_string();
    EXPECT_TRUE(Trajectory::build(s->trajectory).ok()) << f;
  }
}

TEST(Scenario, GivenExposureEventsWhenQueriedThenGainStepsAtEachEvent) {
  ScenarioSpec s = preset("lab");
  s.exposure.gain = 1.0;
  s.exposure_events = {{10.0, 1.5}, {20.0, 0.7}};
  EXPECT_EQ(exposure_gain_at(s, 0.0), 1.0);
  EXPECT_EQ(exposure_gain_at(s, 9.999), 1.0);
  EXPECT_EQ(exposure_gain_at(s, 10.0), 1.5);
  EXPECT_EQ(exposure_gain_at(s, 19.0), 1.5);
  EXPECT_EQ(exposure_gain_at(s, 25.0), 0.7);
}

TEST(Scenario, GivenSameAndDifferentSeedsWhenStreamsSynthesizedThenSameSeedRepeatsAndOtherDiffers) {
  ScenarioSpec s = preset("outdoor");
  const Trajectory traj = trajectory_of(s);
  const auto g1 = synthesize_gnss(traj, s.gnss, s.seed, 30.0, 0);
  const auto g2 = synthesize_gnss(traj, s.gnss, s.seed, 30.0, 0);
  const auto g3 = synthesize_gnss(traj, s.gnss, s.seed + 1, 30.0, 0);
  const auto i1 = synthesize_imu(traj, s.imu, s.seed, 30.0, 0);
  const auto i2 = synthesize_imu(traj, s.imu, s.seed, 30.0, 0);
  const auto i3 = synthesize_imu(traj, s.imu, s.seed + 1, 30.0, 0);
  size_t gd = 0, id = 0;
  for (size_t k = 0; k < g1.size(); ++k) {
    EXPECT_EQ(g1[k].fix.lat_deg, g2[k].fix.lat_deg);
    gd += g1[k].fix.lat_deg != g3[k].fix.lat_deg;
  }
  for (size_t k = 0; k < i1.size(); ++k) {
    EXPECT_EQ(i1[k].sample.gyro_radps, i2[k].sample.gyro_radps);
    id += i1[k].sample.gyro_radps != i3[k].sample.gyro_radps;
  }
  EXPECT_GT(gd, g1.size() / 2);
  EXPECT_EQ(id, i1.size());
}

}  // namespace
}  // namespace hwr::sim
