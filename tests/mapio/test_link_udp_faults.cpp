// The whole link over real UDP multicast (issue #5 acceptance, fault tests): MapStreamer in this
// process, the hwr-ground program in a child process, both inside a private network namespace
// (tests/mapio/private_netns.hpp; never any outside address). Faults are real: packet loss and a
// link cut by nftables rules on the namespace's loopback, and SIGKILL of the ground station with a
// restart on the same folder. Oracle: the streamer's flush() sees every chunk acknowledged, and the
// ground station's merged map holds every submitted point exactly once, within the codec's 1 mm.

#include <signal.h>
#include <spawn.h>
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include <gtest/gtest.h>

#include "hwr/mapio/cloud_writers.hpp"
#include "hwr/mapio/ground_store.hpp"
#include "hwr/mapio/lcm_link.hpp"
#include "hwr/mapio/map_streamer.hpp"
#include "hwr_lcm/pose_t.hpp"
#include "hwr_lcm/status_t.hpp"
#include "ground_process.hpp"
#include "private_netns.hpp"
#include "cross_run.hpp"

extern char** environ;

namespace hwr::mapio {
namespace {

namespace fs = std::filesystem;
const char* kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";

pid_t start_ground(const std::string& out) {
  return hwr::test::start_ground_process({"--out", out, "--link", kUrl, "--status-interval", "0"},
                                         "/dev/null");
}

int stop(pid_t pid, int sig) {
  kill(pid, sig);
  int st = 0;
  waitpid(pid, &st, 0);
  return st;
}

// Kills the ground station however the test body ends (an ASSERT returns early).
struct GroundGuard {
  pid_t* pid;
  ~GroundGuard() {
    if (*pid > 0) stop(*pid, SIGKILL);
  }
};

bool sh(const std::string& cmd) { return std::system(cmd.c_str()) == 0; }

// A wall of 2 cm grid points per segment: exact positions the oracle can find again.
struct Stream {
  std::vector<std::vector<ChunkPoint>> batches;
  std::vector<int32_t> segment_of;
  std::vector<bool> completes;
  size_t points = 0;
};

Stream make_stream(int segments, int batches_per_segment, int points_per_batch) {
  Stream s;
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> colour(0, 255);
  for (int seg = 0; seg < segments; ++seg) {
    int k = 0;
    for (int b = 0; b < batches_per_segment; ++b) {
      std::vector<ChunkPoint> pts(static_cast<size_t>(points_per_batch));
      for (ChunkPoint& p : pts) {
        p.x_m = 0.02f * static_cast<float>(k % 500);
        p.y_m = 0.02f * static_cast<float>(k / 500);
        p.z_m = 1.0f + 0.01f * static_cast<float>(seg);
        p.r = static_cast<uint8_t>(colour(rng));
        p.g = static_cast<uint8_t>(colour(rng));
        p.b = static_cast<uint8_t>(colour(rng));
        p.flags = 0;
        ++k;
      }
      s.points += pts.size();
      s.batches.push_back(std::move(pts));
      s.segment_of.push_back(seg);
      s.completes.push_back(b + 1 == batches_per_segment);
    }
  }
  return s;
}

// Each segment's frame is 10 m further along x in the world.
Eigen::Isometry3d T_world_segment(int32_t seg) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(10.0 * seg, 0, 0);
  return T;
}

// Every submitted point is in merged.ply exactly once (within 1 mm) and nothing else is.
void expect_merged_equals(const std::string& out, const Stream& s) {
  std::vector<fs::path> merged;
  for (const auto& e : fs::recursive_directory_iterator(out))
    if (e.path().filename() == "merged.ply") merged.push_back(e.path());
  ASSERT_EQ(merged.size(), 1u);
  CloudArrays cloud;
  ASSERT_TRUE(read_ply(merged[0].string(), &cloud).ok());
  ASSERT_EQ(cloud.size(), s.points);
  // Grid key -> the submitted colour, as the streamer's codec keeps it (5 bits by default).
  const int color_bits = MapStreamerConfig{}.codec.color_bits;
  std::unordered_map<int64_t, std::array<uint8_t, 3>> expected_rgb;
  for (size_t b = 0; b < s.batches.size(); ++b) {
    for (const ChunkPoint& p : s.batches[b]) {
      const int64_t gx = std::lround(p.x_m / 0.02), gy = std::lround(p.y_m / 0.02);
      expected_rgb[(static_cast<int64_t>(s.segment_of[b]) << 40) | (gy << 20) | gx] = {
          reduce_color_channel(p.r, color_bits), reduce_color_channel(p.g, color_bits),
          reduce_color_channel(p.b, color_bits)};
    }
  }
  std::unordered_map<int64_t, int> seen;  // grid key -> count
  int wrong_colour = 0;
  for (size_t i = 0; i < cloud.size(); ++i) {
    const double x = cloud.xyz[3 * i], y = cloud.xyz[3 * i + 1], z = cloud.xyz[3 * i + 2];
    const int seg = static_cast<int>(std::lround((z - 1.0) / 0.01));
    const double xs = x - 10.0 * seg;
    const int64_t gx = std::lround(xs / 0.02), gy = std::lround(y / 0.02);
    EXPECT_NEAR(xs, 0.02 * gx, 0.001);
    EXPECT_NEAR(y, 0.02 * gy, 0.001);
    EXPECT_NEAR(z, 1.0 + 0.01 * seg, 0.001);
    const int64_t key = (static_cast<int64_t>(seg) << 40) | (gy << 20) | gx;
    ++seen[key];
    const auto it = expected_rgb.find(key);
    if (it == expected_rgb.end() || it->second[0] != cloud.rgb[3 * i] ||
        it->second[1] != cloud.rgb[3 * i + 1] || it->second[2] != cloud.rgb[3 * i + 2])
      ++wrong_colour;
  }
  EXPECT_EQ(seen.size(), s.points);  // no point twice
  EXPECT_EQ(wrong_colour, 0) << "points whose colour is not the submitted one at " << color_bits << " bits";
}

struct Fault {
  double loss_pct = 0;    // random UDP drop on the namespace's input
  double cut_at_s = -1;   // drop everything from then ...
  double cut_for_s = 0;   // ... for this long
  double kill_at_s = -1;  // SIGKILL hwr-ground then, restart it 1 s later
};

void run_link(const Fault& f) {
  ASSERT_TRUE(test::setup_private_loopback());
  const std::string out = (fs::temp_directory_path() / ("hwr_link_" + std::to_string(getpid()))).string();
  fs::remove_all(out);
  if (f.loss_pct > 0 || f.cut_at_s >= 0) {
    ASSERT_TRUE(
        sh("nft add table inet hwr && nft add chain inet hwr in '{ type filter hook input priority 0; }'"))
        << "nftables is needed for the loss and cut tests (Debian nftables, toolchain/install-deps.sh)";
  }
  if (f.loss_pct > 0) {
    const int mod = static_cast<int>(std::lround(100.0 / f.loss_pct));
    ASSERT_TRUE(
        sh("nft add rule inet hwr in meta l4proto udp numgen random mod " + std::to_string(mod) + " 0 drop"));
  }
  pid_t ground = start_ground(out);
  GroundGuard guard{&ground};
  ASSERT_GT(ground, 0);
  MapStreamerConfig cfg;
  // ~90 chunks: with 10 % loss the chance that none is lost (and the fault goes untested) is 1e-4.
  cfg.max_points_per_chunk = 4'000;
  auto streamer = MapStreamer::start(kUrl, "robot-test", 42, cfg);
  ASSERT_TRUE(streamer.ok()) << streamer.status().message();
  Stream s = make_stream(3, 8, 12'000);
  // Segment 1 closes with nothing left to send: its completing batch is empty.
  s.batches.insert(s.batches.begin() + 16, std::vector<ChunkPoint>{});
  s.segment_of.insert(s.segment_of.begin() + 16, 1);
  s.completes[15] = false;
  s.completes.insert(s.completes.begin() + 16, true);
  const auto t0 = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  bool cut_on = false, cut_done = false, killed = false, restarted = false;
  double kill_time = 0;
  size_t next = 0;
  while (next < s.batches.size() || !cut_done || (f.kill_at_s >= 0 && !restarted)) {
    const double t = elapsed();
    if (next < s.batches.size()) {
      const auto& b = s.batches[next];
      ASSERT_TRUE((*streamer)->submit(s.segment_of[next], 0, T_world_segment(s.segment_of[next]), b.data(),
                                      nullptr, static_cast<int>(b.size()), s.completes[next], 30.0));
      ++next;
    }
    if (f.cut_at_s >= 0 && !cut_on && !cut_done && t >= f.cut_at_s) {
      ASSERT_TRUE(sh("nft add rule inet hwr in meta l4proto udp drop comment cut"));
      cut_on = true;
    }
    if (cut_on && t >= f.cut_at_s + f.cut_for_s) {
      ASSERT_TRUE(sh("nft flush chain inet hwr in"));
      if (f.loss_pct > 0) {
        const int mod = static_cast<int>(std::lround(100.0 / f.loss_pct));
        ASSERT_TRUE(sh("nft add rule inet hwr in meta l4proto udp numgen random mod " + std::to_string(mod) +
                       " 0 drop"));
      }
      cut_on = false;
      cut_done = true;
    }
    if (f.cut_at_s < 0) cut_done = true;
    if (f.kill_at_s >= 0 && !killed && t >= f.kill_at_s) {
      stop(ground, SIGKILL);
      ground = -1;
      killed = true;
      kill_time = t;
    }
    if (killed && !restarted && t >= kill_time + 1.0) {
      ground = start_ground(out);
      ASSERT_GT(ground, 0);
      restarted = true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_TRUE((*streamer)->flush(60.0)) << "not every chunk was acknowledged";
  const MapStreamerStats st = (*streamer)->stats();
  std::printf("[link] %lld chunks, %lld resends, %.1f s\n", static_cast<long long>(st.chunks),
              static_cast<long long>(st.resends), elapsed());
  if (f.loss_pct > 0 || f.cut_at_s >= 0 || f.kill_at_s >= 0) {
    EXPECT_GT(st.resends, 0) << "the fault never cost a chunk: the test did not exercise the link";
  }
  const int status = stop(ground, SIGTERM);  // writes the merged map
  ground = -1;
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "hwr-ground exit status " << status;
  expect_merged_equals(out, s);
  fs::remove_all(out);
}

#define HWR_LINK_TEST(name, ...)     \
  TEST(LinkUdpFaults, name) {        \
    if (!test::in_private_netns()) { \
      HWR_RUN_IN_PRIVATE_NETNS();    \
      return;                        \
    }                                \
    run_link(__VA_ARGS__);           \
  }

HWR_LINK_TEST(GivenACleanLinkThenEveryPointArrivesOnce, Fault{})
HWR_LINK_TEST(GivenTenPercentPacketLossThenEveryPointArrivesOnce, Fault{10.0, -1, 0, -1})
HWR_LINK_TEST(GivenAFiveSecondCutThenEveryPointArrivesOnce, Fault{0, 0.5, 5.0, -1})
HWR_LINK_TEST(GivenTheGroundStationKilledMidStreamThenEveryPointArrivesOnce, Fault{0, -1, 0, 1.0})

// Telemetry rides the streamer's thread: every posted pose (fewer than the ring holds) and the
// latest status arrive on HWR_POSE / HWR_STATUS with the robot's ids.
TEST(LinkUdpFaults, GivenPostedPosesAndStatusThenTheyArriveOnTheirChannels) {
  if (!test::in_private_netns()) {
    HWR_RUN_IN_PRIVATE_NETNS();
    return;
  }
  ASSERT_TRUE(test::setup_private_loopback());
  auto listener = LcmLink::open(kUrl);
  ASSERT_TRUE(listener.ok()) << listener.status().message();
  std::vector<hwr_lcm::pose_t> poses;
  std::vector<hwr_lcm::status_t> status;
  listener->subscribe(kChannelPose, [&](const uint8_t* d, size_t n) {
    hwr_lcm::pose_t p;
    if (p.decode(d, 0, static_cast<int>(n)) == static_cast<int>(n)) poses.push_back(p);
  });
  listener->subscribe(kChannelStatus, [&](const uint8_t* d, size_t n) {
    hwr_lcm::status_t st;
    if (st.decode(d, 0, static_cast<int>(n)) == static_cast<int>(n)) status.push_back(st);
  });
  auto streamer = MapStreamer::start(kUrl, "robot-tel", 7, MapStreamerConfig{});
  ASSERT_TRUE(streamer.ok()) << streamer.status().message();
  for (int i = 0; i < 20; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(0.1 * i, 0, 0);
    (*streamer)->post_pose(1000 + i, T, i % 2 == 0);
  }
  hwr_lcm::status_t st;
  st.t_ns = 5;
  st.num_tasks = 1;
  st.task_name = {"camera"};
  st.task_runs = {30};
  st.task_overruns = {2};
  st.task_slips = {0};
  st.num_counters = 0;
  (*streamer)->post_status(st);
  for (int i = 0; i < 200 && (poses.size() < 20 || status.empty()); ++i)
    ASSERT_TRUE(listener->handle(10).ok());
  ASSERT_EQ(poses.size(), 20u);
  for (int i = 0; i < 20; ++i) {
    EXPECT_EQ(poses[static_cast<size_t>(i)].t_ns, 1000 + i);
    EXPECT_EQ(poses[static_cast<size_t>(i)].robot_id, "robot-tel");
    EXPECT_EQ(poses[static_cast<size_t>(i)].run_id, 7);
    EXPECT_DOUBLE_EQ(poses[static_cast<size_t>(i)].T_world_cam[3], 0.1 * i);
    EXPECT_EQ(poses[static_cast<size_t>(i)].tracking, i % 2 == 0 ? 1 : 0);
  }
  ASSERT_EQ(status.size(), 1u);
  EXPECT_EQ(status[0].robot_id, "robot-tel");
  EXPECT_EQ(status[0].task_name, std::vector<std::string>{"camera"});
  EXPECT_EQ(status[0].task_overruns, std::vector<int64_t>{2});
  EXPECT_EQ((*streamer)->stats().poses_published, 20);
}

}  // namespace
}  // namespace hwr::mapio
