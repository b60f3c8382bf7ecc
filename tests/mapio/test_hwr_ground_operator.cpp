// hwr-ground's operator channel (issue #7 item 4): --operator-input's line errors, each reported with
// its line number and skipped; pending commands reported after a restart; and the whole round trip
// over real UDP multicast inside a private network namespace (tests/mapio/private_netns.hpp): the
// hwr-ground program as a child process, a minimal robot (operator_fakes.hpp) in this process. A
// reject and an added region sent while the robot is down stay pending across a restart of
// hwr-ground, are delivered once the robot is up, change its list, and survive a restart of both.

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "apps/cli_run.hpp"
#include "hwr/core/file_io.hpp"
#include "hwr/mapio/lcm_link.hpp"
#include "hwr/mapio/operator_console.hpp"
#include "operator_fakes.hpp"
#include "ground_process.hpp"
#include "private_netns.hpp"
#include "temp_dir.hpp"
#include "cross_run.hpp"

namespace hwr::mapio {
namespace {

namespace fs = std::filesystem;
using hwr::testing::TempDir;

const std::string kGround = hwr::test::kGroundProgram;

void write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path);
  f << text;
}

std::string read_text(const std::string& path) {
  std::string s;
  (void)core::read_file(path, &s);
  return s;
}

bool has(const std::string& text, const std::string& what) { return text.find(what) != std::string::npos; }

TEST(HwrGroundOperator, GivenBadInputLinesThenEachReportedWithItsNumberAndSkipped) {
  TempDir tmp;
  const std::string in = tmp.file("in.txt");
  write_text(in,
             "# operator session\n"
             "\n"
             "reject 4\n"                                           // 3: no robot known yet
             "--robot hwr-0 reject 4\n"                             // 4: sent
             "--robot hwr-0 rejct 4\n"                              // 5
             "--robot hwr-0 move 4 1 2 3 0.5 0.1\n"                 // 6: a size missing
             "--robot hwr-0 move 4 1 2 3 0.5 0 0.1\n"               // 7: a zero size
             "--robot hwr-0 move 4 1 2 3 0.5 0.1 0.1 0.9 0 0 0\n"   // 8: not a unit quaternion
             "--robot hwr-0 add 1732477000100000000 10 20 0 40\n"   // 9: empty region
             "--robot hwr-0 add 17 10 20 x 40\n"                    // 10
             "--robot ../x confirm 1\n"                             // 11
             "confirm -3\n"                                         // 12
             "--robot hwr-0 move 4 1 2 3 0.5 0.1 0.1\n"             // 13: sent
             "--robot hwr-0 add 1732477000100000000 10 20 30 40");  // 14: sent (no newline at the end)
  const std::string args =
      "--out " + tmp.file("out") + " --link memq:// --status-interval 0 --exit-after-idle 0.5";
  const auto r =
      hwr::testing::run_cli(hwr::test::emulated_command(kGround), args + " --operator-input " + in);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const std::string at = in + " line ";
  EXPECT_TRUE(has(r.out, at + "3: no robot has sent detections yet")) << r.out;
  EXPECT_TRUE(has(r.out, at + "5: unknown command 'rejct' (expected confirm, reject, move or add), skipped"))
      << r.out;
  EXPECT_TRUE(has(r.out, at + "6: move takes ID CX CY CZ SX SY SZ [QW QX QY QZ], got 6 arguments")) << r.out;
  EXPECT_TRUE(has(r.out, at + "7: operator command (move for robot 'hwr-0'): move needs box_size_m > 0 on "
                              "each axis, got 0.5 0 0.1"))
      << r.out;
  EXPECT_TRUE(has(r.out, at + "8: operator command (move for robot 'hwr-0'): box_q_world_box has norm 0.9"))
      << r.out;
  EXPECT_TRUE(has(r.out, at + "9: operator command (add for robot 'hwr-0'): add needs box_px")) << r.out;
  EXPECT_TRUE(has(r.out, at + "10: 'x' is not a finite number (expected X Y W H in pixels)")) << r.out;
  EXPECT_TRUE(has(r.out, at + "11: operator command (confirm for robot '../x'): robot_id may hold only"))
      << r.out;
  EXPECT_TRUE(has(r.out, at + "12: detection id '-3' is not an integer >= 0")) << r.out;
  EXPECT_FALSE(has(r.out, at + "1: ") || has(r.out, at + "2: ") || has(r.out, at + "4: ") ||
               has(r.out, at + "13: ") || has(r.out, at + "14: "))
      << r.out;
  const auto kv = hwr::testing::key_values(r.out);
  EXPECT_EQ(kv.at("operator_commands_sent"), "3") << r.out;
  EXPECT_EQ(kv.at("operator_commands_pending"), "3") << r.out;
  EXPECT_EQ(kv.at("ground_rejected"), "0") << r.out;  // the map link is unaffected

  // Nothing acknowledged them: a restart on the same folder says so and sends them again.
  const auto again = hwr::testing::run_cli(hwr::test::emulated_command(kGround), args);
  ASSERT_EQ(again.exit_code, 0) << again.out;
  EXPECT_TRUE(has(again.out, "3 operator commands still pending from before")) << again.out;

  EXPECT_EQ(
      hwr::testing::run_cli(hwr::test::emulated_command(kGround), args + " --operator-robot ../x").exit_code,
      2);
  const auto missing = hwr::testing::run_cli(hwr::test::emulated_command(kGround),
                                             args + " --operator-input " + tmp.file("none.txt"));
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_TRUE(has(missing.out, "none.txt: cannot open operator input")) << missing.out;
}

