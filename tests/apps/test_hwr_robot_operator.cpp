// The operator round trip (issue #7 acceptance): hwr-robot runs the sim lab with the geometric seam
// detector and streams its welding-region list; the ground-station library (mapio::OperatorConsole)
// rejects one detection and adds a region; both change the robot's list, and both survive a restart
// of the two ends: the console reopened on its folder still shows them, and the robot started again
// on its map (--prior-map) publishes the same list, without applying the commands twice.
// UDP multicast only inside a private network namespace (tests/mapio/private_netns.hpp).

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>

#include <Eigen/Core>

#include "cli_run.hpp"
#include "hwr/detect/detection_ledger.hpp"
#include "hwr/mapio/lcm_link.hpp"
#include "hwr/mapio/operator_console.hpp"
#include "hwr/mapio/operator_wire.hpp"
#include "mapio/private_netns.hpp"

namespace {

const std::string kRobot = HWR_BINARY_DIR "/apps/hwr-robot/hwr-robot";
const std::string kGround = HWR_BINARY_DIR "/apps/hwr-ground/hwr-ground";
const std::string kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";
constexpr const char* kRobotId = "welder";

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

using hwr::testing::start_cli;
using hwr::testing::wait_cli;

std::string read_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// The ground end: the console and its LCM link, pumped by the test.
struct Ground {
  std::unique_ptr<hwr::mapio::OperatorConsole> console;
  std::unique_ptr<hwr::mapio::LcmLink> link;

