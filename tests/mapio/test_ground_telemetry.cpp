// The ground station's telemetry for the viewer (mapio/ground_telemetry.hpp): poses make the latest
// run's trajectory, thinned when full; a later run replaces an earlier one, an earlier run's or an
// older pose is ignored; status and keyframe images are kept; everything is back after a reopen, and
// a damaged trajectory line or status file costs only itself.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "hwr/core/file_io.hpp"
#include "hwr/mapio/ground_telemetry.hpp"
#include "temp_dir.hpp"

namespace hwr::mapio {
namespace {

using hwr::testing::TempDir;

template <class Msg>
std::vector<uint8_t> lcm_encode(const Msg& m) {
  std::vector<uint8_t> b(static_cast<size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

void give_pose(GroundTelemetry* g, int64_t run, int64_t t_ns, double x, const std::string& robot = "hwr-0") {
  hwr_lcm::pose_t p;
  p.t_ns = t_ns;
  p.robot_id = robot;
  p.run_id = run;
  const double T[12] = {1, 0, 0, x, 0, 1, 0, 2 * x, 0, 0, 1, 0.5};
  std::copy(T, T + 12, p.T_world_cam);
  p.tracking = 1;
  p.localized = 0;
  const auto b = lcm_encode(p);
  g->on_pose_message(b.data(), b.size());
}

void give_status(GroundTelemetry* g, int64_t run, int64_t overruns) {
  hwr_lcm::status_t s;
  s.t_ns = 1;
  s.robot_id = "hwr-0";
  s.run_id = run;
  s.num_tasks = 1;
  s.task_name = {"camera"};
  s.task_runs = {10};
  s.task_overruns = {overruns};
  s.task_slips = {0};
  s.num_counters = 0;
  const auto b = lcm_encode(s);
  g->on_status_message(b.data(), b.size(), 42);
}

void give_image(GroundTelemetry* g, int64_t run, int64_t keyframe_t_ns) {
  hwr_lcm::keyframe_image_t m;
  m.t_ns = 1;
  m.robot_id = "hwr-0";
  m.run_id = run;
  m.keyframe_t_ns = keyframe_t_ns;
  m.width = 640;
  m.height = 480;
  m.jpeg_width = 640;
  m.jpeg_height = 480;
  m.jpeg = {0xFF, 0xD8, 0xFF, 0xD9};
  m.size = 4;
  const auto b = lcm_encode(m);
  g->on_keyframe_image_message(b.data(), b.size());
}

std::unique_ptr<GroundTelemetry> open_ok(const std::string& dir, size_t max_poses = 20'000) {
  GroundTelemetryConfig c;
  c.out_dir = dir;
  c.max_trajectory_poses = max_poses;
  auto g = GroundTelemetry::open(c);
  EXPECT_TRUE(g.ok()) << g.status().message();
  return g.ok() ? std::move(g.value()) : nullptr;
}

TEST(GroundTelemetry, GivenPosesStatusAndImagesThenKeptAndBackAfterReopen) {
  TempDir tmp;
  {
    auto g = open_ok(tmp.path());
    ASSERT_TRUE(g);
    for (int i = 0; i < 10; ++i) give_pose(g.get(), 5, 100 + i, 0.1 * i);
    give_status(g.get(), 5, 3);
    give_image(g.get(), 5, 2000);
    give_image(g.get(), 5, 1000);
    give_image(g.get(), 5, 2000);  // sent again: replaced, not listed twice
    const RobotTelemetry* r = g->robot("hwr-0");
    ASSERT_NE(r, nullptr);
    EXPECT_EQ(r->run_id, 5);
    ASSERT_EQ(r->trajectory.size(), 10u);
    EXPECT_DOUBLE_EQ(r->trajectory.back().T_world_cam[7], 1.8);
    ASSERT_TRUE(r->status);
    EXPECT_EQ(r->status->task_overruns[0], 3);
    EXPECT_EQ(r->status_received_ns, 42);
    ASSERT_EQ(r->keyframes.size(), 2u);
    EXPECT_EQ(r->keyframes[0].keyframe_t_ns, 1000);
    std::string jpeg;
    ASSERT_TRUE(core::read_file(r->keyframes[1].path, &jpeg).ok());
    EXPECT_EQ(jpeg.size(), 4u);
    EXPECT_EQ(g->stats().poses, 10);
  }
  auto g = open_ok(tmp.path());
  ASSERT_TRUE(g);
  EXPECT_TRUE(g->open_notes().empty());
  const RobotTelemetry* r = g->robot("hwr-0");
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->run_id, 5);
  ASSERT_EQ(r->trajectory.size(), 10u);
  EXPECT_EQ(r->trajectory[3].t_ns, 103);
  EXPECT_DOUBLE_EQ(r->trajectory[3].T_world_cam[3], 0.30000000000000004);  // %.17g: exact
  ASSERT_TRUE(r->status);
  EXPECT_EQ(r->status->task_overruns[0], 3);
  EXPECT_EQ(r->keyframes.size(), 2u);
  give_pose(g.get(), 5, 200, 9.0);  // appended after the reopen
  EXPECT_EQ(g->robot("hwr-0")->trajectory.size(), 11u);
}

TEST(GroundTelemetry, GivenLaterRunThenItReplacesAndEarlierRunsOrOlderPosesAreIgnored) {
  TempDir tmp;
  auto g = open_ok(tmp.path());
  ASSERT_TRUE(g);
  give_pose(g.get(), 5, 100, 0);
  give_image(g.get(), 5, 10);
  give_pose(g.get(), 6, 50, 1);  // a new run starting its clock earlier: replaces run 5
  const RobotTelemetry* r = g->robot("hwr-0");
  EXPECT_EQ(r->run_id, 6);
  EXPECT_EQ(r->trajectory.size(), 1u);
  EXPECT_TRUE(r->keyframes.empty());
  give_pose(g.get(), 5, 300, 2);  // late message of the earlier run
  give_pose(g.get(), 6, 50, 3);   // repeat
  give_pose(g.get(), 6, 40, 3);   // reordered
  EXPECT_EQ(r->trajectory.size(), 1u);
  EXPECT_EQ(g->stats().out_of_order, 3);
  give_pose(g.get(), 6, 60, 4, "hwr-1");  // another robot has its own
  EXPECT_EQ(g->robots(), (std::vector<std::string>{"hwr-0", "hwr-1"}));
}

TEST(GroundTelemetry, GivenMorePosesThanTheLimitThenEveryOtherDroppedAndNewestKept) {
  TempDir tmp;
  auto g = open_ok(tmp.path(), 8);
  ASSERT_TRUE(g);
  // Pushes 9, 13, 17, ... find the list of 8 full and thin it to 4: the 101st is one of them.
  for (int i = 0; i <= 100; ++i) give_pose(g.get(), 1, 1000 + i, i);
  const RobotTelemetry* r = g->robot("hwr-0");
  EXPECT_LE(r->trajectory.size(), 8u);
  EXPECT_GE(r->trajectory.size(), 4u);
  EXPECT_EQ(r->trajectory.back().t_ns, 1100);
  EXPECT_LT(r->trajectory.front().t_ns, 1010);  // the whole path stays drawn, thinner
  EXPECT_EQ(r->trajectory.end()[-2].t_ns, 1099) << "thinning dropped the newest pose before the last one";
  for (size_t i = 1; i < r->trajectory.size(); ++i)
    EXPECT_LT(r->trajectory[i - 1].t_ns, r->trajectory[i].t_ns);
}

TEST(GroundTelemetry, GivenBadMessagesThenCountedAndNothingKept) {
  TempDir tmp;
  auto g = open_ok(tmp.path());
  ASSERT_TRUE(g);
  const uint8_t junk[] = {1, 2, 3, 4, 5, 6, 7, 8, 9};
  g->on_pose_message(junk, sizeof junk);
  g->on_status_message(junk, sizeof junk, 0);
  g->on_keyframe_image_message(junk, sizeof junk);
  g->on_pose_message(nullptr, 0);
  EXPECT_EQ(g->stats().rejected, 4);
  EXPECT_FALSE(g->stats().last_error.empty());
  EXPECT_TRUE(g->robots().empty());
}

TEST(GroundTelemetry, GivenDamagedFilesThenNotedAndTheRestLoads) {
  TempDir tmp;
  {
    auto g = open_ok(tmp.path());
    ASSERT_TRUE(g);
    for (int i = 0; i < 5; ++i) give_pose(g.get(), 3, 10 + i, i);
    give_status(g.get(), 3, 1);
  }
  const std::string dir = tmp.path() + "/hwr-0/telemetry";
  {
    std::ofstream f(dir + "/trajectory_3.txt", std::ios::app);
    f << "15 1 0 1 0 0 0 0 1 0 0 0 0 1 0.5";  // cut by a crash before its '\n' (what is left parses)
  }
  ASSERT_TRUE(core::write_file_atomic(dir + "/status.lcm", std::string("garbage")).ok());
  std::ofstream(dir + "/kf_x.jpg") << "not listed";
  auto g = open_ok(tmp.path());
  ASSERT_TRUE(g);
  EXPECT_EQ(g->open_notes().size(), 2u);
  const RobotTelemetry* r = g->robot("hwr-0");
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->trajectory.size(), 5u);
  EXPECT_FALSE(r->status);
  EXPECT_TRUE(r->keyframes.empty());
  give_pose(g.get(), 3, 20, 7.0);  // appended on a line of its own after the cut one
  auto again = open_ok(tmp.path());
  ASSERT_TRUE(again);
  ASSERT_EQ(again->robot("hwr-0")->trajectory.size(), 6u);
  EXPECT_EQ(again->robot("hwr-0")->trajectory.back().t_ns, 20);
}

}  // namespace
}  // namespace hwr::mapio
