// The viewer in a browser (issue #9 acceptance): hwr-robot runs the sim lab with the geometric seam
// detector, hwr-ground serves the built page (toolchain/build-web.sh) with --http 127.0.0.1:0, and
// headless Debian Chromium, driven by playwright-core (apps/hwr-ground/web/e2e/viewer_e2e.mjs), loads
// the page, waits until at least two segments and one detection are drawn, rejects the detection,
// waits for the robot's acknowledgement and the robot's own list to say rejected, reloads the page
// and takes a screenshot. Here: the robot's list changed (its detections.yaml, its summary line),
// and the screenshot is not blank. Everything runs inside a private network namespace
// (tests/mapio/private_netns.hpp): the multicast link and the HTTP server never leave it.
// Needs Node.js, the page's npm packages and Chromium: toolchain/test.sh installs and builds them.

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <thread>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "cli_run.hpp"
#include "mapio/ground_process.hpp"
#include "mapio/private_netns.hpp"

namespace {

const std::string kRobot = HWR_BINARY_DIR "/apps/hwr-robot/hwr-robot";
const std::string kGround = hwr::test::kGroundProgram;
const std::string kWebRoot = HWR_SOURCE_DIR "/build/web/dist";
const std::string kScript = HWR_SOURCE_DIR "/apps/hwr-ground/web/e2e/viewer_e2e.mjs";
const std::string kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";
constexpr const char* kRobotId = "viewer-e2e";

struct Process {
  pid_t pid = -1;
  ~Process() {
    if (pid > 0) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, nullptr, 0);
    }
  }
  int stop() {
    ::kill(pid, SIGTERM);
    const int code = hwr::testing::wait_cli(pid);
    pid = -1;
    return code;
  }
  int wait() {
    const int code = hwr::testing::wait_cli(pid);
    pid = -1;
    return code;
  }
};

std::string read_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

TEST(HwrGroundViewerBrowser, GivenRobotAndGroundWhenThePageRejectsADetectionThenTheRobotsListChanges) {
  // What the test needs, said plainly when missing (toolchain/test.sh provides all three).
  ASSERT_TRUE(std::filesystem::exists(kWebRoot + "/index.html"))
      << kWebRoot << " is not built: run ./toolchain/build-web.sh";
  ASSERT_TRUE(std::filesystem::exists(HWR_SOURCE_DIR "/apps/hwr-ground/web/node_modules/playwright-core"))
      << "the page's npm packages are missing: run ./toolchain/build-web.sh";
  const char* chromium_env = std::getenv("HWR_CHROMIUM");
  const std::string chromium = chromium_env != nullptr ? chromium_env : "/usr/bin/chromium";
  ASSERT_TRUE(std::filesystem::exists(chromium))
      << chromium << " is missing: run ./toolchain/install-deps.sh --with-browser";
  if (!hwr::test::in_private_netns()) {
    HWR_RUN_IN_PRIVATE_NETNS();
    return;
  }
  ASSERT_TRUE(hwr::test::setup_private_loopback());
  const std::string dir = ::testing::TempDir() + "hwr_viewer_e2e_" + std::to_string(::getpid());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);

  Process ground, robot;
  ground.pid = hwr::testing::start_cli(kGround + " --out " + dir + "/ground --link '" + kUrl +
                                           "' --status-interval 0 --http 127.0.0.1:0 --web-root " + kWebRoot,
                                       dir + "/ground.txt");
  const int port = hwr::test::wait_for_viewer_port(dir + "/ground.txt");
  ASSERT_GT(port, 0) << read_text(dir + "/ground.txt");
  // Long enough for the page to load, draw and reject while the robot still runs (it applies
  // commands only while it runs): the lab's first seams are detected within its first ~10 s, and this
  // host renders and replays the walk at about real time, so ~50 s are left.
  robot.pid = hwr::testing::start_cli(
      kRobot + " --source sim:lab --duration 60 --quiet --regions geometry --link '" + kUrl +
          "' --robot-id " + kRobotId + " --link-wait 20 --map-out " + dir + "/map",
      dir + "/robot.txt");
  const std::string shot = dir + "/viewer.png";
  const auto e2e = hwr::testing::run_cli("node", kScript + " --url http://127.0.0.1:" + std::to_string(port) +
                                                     "/ --screenshot " + shot + " --timeout-s 240");
  const auto kv = hwr::testing::key_values(e2e.out);
  ASSERT_EQ(e2e.exit_code, 0) << e2e.out << "\nground:\n" << read_text(dir + "/ground.txt");
  ASSERT_EQ(kv.count("e2e_ok"), 1u) << e2e.out;
  EXPECT_GE(std::stoi(kv.at("e2e_segments")), 2) << e2e.out;
  EXPECT_GE(std::stoi(kv.at("e2e_detections")), 1) << e2e.out;
  const std::string rejected_id = kv.at("e2e_rejected_id");

  // The robot's list changed: its summary and the list it keeps in the map store.
  ASSERT_EQ(robot.wait(), 0) << read_text(dir + "/robot.txt");
  const std::string summary = read_text(dir + "/robot.txt");
  EXPECT_NE(summary.find("rejected=1"), std::string::npos) << summary;
  EXPECT_NE(summary.find("commands applied=1"), std::string::npos) << summary;
  const std::string list = read_text(dir + "/map/detections.yaml");
  const std::regex entry("id: " + rejected_id + "\\b[\\s\\S]*?state: (\\w+)");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(list, m, entry)) << list;
  EXPECT_EQ(m[1], "rejected") << list;
  EXPECT_EQ(ground.stop(), 0);

  // The screenshot is a drawn page: not one flat colour, and the 3D view holds more than a background.
  const cv::Mat image = cv::imread(shot, cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty()) << shot;
  EXPECT_GE(image.cols, 800);
  cv::Mat gray;
  cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  cv::Scalar mean, stddev;
  cv::meanStdDev(gray, mean, stddev);
  EXPECT_GT(stddev[0], 10.0) << "a near-uniform screenshot";
  std::map<int, int> colours;
  for (int y = 0; y < image.rows; y += 4)
    for (int x = 0; x < image.cols; x += 4) {
      const cv::Vec3b p = image.at<cv::Vec3b>(y, x);
      ++colours[(p[0] >> 4) << 8 | (p[1] >> 4) << 4 | (p[2] >> 4)];
    }
  EXPECT_GT(colours.size(), 50u) << "too few colours for a drawn point cloud";
  std::filesystem::remove_all(dir);
}

}  // namespace
