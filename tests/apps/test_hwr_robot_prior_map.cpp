// hwr-robot --prior-map, run as a program (issue #6): a second run in the same sim scene, started
// elsewhere, relocalizes against the first run's map store while it moves; its trajectory and
// segments then come out in the first run's frame. A run elsewhere says "not localized".
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "cli_run.hpp"

namespace {

namespace fs = std::filesystem;
const std::string kRobot = HWR_BINARY_DIR "/apps/hwr-robot/hwr-robot";
const std::string kSim = HWR_BINARY_DIR "/apps/hwr-sim/hwr-sim";
const std::string kTeddy = HWR_DATA_DIR "/tum-fr3-teddy-200/rgbd_dataset_freiburg3_teddy";

using hwr::testing::run_cli;

// The second visit (scenarios/lab_revisit_short.yaml): the lab later, starting 1.7 m from where the
// first run started, facing another way, walking to the first run's first joint.
const std::string kRevisit = HWR_SOURCE_DIR "/scenarios/lab_revisit_short.yaml";

struct TempDir {
  std::string path = ::testing::TempDir() + "hwr_robot_prior_" + std::to_string(::getpid());
  TempDir() {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
};

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// T_scene_world of a scenario, from the calibration.yaml hwr-sim writes (16 numbers, row-major).
Eigen::Isometry3d scene_T_world(const std::string& scenario, const std::string& out_dir) {
  const auto r = run_cli(kSim, "--scenario " + scenario + " --out " + out_dir + " --duration 1 --no-images");
  EXPECT_EQ(r.exit_code, 0) << r.out;
  const std::string cal = read_text(out_dir + "/calibration.yaml");
  const size_t at = cal.find("T_scene_world: [");
  EXPECT_NE(at, std::string::npos) << cal;
  std::stringstream ss(cal.substr(at + 16));
  Eigen::Matrix4d M;
  char comma = 0;
  for (int i = 0; i < 16; ++i) {
    ss >> M(i / 4, i % 4);
    if (i < 15) ss >> comma;
  }
  Eigen::Isometry3d T;
  T.matrix() = M;
  return T;
}

// The last pose of a TUM trajectory file (t x y z qx qy qz qw).
Eigen::Isometry3d last_pose(const std::string& path) {
  std::ifstream in(path);
  std::string line, last;
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] != '#') last = line;
  }
  std::stringstream ss(last);
  double t = 0, x = 0, y = 0, z = 0, qx = 0, qy = 0, qz = 0, qw = 1;
  ss >> t >> x >> y >> z >> qx >> qy >> qz >> qw;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(qw, qx, qy, qz).normalized().toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

std::vector<std::string> segment_dirs(const std::string& store) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(store + "/segments"))
    out.push_back(e.path().filename().string());
  std::sort(out.begin(), out.end());
  return out;
}

