// hwr-eval map-update, run as a program on a prior and an updated map store written here: a prior that
// drifted 3 cm down at a plate (its keyframe's estimated pose 3 cm below the truth's), and an update
// that deleted the plate's points. Without --truth-traj the truth's box (grown by a margin smaller than
// the drift) misses the prior's plate; with it the box is placed through the keyframe and holds them.

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "cli_run.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/recon/map_store.hpp"

namespace {

namespace fs = std::filesystem;
using hwr::testing::key_values;

const std::string kEval = HWR_BINARY_DIR "/apps/hwr-eval/hwr-eval";

struct TempDir {
  std::string path = ::testing::TempDir() + "hwr_eval_map_update_" + std::to_string(::getpid());
  TempDir() {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
};

// A 0.4 x 0.2 x 0.01 m plate lying at the truth's origin (top at z = 0.005), the floor around it; the
// joint's other plate lies far away (no prior point near it).
constexpr double kDriftZ_m = -0.03;
const char* const kWeldYaml =
    "frame: world\nscenario: \"map-update\"\nplates:\n"
    "  - name: \"j/base\"\n    size_m: [0.4, 0.2, 0.01]\n"
    "    T_world_plate: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]\n"
    "    corners_world: [-0.2, -0.1, -0.005, -0.2, -0.1, 0.005, -0.2, 0.1, -0.005, -0.2, 0.1, 0.005, 0.2, "
    "-0.1, "
    "-0.005, 0.2, -0.1, 0.005, 0.2, 0.1, -0.005, 0.2, 0.1, 0.005]\n"
    "  - name: \"j/far\"\n    size_m: [0.4, 0.2, 0.01]\n"
    "    T_world_plate: [1, 0, 0, 5, 0, 1, 0, 5, 0, 0, 1, 0, 0, 0, 0, 1]\n"
    "    corners_world: [4.8, 4.9, -0.005, 4.8, 4.9, 0.005, 4.8, 5.1, -0.005, 4.8, 5.1, 0.005, 5.2, 4.9, "
    "-0.005, 5.2, 4.9, 0.005, 5.2, 5.1, -0.005, 5.2, 5.1, 0.005]\n"
    "seams:\n  - name: \"j\"\n    type: butt\n    start_world: [-0.2, 0, 0]\n    end_world: [0.2, 0, 0]\n"
    "    plates: [\"j/base\", \"j/far\"]\n";

hwr::recon::SegmentRecord prior_segment(const Eigen::Isometry3d& T_world_cam_est) {
  hwr::recon::SegmentRecord seg;
  seg.segment_id = 0;
  hwr::recon::StoredKeyframe kf;
  kf.id = 0;
  kf.t_ns = 1'000'000'000;
  kf.T_world_cam = T_world_cam_est;
  seg.keyframes.push_back(kf);
  // The plate's top (40 points) and the floor 0.1-0.3 m beside it (the estimate's frame: 3 cm low).
  for (int i = 0; i < 8; ++i) {
    for (int j = 0; j < 5; ++j) {
      seg.points_segment.push_back({static_cast<float>(-0.175 + 0.05 * i),
                                    static_cast<float>(-0.08 + 0.04 * j),
                                    static_cast<float>(0.005 + kDriftZ_m)});
    }
  }
  for (int i = 0; i < 20; ++i) {
    seg.points_segment.push_back(
        {static_cast<float>(-0.5 + 0.05 * i), 0.25f, static_cast<float>(-0.005 + kDriftZ_m)});
  }
  return seg;
}

TEST(HwrEvalMapUpdate, GivenAPriorThatDriftedAtThePlateThenTheTruthTrajectoryPlacesItsOldPlace) {
  TempDir tmp;
  // The keyframe 1 m above the plate looking down; the estimate 3 cm lower than the truth.
  Eigen::Isometry3d T_world_cam_true = Eigen::Isometry3d::Identity();
  T_world_cam_true.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  T_world_cam_true.translation() = Eigen::Vector3d(0, 0, 1.0);
  Eigen::Isometry3d T_world_cam_est = T_world_cam_true;
  T_world_cam_est.translation().z() += kDriftZ_m;

  hwr::recon::StoreMetadata meta;
  meta.run_id = "eval-map-update";
  meta.intrinsics.width = 640;
  meta.intrinsics.height = 480;
  meta.intrinsics.fx = meta.intrinsics.fy = 500;
  meta.intrinsics.cx = 320;
  meta.intrinsics.cy = 240;
  const hwr::recon::SegmentRecord prior = prior_segment(T_world_cam_est);
  hwr::recon::SegmentRecord updated = prior;
  updated.points_segment.erase(updated.points_segment.begin(), updated.points_segment.begin() + 40);
  {
    auto p = hwr::recon::MapStore::open(tmp.path + "/prior", meta);
    ASSERT_TRUE(p.ok()) << p.status().message();
    ASSERT_TRUE(p->write_segment(prior).ok());
    auto u = hwr::recon::MapStore::open(tmp.path + "/updated", meta);
    ASSERT_TRUE(u.ok()) << u.status().message();
    ASSERT_TRUE(u->write_segment(updated).ok());
  }
  std::ofstream(tmp.path + "/weld.yaml") << kWeldYaml;
  ASSERT_TRUE(hwr::core::write_tum_trajectory(
                  tmp.path + "/gt.txt", {{990'000'000, T_world_cam_true}, {1'010'000'000, T_world_cam_true}})
                  .ok());

  const std::string base = "map-update --prior " + tmp.path + "/prior --updated " + tmp.path +
                           "/updated --groundtruth " + tmp.path + "/weld.yaml --moved j --margin 0.01";
  const auto as_given = hwr::testing::run_cli(kEval, base);
  ASSERT_EQ(as_given.exit_code, 0) << as_given.out;
  auto kv = key_values(as_given.out);
  // The box as given (z within ±0.015 m) misses the prior's plate top at -0.025 m: no old-place point
  // (the plate's deletion counts as elsewhere).
  EXPECT_EQ(kv["moved_old_place_points"], "0") << as_given.out;

  const auto placed = hwr::testing::run_cli(kEval, base + " --truth-traj " + tmp.path + "/gt.txt");
  ASSERT_EQ(placed.exit_code, 0) << placed.out;
  kv = key_values(placed.out);
  EXPECT_EQ(kv["moved_old_place_points"], "40") << placed.out;
  EXPECT_EQ(kv["moved_old_place_deleted_pct"], "100.00") << placed.out;
  EXPECT_EQ(kv["elsewhere_deleted_pct"], "0.0000") << placed.out;

  // A truth trajectory with no pose at the keyframe's time: a clear error.
  ASSERT_TRUE(hwr::core::write_tum_trajectory(tmp.path + "/late.txt", {{5'000'000'000, T_world_cam_true},
                                                                       {6'000'000'000, T_world_cam_true}})
                  .ok());
  const auto late = hwr::testing::run_cli(kEval, base + " --truth-traj " + tmp.path + "/late.txt");
  EXPECT_EQ(late.exit_code, 1) << late.out;
  EXPECT_NE(late.out.find("has no pose at any keyframe of prior segment 0"), std::string::npos) << late.out;
}

}  // namespace
