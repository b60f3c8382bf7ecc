// hwr-ground: the ground station (issue #5 item 4, issue #7 item 4; docs/mapio.md).
//   hwr-ground --out DIR [--link URL] [--status-interval S] [--exit-after-idle S] [--no-pcd]
//              [--operator-input FILE] [--operator-robot ID] [--http [HOST:]PORT] [--web-root DIR]
// Receives the robot's map chunks over LCM, verifies and stores them (DIR/<robot>/<run>/seg_*/),
// acknowledges them, writes each completed segment as PLY and PCD (DIR/<robot>/<run>/maps/) and, on
// exit, the merged map (maps/merged.ply, merged.pcd). Restarting on the same DIR resumes: what is
// stored is reported to the robot, which sends only the rest. A live status line goes to stderr.
// Operator channel (mapio/operator_console.hpp): the robots' detections (HWR_DETECTION) are kept under
// DIR/<robot>/operator/ (detections.txt lists them); with --operator-input, commands read from FILE
// (`-`: stdin; a FIFO works: it is read without blocking) are sent on HWR_OPERATOR_CMD until the robot
// acknowledges them on HWR_OPERATOR_ACK, and each outcome is printed to stderr. Line syntax:
// operator_input.hpp; a bad line is reported with its number and skipped. Commands go to the line's
// --robot ID, else --operator-robot ID, else the only robot whose detections arrived. Pending
// commands are re-sent after a restart.
// Viewer (issue #9; docs/ground_viewer.md): with --http, a web page on HOST:PORT (loopback unless a
// HOST is given) shows the map as it arrives, the robots' trajectories, poses (HWR_POSE), scheduler and
// link health (HWR_STATUS), detections and keyframe images (HWR_KEYFRAME_IMAGE), and sends the
// operator's commands. Telemetry is kept under DIR/<robot>/telemetry/ (mapio/ground_telemetry.hpp).
// Stops on SIGINT/SIGTERM, or with --exit-after-idle S once S seconds pass without a new chunk
// (counted from the start when none arrives). Exit: 0 ok, 1 runtime error, 2 usage.

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <chrono>
#include <mutex>

#include "hwr/core/log.hpp"
#include "hwr/mapio/ground_station.hpp"
#include "hwr/mapio/lcm_link.hpp"
#include "hwr/mapio/ground_telemetry.hpp"
#include "hwr/mapio/operator_console.hpp"
#include "operator_input.hpp"
#include "viewer_server.hpp"