TEST(HwrRobotPriorMap, GivenASecondVisitStartedElsewhereThenItRelocalizesAndContinuesInThePriorsFrame) {
  if (!fs::exists(kSim)) GTEST_SKIP() << "no simulator in this build";
  TempDir tmp;
  const std::string prior = tmp.path + "/prior", current = tmp.path + "/current";
  const auto first = run_cli(kRobot, "--source sim:lab --duration 20 --quiet --map-out " + prior);
  ASSERT_EQ(first.exit_code, 0) << first.out;
  const size_t prior_segments = segment_dirs(prior).size();
  ASSERT_GE(prior_segments, 1u);

  const std::string& yaml = kRevisit;
  const auto second =
      run_cli(kRobot, "--source sim:" + yaml + " --quiet --prior-map " + prior + " --map-out " + current +
                          " --traj-out " + tmp.path + "/traj.txt --gt-out " + tmp.path + "/gt.txt");
  ASSERT_EQ(second.exit_code, 0) << second.out;
  ASSERT_NE(second.out.find("relocalization: localized in the prior map"), std::string::npos) << second.out;

  // Where the second run's world sits in the first's, from the simulator's scene frames.
  const Eigen::Isometry3d T_prior_world_true =
      scene_T_world("lab", tmp.path + "/cal_lab").inverse() * scene_T_world(yaml, tmp.path + "/cal_revisit");
  // The trajectory is in the prior's frame: its last pose against the truth moved into that frame
  // (the error holds both runs' drift over 20 s and 14 s: a few centimetres at most).
  const Eigen::Isometry3d est = last_pose(tmp.path + "/traj.txt");
  const Eigen::Isometry3d truth = T_prior_world_true * last_pose(tmp.path + "/gt.txt");
  const Eigen::Isometry3d d = truth.inverse() * est;
  std::printf("[ prior    ] last pose in the prior frame: %.1f cm, %.2f deg off the truth\n",
              d.translation().norm() * 100, Eigen::AngleAxisd(d.linear()).angle() * 180 / M_PI);
  EXPECT_LT(d.translation().norm(), 0.06);
  EXPECT_LT(Eigen::AngleAxisd(d.linear()).angle(), 0.5 * M_PI / 180);

  // The store: this run's segments have ids after the prior's; below them, only new versions of
  // prior segments (the map update), each one of the prior's ids.
  const std::vector<std::string> segs = segment_dirs(current);
  char first_id[32];
  std::snprintf(first_id, sizeof(first_id), "seg_%06zu", prior_segments);
  ASSERT_TRUE(std::find(segs.begin(), segs.end(), first_id) != segs.end()) << first_id;
  const std::vector<std::string> prior_ids = segment_dirs(prior);
  for (const std::string& s : segs) {
    if (s < first_id) {
      EXPECT_TRUE(std::find(prior_ids.begin(), prior_ids.end(), s) != prior_ids.end()) << s;
    }
  }
  const std::string reloc = read_text(current + "/relocalization.yaml");
  EXPECT_NE(reloc.find("localized: true"), std::string::npos) << reloc;
  EXPECT_NE(reloc.find("first_segment_id: " + std::to_string(prior_segments)), std::string::npos) << reloc;
  EXPECT_NE(reloc.find("T_prior_world:"), std::string::npos) << reloc;
  // Every attempt is logged, the last one the localized (or confirming) one, and the map update's
  // counters follow.
  EXPECT_NE(reloc.find("attempt_log:\n  - {moved_m: "), std::string::npos) << reloc;
  EXPECT_NE(reloc.find("result: \"localized\""), std::string::npos) << reloc;
  EXPECT_NE(reloc.find("map_update:\n  keyframes: "), std::string::npos) << reloc;
  EXPECT_NE(reloc.find("  points_deleted: "), std::string::npos) << reloc;

  // The map update: what it deleted from the first run's segments, against its plate ground truth
  // (fillet_n3 moved between the runs; it is far from this short walk).
  const auto eval = run_cli(HWR_BINARY_DIR "/apps/hwr-eval/hwr-eval",
                            "map-update --prior " + prior + " --updated " + current + " --groundtruth " +
                                tmp.path + "/cal_lab/weld_groundtruth.yaml --moved fillet_n3");
  ASSERT_EQ(eval.exit_code, 0) << eval.out;
  const size_t at = eval.out.find("elsewhere_deleted_pct=");
  ASSERT_NE(at, std::string::npos) << eval.out;
  EXPECT_LE(std::stod(eval.out.substr(at + 22)), 1.0) << "static loss <= 1 %: " << eval.out;
  // Each moved plate is reported too (the fillet joint's base and web).
  EXPECT_NE(eval.out.find("moved_plate_deleted_pct_fillet_n3_base="), std::string::npos) << eval.out;
  EXPECT_NE(eval.out.find("moved_plate_deleted_pct_fillet_n3_web="), std::string::npos) << eval.out;
  std::printf("[ prior    ] %s", eval.out.substr(eval.out.find("map update:")).c_str());
}

TEST(HwrRobotPriorMap, GivenARunOutsideThePriorsAreaThenNotLocalizedAndItsOwnFrameIsKept) {
  if (!fs::exists(kSim)) GTEST_SKIP() << "no simulator in this build";
  ASSERT_TRUE(fs::is_directory(kTeddy)) << "dataset folder missing: " << kTeddy;
  TempDir tmp;
  const std::string prior = tmp.path + "/prior", current = tmp.path + "/current";
  const auto first = run_cli(kRobot, "--source tum:" + kTeddy + " --quiet --map-out " + prior);
  ASSERT_EQ(first.exit_code, 0) << first.out;
  // The sim lab's start never saw the TUM office.
  const auto second = run_cli(
      kRobot, "--source sim:lab --duration 12 --quiet --prior-map " + prior + " --map-out " + current);
  ASSERT_EQ(second.exit_code, 0) << second.out;
  EXPECT_NE(second.out.find("relocalization: NOT localized"), std::string::npos) << second.out;
  const std::string reloc = read_text(current + "/relocalization.yaml");
  EXPECT_NE(reloc.find("localized: false"), std::string::npos) << reloc;
  EXPECT_EQ(reloc.find("T_prior_world:"), std::string::npos) << reloc;
  EXPECT_EQ(reloc.find("result: \"localized\""), std::string::npos) << reloc;
  EXPECT_EQ(reloc.find("map_update:"), std::string::npos) << reloc;
}

TEST(HwrRobotPriorMap, GivenAMissingPriorMapThenOneClearLineAndExitCode1) {
  TempDir tmp;
  const auto r =
      run_cli(kRobot, "--source tum:" + kTeddy + " --quiet --prior-map " + tmp.path + "/nothing-here");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("--prior-map"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("nothing-here"), std::string::npos) << r.out;
}

}  // namespace
