// hwr-ground's viewer API (issue #9; docs/ground_viewer.md) end to end over real UDP multicast in a
// private network namespace (private_netns.hpp): the hwr-ground program as a child process with
// --http 127.0.0.1:0, the robot's side played by the real MapStreamer in this process (map segments,
// poses, status, a detection, a keyframe image, the answer to a command), read back through the HTTP
// API with cpp-httplib's client. A page's reject reaches the robot and its acknowledgement the page;
// bad requests get 4xx with a reason; and after a restart of hwr-ground the API shows the same.

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "apps/cli_run.hpp"
#include "cross_run.hpp"
#include "hwr/core/file_io.hpp"
#include "hwr/mapio/lcm_link.hpp"
#include "hwr/mapio/map_streamer.hpp"
#include "ground_process.hpp"
#include "private_netns.hpp"
#include "temp_dir.hpp"

// After Eigen: httplib.h includes <resolv.h>, whose `_res` macro breaks Eigen's product kernels.
#include <httplib.h>

namespace hwr::mapio {
namespace {

using hwr::testing::TempDir;
using nlohmann::json;

const std::string kGround = hwr::test::kGroundProgram;
const char* kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";
constexpr int64_t kRunId = 1'732'477'000'000'000'000;
constexpr int kPointsPerSegment = 1500;

pid_t start_ground(const std::string& out, const std::string& web, const std::string& log) {
  return hwr::test::start_ground_process(
      {"--out", out, "--link", kUrl, "--status-interval", "0", "--http", "127.0.0.1:0", "--web-root", web},
      log);
}

struct Ground {
  pid_t pid = -1;
  int port = -1;
  ~Ground() { stop(); }
  int stop() { return pid > 0 ? hwr::test::stop_ground_process(&pid) : -1; }
};

int wait_for_port(const std::string& log) { return hwr::test::wait_for_viewer_port(log); }

json get_json(int port, const std::string& path, int* status = nullptr) {
  httplib::Client c("127.0.0.1", port);
  c.set_read_timeout(30, 0);
  auto res = c.Get(path.c_str());
  if (status != nullptr) *status = res ? res->status : -1;
  if (!res) return json();
  return json::parse(res->body, nullptr, false);
}

// Polls GET /api/state until `done(robot)` for robot "viewer-0" holds (up to 60 s).
template <class Done>
json wait_state(int port, Done&& done) {
  json robot;
  for (int i = 0; i < 300; ++i) {
    const json s = get_json(port, "/api/state");
    if (s.is_object())
      for (const json& r : s["robots"])
        if (r["robot_id"] == "viewer-0") robot = r;
    if (!robot.is_null() && done(robot)) return robot;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  ADD_FAILURE() << "state never reached the expected condition; last: " << robot.dump();
  return robot;
}

Eigen::Isometry3d T_world_segment(int segment) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(10.0 * segment, 1.0, 0.0);
  return T;
}

// A segment's points in its frame: a 1.5 m line of coloured points, x = 1 mm * i.
std::vector<ChunkPoint> segment_points(int segment) {
  std::vector<ChunkPoint> pts(kPointsPerSegment);
  for (int i = 0; i < kPointsPerSegment; ++i)
    pts[i] = {0.001f * i, 0.5f * segment,
              0.25f,      static_cast<uint8_t>(i % 251),
              40,         static_cast<uint8_t>(segment * 100),
              0};
  return pts;
}

hwr_lcm::detection_t make_detection(int64_t state) {
  hwr_lcm::detection_t d;
  d.t_ns = 100 + state;
  d.detection_id = 3;
  d.segment_id = -1;
  d.keyframe_t_ns = 5'000;
  d.source = 1;
  d.state = static_cast<int8_t>(state);
  d.confidence = 0.875f;
  const float box[4] = {10, 20, 30, 40};
  std::copy(box, box + 4, d.box_px);
  const double c[3] = {1, 2, 3}, size[3] = {0.5, 0.25, 0.125}, q[4] = {1, 0, 0, 0};
  std::copy(c, c + 3, d.box_center_world_m);
  std::copy(size, size + 3, d.box_size_m);
  std::copy(q, q + 4, d.box_q_world_box);
  d.num_seam_points = 2;
  d.seam_world_m = {{0.75, 2, 2.9375}, {1.25, 2, 2.9375}};
  return d;
}

void feed_robot(MapStreamer* robot) {
  for (int s = 0; s < 2; ++s) {
    const auto pts = segment_points(s);
    ASSERT_TRUE(robot->submit(s, 0, T_world_segment(s), pts.data(), nullptr, kPointsPerSegment, true, 5.0));
  }
  for (int i = 0; i < 40; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(0.1 * i, 0.0, 1.0);
    robot->post_pose(1'000 + i, T, true);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));  // the pose ring holds 64
  }
  hwr_lcm::status_t st;
  st.t_ns = 7;
  st.num_tasks = 2;
  st.task_name = {"camera", "mapping"};
  st.task_runs = {90, 30};
  st.task_overruns = {4, 1};
  st.task_slips = {0, 0};
  st.num_counters = 1;
  st.counter_name = {"link.resends"};
  st.counter_value = {2};
  robot->post_status(st);
  robot->post_detection(make_detection(0));
  cv::Mat image(48, 64, CV_8UC3, cv::Scalar(0, 128, 255));
  robot->post_keyframe_image(5'000, image);
}

bool complete_map(const json& r) {
  if (r["segments"].size() != 2 || r["detections"].size() != 1 || r["keyframes"].size() != 1 ||
      r["status"].is_null() || r["trajectory_poses"] != 40)
    return false;
  for (const json& s : r["segments"])
    if (s["complete"] != true) return false;
  return true;
}

TEST(HwrGroundViewer, GivenRobotTelemetryThenApiShowsItAcceptsARejectAndSurvivesARestart) {
  if (!hwr::test::in_private_netns()) {
    HWR_RUN_IN_PRIVATE_NETNS();
    return;
  }
  ASSERT_TRUE(hwr::test::setup_private_loopback());
  TempDir tmp;
  const std::string out = tmp.file("out"), web = tmp.file("web");
  std::filesystem::create_directories(web);
  std::ofstream(web + "/index.html") << "<html>viewer page</html>";
  Ground ground;
  ground.pid = start_ground(out, web, tmp.file("ground1.txt"));
  ASSERT_GT(ground.pid, 0);
  ground.port = wait_for_port(tmp.file("ground1.txt"));
  ASSERT_GT(ground.port, 0);

  MapStreamerConfig config;
  auto robot = MapStreamer::start(kUrl, "viewer-0", kRunId, config);
  ASSERT_TRUE(robot.ok()) << robot.status().message();
  feed_robot(robot.value().get());
  json r = wait_state(ground.port, complete_map);
  ASSERT_TRUE(complete_map(r)) << r.dump(2);

  // What the page draws.
  EXPECT_EQ(r["run_id"], std::to_string(kRunId));  // 64-bit ids as strings
  EXPECT_EQ(r["segments"][1]["points"], kPointsPerSegment);
  EXPECT_EQ(r["segments"][1]["T_world_segment"][3], 10.0);
  EXPECT_EQ(r["link"]["missing_chunks"], 0);
  EXPECT_EQ(r["link"]["points_stored"], 2 * kPointsPerSegment);
  EXPECT_GT(r["link"]["bytes_stored"].get<int64_t>(), 1000);
  EXPECT_EQ(r["link"]["robot_resends"], 2);
  EXPECT_EQ(r["status"]["tasks"][0]["name"], "camera");
  EXPECT_EQ(r["status"]["tasks"][0]["overruns"], 4);
  EXPECT_EQ(r["pose"]["T_world_cam"][3], 3.9000000000000004);
  const json& d = r["detections"][0];
  EXPECT_EQ(d["detection_id"], "3");
  EXPECT_EQ(d["source"], "geometry");
  EXPECT_EQ(d["state"], "proposed");
  EXPECT_EQ(d["confidence"], 0.875);
  EXPECT_EQ(d["seam_world_m"][1][0], 1.25);
  EXPECT_EQ(r["keyframes"][0]["t_ns"], "5000");
  EXPECT_EQ(r["keyframes"][0]["width"], 64);

  // The segment's points, in the world frame, within the codec's 1 mm, colours exact up to 5 bits.
  httplib::Client client("127.0.0.1", ground.port);
  client.set_read_timeout(30, 0);
  const std::string seg =
      "/api/segment?robot=viewer-0&run=" + std::to_string(kRunId) + "&segment=1&version=0";
  auto full = client.Get(seg.c_str());
  ASSERT_TRUE(full);
  ASSERT_EQ(full->status, 200);
  uint32_t header[4];
  ASSERT_GE(full->body.size(), sizeof header);
  std::memcpy(header, full->body.data(), sizeof header);
  EXPECT_EQ(std::string(full->body.data(), 4), "HWRS");
  ASSERT_EQ(header[2], static_cast<uint32_t>(kPointsPerSegment));
  ASSERT_EQ(full->body.size(), 16u + 15u * kPointsPerSegment);
  std::vector<float> xyz(3 * kPointsPerSegment);
  std::memcpy(xyz.data(), full->body.data() + 16, xyz.size() * sizeof(float));
  double min_x = 1e9, max_x = -1e9;
  for (int i = 0; i < kPointsPerSegment; ++i) {
    EXPECT_NEAR(xyz[3 * i + 1], 1.5, 0.0011);  // 1.0 + 0.5 * segment
    EXPECT_NEAR(xyz[3 * i + 2], 0.25, 0.0011);
    min_x = std::min<double>(min_x, xyz[3 * i]);
    max_x = std::max<double>(max_x, xyz[3 * i]);
  }
  EXPECT_NEAR(min_x, 10.0, 0.0011);
  EXPECT_NEAR(max_x, 10.0 + 0.001 * (kPointsPerSegment - 1), 0.0011);
  auto thin = client.Get((seg + "&max_points=100").c_str());
  ASSERT_TRUE(thin);
  std::memcpy(header, thin->body.data(), sizeof header);
  EXPECT_EQ(header[2], 100u);
  EXPECT_EQ(header[3], static_cast<uint32_t>(kPointsPerSegment));

  auto trajectory = get_json(ground.port, "/api/trajectory?robot=viewer-0");
  ASSERT_EQ(trajectory["xyz"].size(), 40u);
  EXPECT_EQ(trajectory["xyz"][39][0], 3.9000000000000004);
  auto jpeg = client.Get("/api/keyframe?robot=viewer-0&t_ns=5000");
  ASSERT_TRUE(jpeg);
  EXPECT_EQ(jpeg->get_header_value("Content-Type"), "image/jpeg");
  const cv::Mat decoded =
      cv::imdecode(std::vector<uint8_t>(jpeg->body.begin(), jpeg->body.end()), cv::IMREAD_COLOR);
  EXPECT_EQ(decoded.cols, 64);
  EXPECT_EQ(decoded.rows, 48);
  auto page = client.Get("/");
  ASSERT_TRUE(page);
  EXPECT_NE(page->body.find("viewer page"), std::string::npos);

  // Bad requests: a reason, nothing sent.
  int status = 0;
  get_json(ground.port, "/api/segment?robot=viewer-0&run=x&segment=1&version=0", &status);
  EXPECT_EQ(status, 400);
  get_json(ground.port, "/api/segment?robot=viewer-0&run=" + std::to_string(kRunId) + "&segment=9&version=0",
           &status);
  EXPECT_EQ(status, 404);
  get_json(ground.port, "/api/segment?robot=viewer-0&run=1&segment=4294967297&version=0", &status);
  EXPECT_EQ(status, 400);  // not cut to segment 1
  get_json(ground.port, "/api/segment?robot=viewer-0&run=+1&segment=1&version=0", &status);
  EXPECT_EQ(status, 400);
  // Another Host (a page whose name was made to resolve to 127.0.0.1) is refused; so is a command
  // that is not sent as JSON (what a page elsewhere could send without a CORS preflight).
  httplib::Headers rebound = {{"Host", "attacker.example:" + std::to_string(ground.port)}};
  auto foreign = client.Get("/api/state", rebound);
  ASSERT_TRUE(foreign);
  EXPECT_EQ(foreign->status, 403);
  auto plain =
      client.Post("/api/command", R"({"robot":"viewer-0","kind":"reject","detection_id":"3"})", "text/plain");
  ASSERT_TRUE(plain);
  EXPECT_EQ(plain->status, 415);
  get_json(ground.port, "/api/keyframe?robot=viewer-0&t_ns=4", &status);
  EXPECT_EQ(status, 404);
  for (
      const std::string& body :
      {std::string("{not json"), std::string(R"({"robot":"viewer-0","kind":"reject"})"),
       std::string(R"({"robot":"../x","kind":"reject","detection_id":"3"})"),
       std::string(
           R"({"robot":"viewer-0","kind":"move","detection_id":"3","center_world_m":[1,2,3],"size_m":[0,1,1],"q_world_box":[1,0,0,0]})")}) {
    auto res = client.Post("/api/command", body, "application/json");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 400) << body;
    EXPECT_TRUE(json::parse(res->body, nullptr, false).contains("error")) << res->body;
  }

  // The operator rejects detection 3 from the page; the robot applies it and answers.
  auto sent = client.Post("/api/command", R"({"robot":"viewer-0","kind":"reject","detection_id":"3"})",
                          "application/json");
  ASSERT_TRUE(sent);
  ASSERT_EQ(sent->status, 200) << sent->body;
  const std::string command_id = json::parse(sent->body)["command_id"];
  hwr_lcm::operator_command_t command;
  // The robot's side takes the ground's command off the link, polling for up to 30 s.
  auto take_command = [&](hwr_lcm::operator_command_t* taken) {
    for (int i = 0; i < 300; ++i) {
      if (robot.value()->take_operator_command(taken)) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return false;
  };
  bool received = take_command(&command);
  ASSERT_TRUE(received);
  EXPECT_EQ(std::to_string(command.command_id), command_id);
  EXPECT_EQ(command.kind, 1);
  EXPECT_EQ(command.detection_id, 3);
  hwr_lcm::command_ack_t ack;
  ack.t_ns = 200;
  ack.command_id = command.command_id;
  ack.accepted = 1;
  ack.detection_id = 3;
  robot.value()->post_command_ack(ack);
  robot.value()->post_detection(make_detection(2));
  auto acknowledged = [&](const json& x) {
    return !x["commands"].empty() && x["commands"].back()["state"] == "accepted" &&
           x["detections"][0]["state"] == "rejected";
  };
  r = wait_state(ground.port, acknowledged);
  ASSERT_TRUE(acknowledged(r)) << r.dump(2);
  EXPECT_EQ(r["commands"].back()["command_id"], command_id);

  // A region drawn on the keyframe image reaches the robot in the keyframe's pixels; the robot's
  // refusal comes back with its reason.
  auto added = client.Post("/api/command",
                           R"({"robot":"viewer-0","kind":"add","keyframe_t_ns":"5000","box_px":[8,6,20,16]})",
                           "application/json");
  ASSERT_TRUE(added);
  ASSERT_EQ(added->status, 200) << added->body;
  const std::string add_id = json::parse(added->body)["command_id"];
  received = take_command(&command);
  ASSERT_TRUE(received);
  EXPECT_EQ(std::to_string(command.command_id), add_id);
  EXPECT_EQ(command.kind, 3);
  EXPECT_EQ(command.keyframe_t_ns, 5000);
  EXPECT_EQ(command.box_px[0], 8.0f);
  EXPECT_EQ(command.box_px[3], 16.0f);
  EXPECT_EQ(command.box_size_m[0], 0.0);  // no world box: the robot lifts the rectangle with its depth
  ack.command_id = command.command_id;
  ack.accepted = 0;
  ack.reason = "keyframe 5000 no longer kept \xe2\x80";  // cut mid-character: not UTF-8
  ack.detection_id = -1;
  robot.value()->post_command_ack(ack);
  auto refused = [&](const json& x) {
    for (const json& c : x["commands"])
      if (c["command_id"] == add_id)
        return c["state"] == "refused" &&
               c["reason"].get<std::string>().rfind("keyframe 5000 no longer kept ", 0) == 0;
    return false;
  };
  r = wait_state(ground.port, refused);
  ASSERT_TRUE(refused(r)) << r.dump(2);

  // Damaged telemetry is counted and dropped.
  auto noise = LcmLink::open(kUrl);
  ASSERT_TRUE(noise.ok());
  const uint8_t junk[] = {0xde, 0xad, 0xbe, 0xef, 1, 2, 3};
  ASSERT_TRUE(noise->publish_bytes(kChannelPose, junk, sizeof junk).ok());
  bool counted = false;
  for (int i = 0; i < 300 && !counted; ++i) {
    counted = get_json(ground.port, "/api/state")["server"]["telemetry_rejected"] == 1;
    if (!counted) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_TRUE(counted);

  // A restart of hwr-ground loses nothing the page shows.
  robot.value().reset();
  EXPECT_EQ(ground.stop(), 0);
  std::string log;
  ASSERT_TRUE(core::read_file(tmp.file("ground1.txt"), &log).ok());
  EXPECT_NE(log.find("telemetry_rejected=1\n"), std::string::npos) << log;
  EXPECT_NE(log.find("telemetry_keyframe_images=1\n"), std::string::npos) << log;
  ground.pid = start_ground(out, web, tmp.file("ground2.txt"));
  ground.port = wait_for_port(tmp.file("ground2.txt"));
  ASSERT_GT(ground.port, 0);
  const json again = wait_state(ground.port, complete_map);
  EXPECT_EQ(again["segments"], r["segments"]);
  EXPECT_EQ(again["detections"], r["detections"]);
  EXPECT_EQ(again["commands"], r["commands"]);
  EXPECT_EQ(again["pose"], r["pose"]);
  EXPECT_EQ(again["status"]["tasks"], r["status"]["tasks"]);
  EXPECT_EQ(again["keyframes"], r["keyframes"]);
  EXPECT_EQ(again["trajectory_poses"], 40);
}

TEST(HwrGroundViewer, GivenBadHttpAddressesThenUsageErrorAndLoopbackByDefault) {
  TempDir tmp;
  const std::string base =
      "--out " + tmp.file("out") + " --link memq:// --status-interval 0 --exit-after-idle 0";
  for (const char* bad : {"x", "127.0.0.1:70000", ":80", "127.0.0.1:"}) {
    const auto r = hwr::testing::run_cli(hwr::test::emulated_command(kGround),
                                         base + " --http '" + std::string(bad) + "'");
    EXPECT_EQ(r.exit_code, 2) << bad << ": " << r.out;
    EXPECT_NE(r.out.find("expected PORT or HOST:PORT"), std::string::npos) << r.out;
  }
  const auto r = hwr::testing::run_cli(hwr::test::emulated_command(kGround),
                                       base + " --http 0 --web-root " + tmp.file("none"));
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("viewer at http://127.0.0.1:"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("page not built"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace hwr::mapio
