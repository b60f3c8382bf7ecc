// hwr-robot --regions truth and hwr-eval ae --map, run as programs (issue #4: the finer resolution
// around welding regions, and AE measured on it): the first 40 s of the sim lab walk (two joints
// seen up close), the simulator's joints as detections; the map store holds the regions and their
// fine clouds, and the welding plates fitted in them come out within a few millimetres of the
// truth — far closer than the coarse map's 2 cm voxels allow. Bad uses say what is wrong.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "cli_run.hpp"
#include "temp_dir.hpp"

namespace {

namespace fs = std::filesystem;
const std::string kRobot = HWR_BINARY_DIR "/apps/hwr-robot/hwr-robot";
const std::string kSim = HWR_BINARY_DIR "/apps/hwr-sim/hwr-sim";
const std::string kEval = HWR_BINARY_DIR "/apps/hwr-eval/hwr-eval";
const std::string kTeddy = HWR_DATA_DIR "/tum-fr3-teddy-200/rgbd_dataset_freiburg3_teddy";

// The first 40 s of the lab: the truth files (no images: a second) in dir/sim, then the robot
// rendering the same scenario live with --regions `regions`, its store in dir/map and its true
// trajectory in dir/gt.txt. The robot's result (a failed hwr-sim run gives exit code -1 and its output).
hwr::testing::CliRun run_lab_40s(const std::string& dir, const std::string& regions) {
  const auto sim =
      hwr::testing::run_cli(kSim, "--scenario lab --no-images --duration 40 --out " + dir + "/sim");
  if (sim.exit_code != 0) return {-1, sim.out};
  return hwr::testing::run_cli(kRobot, "--source sim:lab --duration 40 --quiet --regions " + regions +
                                           " --map-out " + dir + "/map --gt-out " + dir + "/gt.txt");
}

// hwr-eval ae on run_lab_40s's store against its truth (extra: more options, e.g. --segmented).
hwr::testing::CliRun run_region_ae(const std::string& dir, const std::string& extra) {
  return hwr::testing::run_cli(kEval, "ae --groundtruth " + dir + "/sim/weld_groundtruth.yaml --map " + dir +
                                          "/map --truth-traj " + dir + "/gt.txt" + extra);
}

TEST(
    HwrRobotRegions,
    GivenTheSimulatorsJointsAsDetectionsThenTheStoreKeepsTheirFineCloudsAndTheirPlatesAreMillimetreAccurate) {
  if (!fs::exists(kSim)) GTEST_SKIP() << "no simulator in this build";
  hwr::testing::TempDir dir("hwr_robot_regions");
  const std::string& tmp_path = dir.path();
  const auto robot = run_lab_40s(tmp_path, "truth");
  ASSERT_EQ(robot.exit_code, 0) << robot.out;
  EXPECT_NE(robot.out.find("welding regions: the simulator's 9 joints as detections"), std::string::npos)
      << robot.out;
  EXPECT_NE(robot.out.find("map: welding regions="), std::string::npos) << robot.out;
  EXPECT_TRUE(fs::exists(tmp_path + "/map/segments/seg_000000/fine.bin"));

  const auto ae = run_region_ae(tmp_path, "");
  ASSERT_EQ(ae.exit_code, 0) << ae.out;
  std::printf("%s", ae.out.c_str());
  const auto kv = hwr::testing::key_values(ae.out);
  ASSERT_TRUE(kv.count("ae_mm") && kv.count("plates_in_regions") && kv.count("regions")) << ae.out;
  // 40 s pass fillet_s1 and butt_s2 close by (a third joint may be seen from afar).
  EXPECT_GE(std::atoi(kv.at("regions").c_str()), 2);
  EXPECT_GE(std::atoi(kv.at("plates_in_regions").c_str()), 4);
  EXPECT_GE(std::atoi(kv.at("plates_seen").c_str()), 4);
  EXPECT_LT(std::atof(kv.at("ae_mm").c_str()), 3.0);
  EXPECT_GT(std::atoll(kv.at("fine_points").c_str()), 100000);
  // With segmentation (segments chained by their junctions) the same plates, as accurate.
  const auto seg = run_region_ae(tmp_path, " --segmented");
  ASSERT_EQ(seg.exit_code, 0) << seg.out;
  EXPECT_LT(std::atof(hwr::testing::key_values(seg.out).at("ae_mm").c_str()), 3.0);
}

// --regions geometry (issue #7): the geometric seam detector on each keyframe's depth, no truth used.
// The first 40 s of the lab pass fillet_s1 close by: its base and web end up in a detected region
// and are fitted within millimetres.
TEST(HwrRobotRegions, GivenTheGeometricSeamDetectorThenTheFilletPassedCloseByIsARegionWithItsPlates) {
  if (!fs::exists(kSim)) GTEST_SKIP() << "no simulator in this build";
  hwr::testing::TempDir dir("hwr_robot_regions_geometry");
  const std::string& tmp_path = dir.path();
  const auto robot = run_lab_40s(tmp_path, "geometry");
  ASSERT_EQ(robot.exit_code, 0) << robot.out;
  EXPECT_NE(robot.out.find("the geometric seam detector on each keyframe's depth"), std::string::npos)
      << robot.out;
  EXPECT_NE(robot.out.find("map: welding regions="), std::string::npos) << robot.out;
  const auto ae = run_region_ae(tmp_path, "");
  ASSERT_EQ(ae.exit_code, 0) << ae.out;
  std::printf("%s", ae.out.c_str());
  const auto kv = hwr::testing::key_values(ae.out);
  ASSERT_TRUE(kv.count("ae_mm") && kv.count("plates_in_regions")) << ae.out;
  for (const char* plate : {"fillet_s1/base", "fillet_s1/web"}) {
    const size_t at = ae.out.find(plate);
    ASSERT_NE(at, std::string::npos) << plate;
    const std::string line = ae.out.substr(at, ae.out.find('\n', at) - at);
    EXPECT_EQ(line.find("not seen"), std::string::npos) << line;
  }
  EXPECT_GE(std::atoi(kv.at("plates_in_regions").c_str()), 2);
  EXPECT_LT(std::atof(kv.at("ae_mm").c_str()), 3.0);
}

TEST(HwrRobotRegions, GivenRegionsTruthWithoutASimulatorSourceABadValueOrAMissingModelThenItSaysSo) {
  const auto teddy =
      hwr::testing::run_cli(kRobot, "--source tum:" + kTeddy + " --duration 1 --regions truth");
  EXPECT_EQ(teddy.exit_code, 2);
  EXPECT_NE(teddy.out.find("--regions truth needs a simulator source"), std::string::npos) << teddy.out;
  const auto bad = hwr::testing::run_cli(kRobot, "--source sim:lab --regions detector");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.out.find("--regions: expected 'truth', 'geometry', 'onnx:MODEL' or 'tensorrt:ENGINE', got "
                         "'detector'"),
            std::string::npos)
      << bad.out;
  // A model that cannot be used: said, and the geometric seam detector runs instead.
  const auto missing_model = hwr::testing::run_cli(
      kRobot, "--source tum:" + kTeddy + " --duration 1 --quiet --regions onnx:/nonexistent/m.onnx");
  EXPECT_EQ(missing_model.exit_code, 0) << missing_model.out;
  EXPECT_NE(
      missing_model.out.find("--regions onnx:/nonexistent/m.onnx: the model is unusable (not found: onnx "
                             "detector: model '/nonexistent/m.onnx' not found"),
      std::string::npos)
      << missing_model.out;
  EXPECT_NE(missing_model.out.find("the geometric seam detector on each keyframe's depth"), std::string::npos)
      << missing_model.out;
}

TEST(HwrEvalRegionAe, GivenAMissingStoreOrOptionThenOneLineAndANonZeroExit) {
  const auto missing =
      hwr::testing::run_cli(kEval, "ae --groundtruth /nonexistent.yaml --map /nonexistent --truth-traj /x");
  EXPECT_EQ(missing.exit_code, 1) << missing.out;
  EXPECT_NE(missing.out.find("/nonexistent.yaml"), std::string::npos) << missing.out;
  const auto usage = hwr::testing::run_cli(kEval, "ae --map /tmp");
  EXPECT_EQ(usage.exit_code, 2) << usage.out;
  EXPECT_NE(usage.out.find("--groundtruth, --map and --truth-traj are required"), std::string::npos)
      << usage.out;
}

}  // namespace