// --- over UDP --------------------------------------------------------------------------------------

const char* kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";

// hwr-ground with stdout and stderr into `log`.
pid_t start_ground(const std::string& out, const std::string& log, const std::vector<std::string>& extra) {
  std::vector<std::string> args = {"--out", out, "--link", kUrl, "--status-interval", "0"};
  args.insert(args.end(), extra.begin(), extra.end());
  return hwr::test::start_ground_process(args, log);
}

int stop_ground(pid_t* pid) { return hwr::test::stop_ground_process(pid); }

struct GroundGuard {
  pid_t* pid;
  ~GroundGuard() {
    if (*pid > 0) {
      kill(*pid, SIGKILL);
      waitpid(*pid, nullptr, 0);
    }
  }
};

// Runs the robot's side (handling commands, publishing its list every 200 ms) until `done` or 60 s.
template <class Done>
bool run_robot_until(LcmLink* link, test::FakeRobot* robot, Done&& done) {
  const auto start = std::chrono::steady_clock::now();
  auto last_publish = start - std::chrono::seconds(1);
  while (std::chrono::steady_clock::now() - start < std::chrono::seconds(60)) {
    if (std::chrono::steady_clock::now() - last_publish > std::chrono::milliseconds(200)) {
      robot->publish_all();
      last_publish = std::chrono::steady_clock::now();
    }
    if (!link->handle(20).ok()) return false;
    if (done()) return true;
  }
  return false;
}

