// hwr-robot --record FILE, then --source lcmlog:FILE: a run replayed from its recording gives the
// pipeline the same samples and frames (same counts, same IMU/magnetometer streams, stereo kept) and
// the same trajectory to within what rounding the depth to the millimetre changes (0.6 mm on teddy); a file
// that is not a recording, or an unwritable --record path, is one clear line and exit code 1.

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "cli_run.hpp"

namespace {

const std::string kRobot = HWR_BINARY_DIR "/apps/hwr-robot/hwr-robot";
const std::string kTeddy = HWR_DATA_DIR "/tum-fr3-teddy-200/rgbd_dataset_freiburg3_teddy";
const std::string kStereoScenario = HWR_SOURCE_DIR "/scenarios/lab_stereo_noisy.yaml";

using hwr::testing::CliRun;
using hwr::testing::run_cli;

std::string temp_dir(const std::string& name) {
  const std::string dir = ::testing::TempDir() + "hwr_record_" + name + "_" + std::to_string(::getpid());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// The line of out that starts with prefix (empty when none).
std::string line_of(const std::string& out, const std::string& prefix) {
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(prefix, 0) == 0) return line;
  }
  return "";
}

// The number after "key=" in line (-1 when absent).
long value_of(const std::string& line, const std::string& key) {
  const size_t at = line.find(key + "=");
  return at == std::string::npos ? -1 : std::stol(line.substr(at + key.size() + 1));
}

// TUM trajectory: time (s, as written) -> position.
std::map<std::string, Eigen::Vector3d> read_positions(const std::string& path) {
  std::map<std::string, Eigen::Vector3d> out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::string t;
    Eigen::Vector3d p;
    ls >> t >> p.x() >> p.y() >> p.z();
    out[t] = p;
  }
  return out;
}

TEST(HwrRobotRecord, GivenAStereoSimRunRecordedThenItsReplayConsumesTheSameSamplesAndFrames) {
  ASSERT_TRUE(std::filesystem::exists(kRobot)) << kRobot << " not built";
  const std::string dir = temp_dir("sim");
  const std::string log = dir + "/run.lcmlog";
  const CliRun rec =
      run_cli(kRobot, "--source sim:" + kStereoScenario + " --duration 3 --quiet --record " + log);
  ASSERT_EQ(rec.exit_code, 0) << rec.out;
  const std::string recorded = line_of(rec.out, "recording: ");
  ASSERT_FALSE(recorded.empty()) << rec.out;
  EXPECT_EQ(value_of(recorded, "dropped"), 0) << recorded;  // a replay's recording waits, drops nothing
  const long frames = value_of(recorded, "frames"), imu = value_of(recorded, "imu"),
             mag = value_of(recorded, "mag");
  EXPECT_GE(frames, 80) << recorded;  // 3 s at 30 Hz (the last frames may be past the end)
  EXPECT_GE(imu, 500) << recorded;
  EXPECT_GT(mag, 0) << recorded;
  // What the recording run's pipeline consumed is what was recorded.
  EXPECT_EQ(value_of(line_of(rec.out, "camera: "), "frames"), frames) << rec.out;
  EXPECT_EQ(value_of(line_of(rec.out, "imu: "), "samples"), imu) << rec.out;
  EXPECT_EQ(value_of(line_of(rec.out, "magnetometer: "), "samples"), mag) << rec.out;

  const CliRun replay = run_cli(kRobot, "--source lcmlog:" + log + " --quiet");
  ASSERT_EQ(replay.exit_code, 0) << replay.out;
  EXPECT_NE(replay.out.find("(recorded from sim-live:lab-stereo-noisy)"), std::string::npos) << replay.out;
  EXPECT_EQ(replay.out.find("damaged recording"), std::string::npos) << replay.out;
  const std::string camera = line_of(replay.out, "camera: ");
  EXPECT_EQ(value_of(camera, "frames"), frames) << replay.out;
  EXPECT_EQ(value_of(camera, "dropped"), 0) << replay.out;
  EXPECT_EQ(value_of(camera, "unreadable"), 0) << replay.out;
  EXPECT_EQ(value_of(line_of(replay.out, "imu: "), "samples"), imu) << replay.out;
  EXPECT_EQ(value_of(line_of(replay.out, "magnetometer: "), "samples"), mag) << replay.out;
  // The replay is visual-inertial like the recorded run (the IMU stream and T_imu_cam came back).
  EXPECT_NE(replay.out.find("estimation: mode=visual-inertial"), std::string::npos) << replay.out;
  std::filesystem::remove_all(dir);
}