namespace {

volatile std::sig_atomic_t g_stop = 0;
// Added to now_ns() to make service() send every pending ack regardless of the ack interval.
constexpr int64_t g_force_ack_ns = 1'000'000'000'000;
void on_signal(int) { g_stop = 1; }

// The page toolchain/build-web.sh builds: $HWR_WEB_ROOT, else build/web/dist in the source tree.
std::string default_web_root() {
  if (const char* env = std::getenv("HWR_WEB_ROOT"); env != nullptr && env[0] != '\0') return env;
  return std::string(HWR_SOURCE_DIR) + "/build/web/dist";
}

int usage(const char* msg) {
  if (msg != nullptr) std::fprintf(stderr, "hwr-ground: %s\n", msg);
  std::fprintf(
      stderr,
      "usage: hwr-ground --out DIR [--link URL] [--status-interval S] [--exit-after-idle S] [--no-pcd]\n"
      "                  [--operator-input FILE] [--operator-robot ID] [--http [HOST:]PORT] [--web-root "
      "DIR]\n"
      "  --link URL            LCM URL (default %s)\n"
      "  --status-interval S   seconds between status lines (default 1; 0: none)\n"
      "  --exit-after-idle S   exit S seconds after the last new chunk (or after start, if none)\n"
      "  --no-pcd              write PLY maps only\n"
      "  --operator-input FILE operator commands, one per line (-: stdin; a FIFO works):\n"
      "                          [--robot ID] confirm ID | reject ID\n"
      "                          [--robot ID] move ID CX CY CZ SX SY SZ [QW QX QY QZ]   (world, metres)\n"
      "                          [--robot ID] add KEYFRAME_T_NS X Y W H [CX CY CZ SX SY SZ]   (pixels)\n"
      "  --operator-robot ID   robot of the commands without --robot (default: the only robot whose\n"
      "                        detections arrived)\n"
      "  --http [HOST:]PORT    serve the viewer page (docs/ground_viewer.md) on HOST:PORT; HOST defaults to\n"
      "                        127.0.0.1 (loopback only); PORT 0 picks a free one\n"
      "  --web-root DIR        the built page (default %s; toolchain/build-web.sh)\n",
      hwr::mapio::kDefaultLinkUrl, default_web_root().c_str());
  return 2;
}

// Which robot a command line without --robot is for; empty with *why set when it cannot be told.
std::string default_robot(const hwr::mapio::OperatorConsole& console, const std::string& option,
                          std::string* why) {
  if (!option.empty()) return option;
  const std::vector<std::string> robots = console.robots_with_detections();
  if (robots.size() == 1) return robots[0];
  if (robots.empty()) {
    *why =
        "no robot has sent detections yet: put --robot ID before the command or start hwr-ground with "
        "--operator-robot ID";
  } else {
    std::string list;
    for (const std::string& r : robots) list += (list.empty() ? "" : ", ") + r;
    *why = std::to_string(robots.size()) + " robots have sent detections (" + list +
           "): put --robot ID before the command or start hwr-ground with --operator-robot ID";
  }
  return "";
}

void send_operator_line(hwr::mapio::OperatorConsole& console, const std::string& robot_option,
                        const std::string& input_name, int64_t number, const std::string& text) {
  const std::string where = input_name + " line " + std::to_string(number);
  if (!text.empty() && text[0] == hwr::ground::OperatorInput::kTooLong) {
    std::fprintf(stderr, "hwr-ground: %s: %s, skipped\n", where.c_str(), text.c_str() + 1);
    return;
  }
  auto line = hwr::ground::parse_operator_line(text);
  if (!line.ok()) {
    std::fprintf(stderr, "hwr-ground: %s: %s, skipped\n", where.c_str(), line.status().message().c_str());
    return;
  }
  if (line->empty) return;
  std::string why;
  line->command.robot_id =
      line->robot_id.empty() ? default_robot(console, robot_option, &why) : line->robot_id;
  if (line->command.robot_id.empty()) {
    std::fprintf(stderr, "hwr-ground: %s: %s; skipped\n", where.c_str(), why.c_str());
    return;
  }
  auto id = console.send(line->command);
  if (!id.ok()) {
    std::fprintf(stderr, "hwr-ground: %s: %s, skipped\n", where.c_str(), id.status().message().c_str());
    return;
  }
  std::fprintf(stderr, "hwr-ground: command %lld (%s) for %s: sending\n", static_cast<long long>(*id),
               hwr::mapio::describe_operator_command(line->command).c_str(), line->command.robot_id.c_str());
}

void print_acknowledged(hwr::mapio::OperatorConsole& console) {
  for (const hwr::mapio::OperatorCommandRecord& r : console.take_acknowledged()) {
    const std::string what = hwr::mapio::describe_operator_command(r.command);
    if (r.state == hwr::mapio::CommandState::kAccepted) {
      const bool added = r.command.kind == static_cast<int8_t>(hwr::mapio::OperatorCommandKind::kAdd);
      std::fprintf(stderr, "hwr-ground: command %lld (%s): accepted%s\n",
                   static_cast<long long>(r.command.command_id), what.c_str(),
                   added ? (", detection " + std::to_string(r.detection_id)).c_str() : "");
    } else {
      std::string reason = r.reason;
      for (char& ch : reason) {
        if (static_cast<unsigned char>(ch) < 0x20) ch = ' ';
      }
      std::fprintf(stderr, "hwr-ground: command %lld (%s): refused: %s\n",
                   static_cast<long long>(r.command.command_id), what.c_str(), reason.c_str());
    }
  }
}

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

int main(int argc, char** argv) {
  std::string out, url = hwr::mapio::kDefaultLinkUrl;
  std::string operator_input_path, operator_robot, http, web_root = default_web_root();
  double status_s = 1.0, idle_exit_s = -1.0;
  bool pcd = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--out" && has_value) {
      out = argv[++i];
    } else if (a == "--link" && has_value) {
      url = argv[++i];
    } else if (a == "--status-interval" && has_value) {
      status_s = std::atof(argv[++i]);
    } else if (a == "--exit-after-idle" && has_value) {
      idle_exit_s = std::atof(argv[++i]);
    } else if (a == "--operator-input" && has_value) {
      operator_input_path = argv[++i];
    } else if (a == "--operator-robot" && has_value) {
      operator_robot = argv[++i];
      const hwr::core::Status st = hwr::mapio::GroundStore::validate_robot_id(operator_robot);
      if (!st.ok()) return usage(("--operator-robot: " + st.message()).c_str());
    } else if (a == "--http" && has_value) {
      http = argv[++i];
    } else if (a == "--web-root" && has_value) {
      web_root = argv[++i];
    } else if (a == "--no-pcd") {
      pcd = false;
    } else if (a == "--help" || a == "-h") {
      return usage(nullptr);
    } else {
      return usage(("unknown or incomplete argument: " + a).c_str());
    }
  }
  if (out.empty()) return usage("--out DIR is required");
  hwr::ground::ViewerServerConfig viewer_config;
  viewer_config.web_root = web_root;
  if (!http.empty()) {
    const hwr::core::Status st =
        hwr::ground::parse_http_address(http, &viewer_config.host, &viewer_config.port);
    if (!st.ok()) return usage(st.message().c_str());
  }

  hwr::mapio::GroundStationConfig config;
  config.out_dir = out;
  config.write_pcd = pcd;
  auto station = hwr::mapio::GroundStation::open(config);
  if (!station.ok()) {
    std::fprintf(stderr, "hwr-ground: %s\n", station.status().message().c_str());
    return 1;
  }
  auto opened_console = hwr::mapio::OperatorConsole::open(out);
  if (!opened_console.ok()) {
    std::fprintf(stderr, "hwr-ground: %s\n", opened_console.status().message().c_str());
    return 1;
  }
  hwr::mapio::OperatorConsole& console = *opened_console.value();
  for (const std::string& note : console.open_report().notes)
    HWR_LOG_WARN("ground", "operator: %s", note.c_str());
  hwr::mapio::GroundTelemetryConfig telemetry_config;
  telemetry_config.out_dir = out;
  auto opened_telemetry = hwr::mapio::GroundTelemetry::open(telemetry_config);
  if (!opened_telemetry.ok()) {
    std::fprintf(stderr, "hwr-ground: %s\n", opened_telemetry.status().message().c_str());
    return 1;
  }
  hwr::mapio::GroundTelemetry& telemetry = *opened_telemetry.value();
  for (const std::string& note : telemetry.open_notes())
    HWR_LOG_WARN("ground", "telemetry: %s", note.c_str());
  std::unique_ptr<hwr::ground::OperatorInput> input;
  if (!operator_input_path.empty()) {
    auto opened_input = hwr::ground::OperatorInput::open(operator_input_path);
    if (!opened_input.ok()) {
      std::fprintf(stderr, "hwr-ground: %s\n", opened_input.status().message().c_str());
      return 1;
    }
    input = std::make_unique<hwr::ground::OperatorInput>(std::move(opened_input.value()));
  }
  const std::string input_name = operator_input_path == "-" ? "stdin" : operator_input_path;
  auto link = hwr::mapio::LcmLink::open(url);
  if (!link.ok()) {
    std::fprintf(stderr, "hwr-ground: %s\n", link.status().message().c_str());
    return 1;
  }
  hwr::mapio::GroundStation& g = *station.value();
  // The viewer's HTTP threads read the state and send commands under this lock; the loop below holds
  // it whenever it changes the state (not while it waits for messages).
  std::mutex state_mutex;
  using Guard = std::lock_guard<std::mutex>;
  link->subscribe(hwr::mapio::kChannelMapChunk, [&](const uint8_t* d, size_t n) {
    const Guard lock(state_mutex);
    g.on_chunk_message(d, n, now_ns());
  });
  link->subscribe(hwr::mapio::kChannelDetection, [&](const uint8_t* d, size_t n) {
    const Guard lock(state_mutex);
    console.on_detection_message(d, n, now_ns());
  });
  link->subscribe(hwr::mapio::kChannelOperatorAck, [&](const uint8_t* d, size_t n) {
    const Guard lock(state_mutex);
    console.on_ack_message(d, n, now_ns());
  });
  link->subscribe(hwr::mapio::kChannelPose, [&](const uint8_t* d, size_t n) {
    const Guard lock(state_mutex);
    telemetry.on_pose_message(d, n);
  });
  link->subscribe(hwr::mapio::kChannelStatus, [&](const uint8_t* d, size_t n) {
    const Guard lock(state_mutex);
    telemetry.on_status_message(d, n, now_ns());
  });
  link->subscribe(hwr::mapio::kChannelKeyframeImage, [&](const uint8_t* d, size_t n) {
    const Guard lock(state_mutex);
    telemetry.on_keyframe_image_message(d, n);
  });
  // Before the viewer prints its address: a supervisor that stops us once it sees it gets an orderly stop.
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::unique_ptr<hwr::ground::ViewerServer> viewer;
  if (!http.empty()) {
    auto started = hwr::ground::ViewerServer::start(viewer_config, g, console, telemetry, state_mutex);
    if (!started.ok()) {
      std::fprintf(stderr, "hwr-ground: %s\n", started.status().message().c_str());
      return 1;
    }
    viewer = std::move(started.value());
    if (!hwr::ground::is_loopback_host(viewer_config.host)) {
      std::fprintf(
          stderr,
          "hwr-ground: warning: the viewer listens on %s, not loopback: anyone who reaches it can send "
          "operator commands\n",
          viewer_config.host.c_str());
    }
    const bool ipv6 = viewer_config.host.find(':') != std::string::npos;
    std::fprintf(stderr, "hwr-ground: viewer at http://%s%s%s:%d/%s\n", ipv6 ? "[" : "",
                 viewer_config.host.c_str(), ipv6 ? "]" : "", viewer->port(),
                 std::filesystem::exists(web_root + "/index.html")
                     ? ""
                     : (" (page not built under " + web_root + ": run toolchain/build-web.sh)").c_str());
  }
  std::fprintf(stderr, "hwr-ground: listening on %s, storing under %s (%lld chunks already stored)\n",
               url.c_str(), out.c_str(), static_cast<long long>(g.store().chunks_stored()));
  if (console.pending_commands() > 0) {
    std::fprintf(stderr, "hwr-ground: %lld operator commands still pending from before: sending them again\n",
                 static_cast<long long>(console.pending_commands()));
  }
  std::vector<std::pair<int64_t, std::string>> lines;

  const int64_t started_ns = now_ns();
  int64_t last_status = started_ns, last_maps = started_ns;
  int rc = 0;
  while (!g_stop) {
    auto r = link->handle(10);
    if (!r.ok() && g_stop) break;  // the wait was interrupted by SIGINT/SIGTERM
    if (!r.ok()) {
      std::fprintf(stderr, "hwr-ground: %s\n", r.status().message().c_str());
      rc = 1;
      break;
    }
    const int64_t t = now_ns();
    std::unique_lock<std::mutex> lock(state_mutex);
    g.service(t, [&](const hwr_lcm::chunk_ack_t& ack) {
      const hwr::core::Status st = link->publish(hwr::mapio::kChannelMapAck, ack);
      if (!st.ok()) HWR_LOG_WARN("ground", "ack not sent: %s", st.message().c_str());
    });
    if (input) {
      lines.clear();
      const hwr::core::Status st = input->poll(&lines);
      if (!st.ok()) {
        std::fprintf(stderr, "hwr-ground: %s; no more operator input\n", st.message().c_str());
        input.reset();
      }
      for (const auto& [number, text] : lines)
        send_operator_line(console, operator_robot, input_name, number, text);
    }
    console.service(t, [&](const hwr_lcm::operator_command_t& cmd) {
      // Not sent now is sent on the next interval: the command stays pending until acknowledged.
      const hwr::core::Status st = link->publish(hwr::mapio::kChannelOperatorCommand, cmd);
      if (!st.ok()) HWR_LOG_WARN("ground", "operator command not sent: %s", st.message().c_str());
    });
    print_acknowledged(console);
    if (t - last_maps > 1'000'000'000) {
      // Acknowledge what is stored before the (slow) map writing, so the robot is not kept waiting.
      g.service(t + g_force_ack_ns, [&](const hwr_lcm::chunk_ack_t& ack) {
        (void)link->publish(hwr::mapio::kChannelMapAck, ack);
      });
      const hwr::core::Status st = g.write_maps(false);
      if (!st.ok()) HWR_LOG_ERROR("ground", "writing segment maps: %s", st.message().c_str());
      last_maps = t;
    }
    lock.unlock();
    if (status_s > 0 && (t - last_status) * 1e-9 >= status_s) {
      std::fprintf(stderr, "hwr-ground: %s\n", g.status_line(t).c_str());
      last_status = t;
    }
    // Idle since the last new chunk, or since start when none came (a restart after everything was stored).
    const int64_t idle_since = g.stats().last_chunk_ns > 0 ? g.stats().last_chunk_ns : started_ns;
    if (idle_exit_s >= 0 && (t - idle_since) * 1e-9 >= idle_exit_s) break;
  }
  viewer.reset();  // no more HTTP threads: the state is this thread's alone from here
  // Last acks, then the maps.
  g.service(now_ns() + 1'000'000'000'000,
            [&](const hwr_lcm::chunk_ack_t& ack) { (void)link->publish(hwr::mapio::kChannelMapAck, ack); });
  const hwr::core::Status st = g.write_maps(true);
  if (!st.ok()) {
    std::fprintf(stderr, "hwr-ground: writing maps: %s\n", st.message().c_str());
    rc = 1;
  }
  std::printf("%s\n", g.status_line(now_ns()).c_str());
  std::printf("ground_chunks_stored=%lld\nground_points=%lld\nground_duplicates=%lld\nground_rejected=%lld\n",
              static_cast<long long>(g.store().chunks_stored()),
              static_cast<long long>(g.stats().points_stored), static_cast<long long>(g.stats().duplicates),
              static_cast<long long>(g.stats().rejected));
  int64_t detections = 0;
  for (const std::string& robot : console.robots())
    detections += static_cast<int64_t>(console.detections(robot).size());
  std::printf("operator_detections=%lld\noperator_commands_sent=%lld\noperator_commands_pending=%lld\n",
              static_cast<long long>(detections), static_cast<long long>(console.stats().commands_sent),
              static_cast<long long>(console.pending_commands()));
  const hwr::mapio::GroundTelemetryStats& ts = telemetry.stats();
  std::printf(
      "telemetry_poses=%lld\ntelemetry_statuses=%lld\ntelemetry_keyframe_images=%lld\n"
      "telemetry_rejected=%lld\n",
      static_cast<long long>(ts.poses), static_cast<long long>(ts.statuses),
      static_cast<long long>(ts.keyframe_images), static_cast<long long>(ts.rejected));
  std::printf("maps under %s/<robot>/<run>/maps (segment_*.ply/.pcd, merged.ply/.pcd)\n", out.c_str());
  return rc;
}