TEST(HwrGroundOperator, GivenUdpLinkWhenRejectAndAddSentThenRobotListChangesAndSurvivesRestartOfBothEnds) {
  if (!hwr::test::in_private_netns()) {
    HWR_RUN_IN_PRIVATE_NETNS();
    return;
  }
  ASSERT_TRUE(hwr::test::setup_private_loopback());
  TempDir tmp;
  const std::string out = tmp.file("out"), in = tmp.file("in.txt");
  const std::string log1 = tmp.file("ground1.txt"), log2 = tmp.file("ground2.txt"),
                    log3 = tmp.file("ground3.txt");
  write_text(in, "reject 1\nadd 1732477000100000000 10 20 30 40\n");
  pid_t ground = -1;
  GroundGuard guard{&ground};
  test::FakeRobot::Ledger ledger;

  {
    auto link = LcmLink::open(kUrl);
    ASSERT_TRUE(link.ok()) << link.status().message();
    test::FakeRobot robot(&link.value());
    for (const int64_t id : {0, 1, 2}) robot.detections[id] = test::make_detection(id, 100);

    // 1. The robot is down (it ignores commands): the commands stay pending through a restart of
    //    hwr-ground. The lines are read at start, before any detection: --operator-robot names the robot.
    robot.offline = true;
    ground = start_ground(out, log1, {"--operator-input", in, "--operator-robot", "hwr-0"});
    ASSERT_GT(ground, 0);
    ASSERT_TRUE(run_robot_until(&link.value(), &robot, [&] {
      return has(read_text(out + "/hwr-0/operator/detections.txt"), "\n2 geometry proposed");
    })) << read_text(log1);
    ASSERT_EQ(stop_ground(&ground), 0) << read_text(log1);
    EXPECT_TRUE(has(read_text(log1), "operator_commands_pending=2")) << read_text(log1);
    EXPECT_EQ(robot.commands_received, 0);

    // 2. The robot is up, hwr-ground restarts without input: the pending commands are re-sent,
    //    applied once, acknowledged and reported.
    robot.offline = false;
    ground = start_ground(out, log2, {});
    ASSERT_GT(ground, 0);
    ASSERT_TRUE(run_robot_until(&link.value(), &robot, [&] {
      const std::string log = read_text(log2);
      return has(log, "(reject 1): accepted") &&
             has(log, "(add on keyframe 1732477000100000000): accepted") &&
             has(read_text(out + "/hwr-0/operator/detections.txt"), "\n3 operator confirmed");
    })) << read_text(log2);
    ASSERT_EQ(stop_ground(&ground), 0) << read_text(log2);
    const std::string log = read_text(log2);
    EXPECT_TRUE(has(log, "2 operator commands still pending from before")) << log;
    EXPECT_TRUE(has(log, "(add on keyframe 1732477000100000000): accepted, detection 3")) << log;
    EXPECT_TRUE(has(log, "operator_commands_pending=0")) << log;
    EXPECT_EQ(robot.ledger.applied.size(), 2u);
    ASSERT_EQ(robot.detections.size(), 4u);
    EXPECT_EQ(robot.detections.at(1).state, 2);
    ledger = robot.ledger;
  }  // the robot stops: its link and handlers go

  // 3. Both ends restart: the robot from its ledger, hwr-ground from its folder. Nothing is pending,
  //    so nothing is sent again, and the list is the changed one.
  {
    auto link = LcmLink::open(kUrl);
    ASSERT_TRUE(link.ok()) << link.status().message();
    test::FakeRobot robot(&link.value());
    robot.ledger = ledger;
    ground = start_ground(out, log3, {});
    ASSERT_GT(ground, 0);
    int rounds = 0;
    ASSERT_TRUE(run_robot_until(&link.value(), &robot, [&] { return ++rounds > 50; }));
    ASSERT_EQ(stop_ground(&ground), 0) << read_text(log3);
    EXPECT_EQ(robot.commands_received, 0);
    EXPECT_FALSE(has(read_text(log3), "still pending")) << read_text(log3);
  }
  auto console = OperatorConsole::open(out);
  ASSERT_TRUE(console.ok()) << console.status().message();
  const auto list = console.value()->detections("hwr-0");
  ASSERT_EQ(list.size(), 4u);
  EXPECT_EQ(list[1].state, 2);   // rejected
  EXPECT_EQ(list[3].source, 2);  // added by the operator
  EXPECT_EQ(list[3].box_px[2], 30.f);
  for (const auto& c : console.value()->commands("hwr-0")) EXPECT_EQ(c.state, CommandState::kAccepted);
  const std::string journal = read_text(out + "/hwr-0/operator/journal.log");
  EXPECT_TRUE(has(journal, "(reject 1): accepted")) << journal;
}

}  // namespace
}  // namespace hwr::mapio