  static Ground open(const std::string& dir) {
    Ground g;
    auto c = hwr::mapio::OperatorConsole::open(dir);
    EXPECT_TRUE(c.ok()) << c.status().message();
    if (!c.ok()) return g;
    g.console = std::move(c.value());
    auto l = hwr::mapio::LcmLink::open(kUrl);
    EXPECT_TRUE(l.ok()) << l.status().message();
    if (!l.ok()) return g;
    g.link = std::make_unique<hwr::mapio::LcmLink>(std::move(l.value()));
    hwr::mapio::OperatorConsole* console = g.console.get();
    g.link->subscribe(hwr::mapio::kChannelDetection, [console](const uint8_t* d, size_t n) {
      console->on_detection_message(d, n, now_ns());
    });
    g.link->subscribe(hwr::mapio::kChannelOperatorAck,
                      [console](const uint8_t* d, size_t n) { console->on_ack_message(d, n, now_ns()); });
    return g;
  }
  void pump(int ms) {
    const int64_t until = now_ns() + int64_t{ms} * 1'000'000;
    while (now_ns() < until) {
      (void)link->handle(10);
      console->service(now_ns(), [this](const hwr_lcm::operator_command_t& c) {
        (void)link->publish(hwr::mapio::kChannelOperatorCommand, c);
      });
    }
  }
};

const hwr_lcm::detection_t* find(const std::vector<hwr_lcm::detection_t>& list, int64_t id) {
  for (const auto& d : list)
    if (d.detection_id == id) return &d;
  return nullptr;
}

TEST(HwrRobotOperator,
     GivenARejectAndAnAddFromTheGroundThenTheRobotsListChangesAndSurvivesRestartingBothEnds) {
  if (!hwr::test::in_private_netns()) {
    HWR_RUN_IN_PRIVATE_NETNS();
    return;
  }
  ASSERT_TRUE(hwr::test::setup_private_loopback());
  const std::string dir = ::testing::TempDir() + "hwr_operator_" + std::to_string(::getpid());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string console_dir = dir + "/console", map1 = dir + "/map1", map2 = dir + "/map2";
  // hwr-ground acknowledges the map chunks (so the robot's end-of-run flush completes).
  const pid_t ground = start_cli(
      kGround + " --out " + dir + "/ground --link '" + kUrl + "' --status-interval 0", dir + "/ground.txt");

  // 1. The robot passes fillet_s1 at ~14 s of the walk and runs on to 32 s. Not paced at sensor rate:
  // every frame is processed however loaded the host (a paced robot drops frames there), and the
  // commands still reach it live (the run lasts ~20 s of wall time after the first detection).
  const pid_t robot =
      start_cli(kRobot + " --source sim:lab --duration 32 --quiet --regions geometry --link '" + kUrl +
                    "' --robot-id " + kRobotId + " --link-wait 20 --map-out " + map1,
                dir + "/robot1.txt");
  int64_t rejected_id = -1, added_id = -1, reject_cmd = -1, add_cmd = -1, run1 = -1;
  {
    Ground g = Ground::open(console_dir);
    ASSERT_TRUE(g.console && g.link);
    // The first region whose seam the robot has fused (seen from two keyframes: two seam points).
    auto with_seam = [&]() -> std::optional<hwr_lcm::detection_t> {
      for (const auto& d : g.console->detections(kRobotId))
        if (d.num_seam_points == 2) return d;
      return std::nullopt;
    };
    int code = 0;
    for (int i = 0; i < 900 && !with_seam(); ++i) {
      g.pump(100);
      ASSERT_FALSE(hwr::testing::cli_exited(robot, &code))
          << "the robot ended before any detection with a seam:\n"
          << read_text(dir + "/robot1.txt");
    }
    ASSERT_TRUE(with_seam()) << read_text(dir + "/robot1.txt");
    const hwr_lcm::detection_t first = *with_seam();
    rejected_id = first.detection_id;
    run1 = first.run_id;
    EXPECT_EQ(first.state, 0);   // proposed
    EXPECT_EQ(first.source, 1);  // geometry
    {
      // Its seam lies in its box (both in the map frame).
      Eigen::Vector3d mid = Eigen::Vector3d::Zero(), centre, size;
      for (int k = 0; k < 2; ++k)
        mid += 0.5 *
               Eigen::Vector3d(first.seam_world_m[k][0], first.seam_world_m[k][1], first.seam_world_m[k][2]);
      centre << first.box_center_world_m[0], first.box_center_world_m[1], first.box_center_world_m[2];
      size << first.box_size_m[0], first.box_size_m[1], first.box_size_m[2];
      EXPECT_LE((mid - centre).norm(), 0.5 * size.norm());
    }

    hwr_lcm::operator_command_t reject{};
    reject.robot_id = kRobotId;
    reject.kind = 1;
    reject.detection_id = rejected_id;
    auto r = g.console->send(reject);
    ASSERT_TRUE(r.ok()) << r.status().message();
    reject_cmd = r.value();
    // A region drawn on the detection's keyframe, 1 m beside it (a world box: the drawn rectangle alone
    // would need that keyframe's images, which the robot keeps for its newest keyframes only).
    hwr_lcm::operator_command_t add{};
    add.robot_id = kRobotId;
    add.kind = 3;
    add.keyframe_t_ns = first.keyframe_t_ns;
    add.box_px[0] = 100, add.box_px[1] = 120, add.box_px[2] = 80, add.box_px[3] = 60;
    for (int k = 0; k < 3; ++k) {
      add.box_center_world_m[k] = first.box_center_world_m[k] + (k == 0 ? 1.0 : 0.0);
      add.box_size_m[k] = 0.3;
    }
    add.box_q_world_box[0] = 1.0;
    auto a = g.console->send(add);
    ASSERT_TRUE(a.ok()) << a.status().message();
    add_cmd = a.value();
    for (int i = 0; i < 300 && g.console->pending_commands() > 0; ++i) g.pump(100);
    ASSERT_EQ(g.console->pending_commands(), 0) << read_text(dir + "/robot1.txt");
    auto ra = g.console->command(reject_cmd), aa = g.console->command(add_cmd);
    ASSERT_TRUE(ra.ok() && aa.ok());
    EXPECT_EQ(ra->state, hwr::mapio::CommandState::kAccepted) << ra->reason;
    EXPECT_EQ(ra->detection_id, rejected_id);
    EXPECT_EQ(aa->state, hwr::mapio::CommandState::kAccepted) << aa->reason;
    added_id = aa->detection_id;
    EXPECT_GE(added_id, 0);
    // The robot publishes the changed entries: the ground's list shows them.
    for (int i = 0; i < 100; ++i) {
      const auto now = g.console->detections(kRobotId);
      const auto* x = find(now, rejected_id);
      if (x != nullptr && x->state == 2 && find(now, added_id) != nullptr) break;
      g.pump(100);
    }
    const auto after = g.console->detections(kRobotId);
    ASSERT_NE(find(after, rejected_id), nullptr);
    EXPECT_EQ(find(after, rejected_id)->state, 2);
    ASSERT_NE(find(after, added_id), nullptr);
    EXPECT_EQ(find(after, added_id)->source, 2);  // operator
    EXPECT_NEAR(find(after, added_id)->box_center_world_m[0], first.box_center_world_m[0] + 1.0, 1e-9);
    // Keep the link serviced until the robot has finished its run.
    while (!hwr::testing::cli_exited(robot, &code)) g.pump(200);
    EXPECT_EQ(code, 0) << read_text(dir + "/robot1.txt");
  }  // the ground end stops

  // The robot's list as it left it, in its map store.
  const std::string robot1 = read_text(dir + "/robot1.txt");
  EXPECT_NE(robot1.find("commands applied=2 refused=0"), std::string::npos) << robot1;
  {
    auto saved = hwr::detect::DetectionLedger::load(map1 + "/detections.yaml");
    ASSERT_TRUE(saved.ok()) << saved.status().message();
    ASSERT_NE(saved->find(rejected_id), nullptr);
    EXPECT_EQ(saved->find(rejected_id)->state, hwr::detect::DetectionState::kRejected);
    ASSERT_NE(saved->find(added_id), nullptr);
    EXPECT_EQ(saved->find(added_id)->source, hwr::detect::DetectionSource::kOperator);
    EXPECT_EQ(saved->commands().size(), 2u);
  }

  // 2. Both ends restarted: the console from its folder, the robot on its map.
  {
    Ground g = Ground::open(console_dir);
    ASSERT_TRUE(g.console && g.link);
    const auto restored = g.console->detections(kRobotId);
    ASSERT_NE(find(restored, rejected_id), nullptr);
    EXPECT_EQ(find(restored, rejected_id)->state, 2);
    ASSERT_NE(find(restored, added_id), nullptr);
    EXPECT_EQ(g.console->pending_commands(), 0);
    // What the restarted robot itself sends (the console keeps the versions it already has).
    int rejected_state = -1;
    bool added_seen = false;
    g.link->subscribe(hwr::mapio::kChannelDetection, [&](const uint8_t* data, size_t size) {
      hwr_lcm::detection_t d;
      if (!hwr::mapio::decode_detection(data, size, &d).ok() || d.run_id == run1) return;
      if (d.detection_id == rejected_id) rejected_state = d.state;
      if (d.detection_id == added_id) added_seen = true;
    });
    const int64_t seen_before = g.console->stats().messages;
    // 12 s: it relocalizes against map1 after ~2 m, then places the list in this run's world.
    const pid_t robot2 = start_cli(
        kRobot + " --source sim:lab --duration 12 --quiet --regions geometry --link '" + kUrl +
            "' --robot-id " + kRobotId + " --link-wait 20 --prior-map " + map1 + " --map-out " + map2,
        dir + "/robot2.txt");
    int code = 0;
    while (!hwr::testing::cli_exited(robot2, &code)) g.pump(200);
    g.pump(500);
    EXPECT_EQ(code, 0) << read_text(dir + "/robot2.txt");
    // The restarted robot published its list: the same versions of the same entries (same t_ns: the
    // console keeps what it has).
    EXPECT_GT(g.console->stats().messages, seen_before);
    EXPECT_EQ(g.console->stats().rejected, 0);
    EXPECT_EQ(rejected_state, 2);
    EXPECT_TRUE(added_seen);
    const auto republished = g.console->detections(kRobotId);
    ASSERT_NE(find(republished, rejected_id), nullptr);
    EXPECT_EQ(find(republished, rejected_id)->state, 2);
    ASSERT_NE(find(republished, added_id), nullptr);
  }
  const std::string robot2 = read_text(dir + "/robot2.txt");
  EXPECT_NE(robot2.find("from the prior map's list"), std::string::npos) << robot2;
  EXPECT_NE(robot2.find("commands applied=0 refused=0 repeated=0"), std::string::npos) << robot2;
  // Relocalized: the list was placed in this run's world and its regions made again (the added one
  // and the proposed ones; not the rejected one).
  ASSERT_NE(robot2.find("relocalization: localized in the prior map"), std::string::npos) << robot2;
  const size_t at = robot2.find("restored_from_prior=");
  ASSERT_NE(at, std::string::npos) << robot2;
  EXPECT_GE(std::atoi(robot2.c_str() + at + std::strlen("restored_from_prior=")), 1) << robot2;
  auto saved2 = hwr::detect::DetectionLedger::load(map2 + "/detections.yaml");
  ASSERT_TRUE(saved2.ok()) << saved2.status().message();
  ASSERT_NE(saved2->find(rejected_id), nullptr);
  EXPECT_EQ(saved2->find(rejected_id)->state, hwr::detect::DetectionState::kRejected);
  ASSERT_NE(saved2->find(added_id), nullptr);
  EXPECT_EQ(saved2->commands().size(), 2u);  // the journal goes on with the map

  ::kill(ground, SIGTERM);
  wait_cli(ground);
  std::filesystem::remove_all(dir);
}

}  // namespace
