// hwr-robot, run as a program: a real dataset replays through the scheduler with every frame
// delivered; bad sources give one clear line and exit code 1.

#include <unistd.h>

#include <filesystem>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "cli_run.hpp"

namespace {

const std::string kRobot = HWR_BINARY_DIR "/apps/hwr-robot/hwr-robot";
const std::string kTeddy = HWR_DATA_DIR "/tum-fr3-teddy-200/rgbd_dataset_freiburg3_teddy";

using hwr::testing::CliRun;

CliRun run_robot(const std::string& args) { return hwr::testing::run_cli(kRobot, args); }

TEST(HwrRobotCli, GivenTheTumTeddySequenceWhenReplayedThenEveryAssociatedFrameReachesThePipeline) {
  ASSERT_TRUE(std::filesystem::exists(kRobot)) << kRobot << " not built";
  ASSERT_TRUE(std::filesystem::is_directory(kTeddy)) << "dataset folder missing: " << kTeddy;
  const CliRun r = run_robot("--source tum:" + kTeddy + " --quiet");
  EXPECT_EQ(r.exit_code, 0) << r.out;
  // 193 associated colour/depth pairs (TUM associate.py rule), none dropped or unreadable.
  EXPECT_NE(r.out.find("camera: frames=193 dropped=0 unreadable=0"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("hal "), std::string::npos) << "no scheduler telemetry table:\n" << r.out;
  EXPECT_NE(r.out.find("mapping "), std::string::npos) << "no mapping task in the table:\n" << r.out;
}

TEST(HwrRobotCli, GivenTrajAndTimingOutputsWhenRunOnTeddyThenBothFilesHoldEveryTrackedFrame) {
  ASSERT_TRUE(std::filesystem::is_directory(kTeddy)) << "dataset folder missing: " << kTeddy;
  const std::string dir = ::testing::TempDir() + "hwr_robot_cli_" + std::to_string(::getpid());
  std::filesystem::create_directories(dir);
  const CliRun r =
      run_robot("--source tum:" + kTeddy + " --quiet --traj-out " + dir + "/traj.txt --timing-out " + dir +
                "/timing.csv --ba-export " + dir + "/full_ba.bal");
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("estimation: mode=visual-only frames=193 tracked=193"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("trajectory: 193 poses"), std::string::npos) << r.out;
  std::ifstream traj(dir + "/traj.txt"), timing(dir + "/timing.csv");
  std::string line;
  int poses = 0, rows = 0;
  while (std::getline(traj, line)) poses += (!line.empty() && line[0] != '#') ? 1 : 0;
  std::getline(timing, line);
  EXPECT_EQ(line.rfind("t_s,imu_ms,extract_ms,match_ms,pose_ms,keyframe_ms,total_ms,local_ba_ms", 0), 0u)
      << line;
  while (std::getline(timing, line)) ++rows;
  EXPECT_EQ(poses, 193);
  EXPECT_EQ(rows, 193);
  // --ba-export: the full bundle adjustment as BAL text, header counts matching the body (one line
  // per observation, 9 per camera, 3 per point) and the summary line.
  std::ifstream bal(dir + "/full_ba.bal");
  long cameras = 0, points = 0, observations = 0, lines = 0;
  bal >> cameras >> points >> observations;
  EXPECT_GT(cameras, 10);
  EXPECT_GT(points, 1000);
  EXPECT_GE(observations, points);
  std::getline(bal, line);
  while (std::getline(bal, line)) lines += line.empty() ? 0 : 1;
  EXPECT_EQ(lines, observations + 9 * cameras + 3 * points);
  EXPECT_NE(r.out.find("bundle adjustment problem: " + std::to_string(cameras) + " cameras"),
            std::string::npos)
      << r.out;
  std::filesystem::remove_all(dir);
}

TEST(HwrRobotCli, GivenMapOutputsWhenRunOnTeddyThenTheStoreAndCloudHoldTheMapAndAreNotOverwritten) {
  ASSERT_TRUE(std::filesystem::is_directory(kTeddy)) << "dataset folder missing: " << kTeddy;
  const std::string dir = ::testing::TempDir() + "hwr_robot_map_" + std::to_string(::getpid());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string args =
      "--source tum:" + kTeddy + " --quiet --map-out " + dir + "/store --cloud-out " + dir + "/cloud.bin";
  const CliRun r = run_robot(args);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  // Teddy's close-up views pass the 5x10^5-voxel threshold once: two segments, one junction.
  EXPECT_NE(r.out.find("map: segments=2 "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("junction 1: keyframes"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("map store: 2 segments written (0 failed"), std::string::npos) << r.out;
  EXPECT_TRUE(std::filesystem::exists(dir + "/store/store.yaml"));
  // The world cloud holds the segments' points: each cloud.bin is a 48-byte header and its points.
  uintmax_t segment_point_bytes = 0;
  for (const char* seg : {"seg_000000", "seg_000001"}) {
    const std::string path = dir + "/store/segments/" + seg + "/cloud.bin";
    ASSERT_TRUE(std::filesystem::exists(path)) << path;
    segment_point_bytes += std::filesystem::file_size(path) - 48u;
  }
  const auto cloud_bytes = std::filesystem::file_size(dir + "/cloud.bin");
  EXPECT_GT(cloud_bytes, 16u * 100'000u);
  EXPECT_EQ(cloud_bytes, segment_point_bytes);
  // A second run into the same store is refused before anything is written.
  const CliRun again = run_robot(args);
  EXPECT_EQ(again.exit_code, 1) << again.out;
  EXPECT_NE(again.out.find("already holds 2 segments"), std::string::npos) << again.out;
  std::filesystem::remove_all(dir);
}

// The robot streams its map to the ground-station program over UDP multicast, both inside a private
// network namespace: every point of the robot's map ends up in the ground station's merged map.
TEST(HwrRobotCli, GivenALinkWhenRunOnTeddyThenTheGroundStationHasTheWholeMap) {
  if (std::system("unshare -rn true >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "cannot create a private network namespace here (unshare -rn failed)";
  }
  const std::string dir = ::testing::TempDir() + "hwr_robot_link_" + std::to_string(::getpid());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  // The script goes to a file: the shell that popen starts would otherwise expand its $ variables.
  const std::string url = "'udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608'";
  const std::string script = dir + "/link.sh";
  {
    std::ofstream sh(script);
    sh << "ip link set lo up && ip route add 224.0.0.0/4 dev lo || exit 3\n"
       << "timeout 300 " << hwr::test::emulated_command(HWR_BINARY_DIR "/apps/hwr-ground/hwr-ground")
       << " --out " << dir << "/ground --link " << url << " --status-interval 0 > " << dir
       << "/ground.txt 2>&1 &\n"
       << "g=$!\n"
       << "timeout 300 " << hwr::test::emulated_command(kRobot) << " --source tum:" << kTeddy
       << " --quiet --link " << url << " --robot-id teddy --link-wait 60\n"
       << "rc=$?\n"
       << "kill -TERM $g\n"
       << "wait $g\n"
       << "echo ground_rc=$?\n"
       << "cat " << dir << "/ground.txt\n"
       << "exit $rc\n";
  }
  const CliRun r = hwr::testing::run_cli("unshare -rn bash", script);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("all acknowledged"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ground_rc=0"), std::string::npos) << r.out;
  const size_t at = r.out.find("map: segments=2 points=");
  ASSERT_NE(at, std::string::npos) << r.out;
  const long long robot_points = std::atoll(r.out.c_str() + at + std::strlen("map: segments=2 points="));
  EXPECT_GT(robot_points, 100'000);
  // merged.ply's vertex count is the robot's map size.
  std::string merged;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir + "/ground"))
    if (e.path().filename() == "merged.ply") merged = e.path().string();
  ASSERT_FALSE(merged.empty()) << r.out;
  std::ifstream ply(merged, std::ios::binary);
  std::string line;
  long long vertices = -1;
  while (std::getline(ply, line) && line != "end_header")
    if (line.rfind("element vertex ", 0) == 0) vertices = std::atoll(line.c_str() + 15);
  EXPECT_EQ(vertices, robot_points);
  std::filesystem::remove_all(dir);
}

TEST(HwrRobotCli, GivenABadFaultSpecThenItNamesTheTokenAndExitCode2) {
  const CliRun r = run_robot("--source tum:" + kTeddy + " --faults dropout=3:-1");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("dropout=3:-1"), std::string::npos) << r.out;
}

TEST(HwrRobotCli, GivenAMissingFolderWhenStartedThenOneLineAndExitCode1) {
  const CliRun r = run_robot("--source tum:/nonexistent/teddy");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("/nonexistent/teddy: no such folder"), std::string::npos) << r.out;
}

TEST(HwrRobotCli, GivenAFolderThatIsNotASimRunWhenStartedThenItSaysSo) {
  const CliRun r = run_robot("--source sim:" + kTeddy);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("not a simulator run"), std::string::npos) << r.out;
}

TEST(HwrRobotCli, GivenBadArgumentsThenUsageAndExitCode2) {
  EXPECT_EQ(run_robot("").exit_code, 2);
  EXPECT_EQ(run_robot("--frobnicate").exit_code, 2);
  EXPECT_EQ(run_robot("--source tum:" + kTeddy + " --duration -3").exit_code, 2);
}

}  // namespace