TEST(HwrRobotRecord, GivenTeddyRecordedThenTheReplayTracksEveryFrameOnTheSameTrajectory) {
  ASSERT_TRUE(std::filesystem::is_directory(kTeddy)) << "dataset folder missing: " << kTeddy;
  const std::string dir = temp_dir("teddy");
  const std::string log = dir + "/teddy.lcmlog";
  const CliRun rec = run_cli(kRobot, "--source tum:" + kTeddy + " --quiet --no-full-ba --record " + log +
                                         " --traj-out " + dir + "/direct.txt");
  ASSERT_EQ(rec.exit_code, 0) << rec.out;
  EXPECT_NE(rec.out.find("frames=193 dropped=0"), std::string::npos) << line_of(rec.out, "recording: ");
  const CliRun replay =
      run_cli(kRobot, "--source lcmlog:" + log + " --quiet --no-full-ba --traj-out " + dir + "/replayed.txt");
  ASSERT_EQ(replay.exit_code, 0) << replay.out;
  EXPECT_NE(replay.out.find("camera: frames=193 dropped=0 unreadable=0"), std::string::npos) << replay.out;
  const auto direct = read_positions(dir + "/direct.txt"), replayed = read_positions(dir + "/replayed.txt");
  ASSERT_EQ(direct.size(), replayed.size());
  ASSERT_GT(direct.size(), 150u);
  // Same image times; positions apart only by the depth's rounding to 1 mm (TUM's is 0.2 mm).
  double worst_m = 0;
  for (const auto& [t, p] : direct) {
    const auto it = replayed.find(t);
    ASSERT_NE(it, replayed.end()) << "pose at " << t << " missing from the replay";
    worst_m = std::max(worst_m, (it->second - p).norm());
  }
  EXPECT_LT(worst_m, 0.005) << "the replayed trajectory left the recorded run's by " << worst_m << " m";
  std::filesystem::remove_all(dir);
}

TEST(HwrRobotRecord, GivenAFileThatIsNotARecordingOrAnUnwritablePathThenOneClearLineAndExit1) {
  const std::string dir = temp_dir("bad");
  const std::string junk = dir + "/junk.lcmlog";
  std::ofstream(junk) << "not an LCM log";
  const CliRun a = run_cli(kRobot, "--source lcmlog:" + junk + " --quiet");
  EXPECT_EQ(a.exit_code, 1) << a.out;
  EXPECT_NE(a.out.find("not a sensor recording"), std::string::npos) << a.out;
  const CliRun b = run_cli(kRobot, "--source lcmlog:" + dir + "/missing.lcmlog --quiet");
  EXPECT_EQ(b.exit_code, 1) << b.out;
  EXPECT_NE(b.out.find("no such file"), std::string::npos) << b.out;
  const CliRun c = run_cli(
      kRobot, "--source tum:" + kTeddy + " --duration 1 --quiet --record /nonexistent/dir/run.lcmlog");
  EXPECT_EQ(c.exit_code, 1) << c.out;
  EXPECT_NE(c.out.find("--record /nonexistent/dir/run.lcmlog: cannot create the log file"), std::string::npos)
      << c.out;
  std::filesystem::remove_all(dir);
}

}  // namespace
