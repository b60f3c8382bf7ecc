// hwr-ground: the ground-station chunk receiver (issue #5 item 4; docs/mapio.md).
//   hwr-ground --out DIR [--link URL] [--status-interval S] [--exit-after-idle S] [--no-pcd]
// Receives the robot's map chunks over LCM, verifies and stores them (DIR/<robot>/<run>/seg_*/),
// acknowledges them, writes each completed segment as PLY and PCD (DIR/<robot>/<run>/maps/) and, on
// exit, the merged map (maps/merged.ply, merged.pcd). Restarting on the same DIR resumes: what is
// stored is reported to the robot, which sends only the rest. A live status line goes to stderr.
// Stops on SIGINT/SIGTERM, or with --exit-after-idle S once S seconds pass without a new chunk
// (counted from the start when none arrives). Exit: 0 ok, 1 runtime error, 2 usage.

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include <chrono>

#include "hwr/core/log.hpp"
#include "hwr/mapio/ground_station.hpp"
#include "hwr/mapio/lcm_link.hpp"

namespace {

volatile std::sig_atomic_t g_stop = 0;
// Added to now_ns() to make service() send every pending ack regardless of the ack interval.
constexpr int64_t g_force_ack_ns = 1'000'000'000'000;
void on_signal(int) { g_stop = 1; }

int usage(const char* msg) {
  if (msg != nullptr) std::fprintf(stderr, "hwr-ground: %s\n", msg);
  std::fprintf(
      stderr,
      "usage: hwr-ground --out DIR [--link URL] [--status-interval S] [--exit-after-idle S] [--no-pcd]\n"
      "  --link URL            LCM URL (default %s)\n"
      "  --status-interval S   seconds between status lines (default 1; 0: none)\n"
      "  --exit-after-idle S   exit S seconds after the last new chunk (or after start, if none)\n",
      hwr::mapio::kDefaultLinkUrl);
  return 2;
}

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

int main(int argc, char** argv) {
  std::string out, url = hwr::mapio::kDefaultLinkUrl;
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
    } else if (a == "--no-pcd") {
      pcd = false;
    } else if (a == "--help" || a == "-h") {
      return usage(nullptr);
    } else {
      return usage(("unknown or incomplete argument: " + a).c_str());
    }
  }
  if (out.empty()) return usage("--out DIR is required");

  hwr::mapio::GroundStationConfig config;
  config.out_dir = out;
  config.write_pcd = pcd;
  auto station = hwr::mapio::GroundStation::open(config);
  if (!station.ok()) {
    std::fprintf(stderr, "hwr-ground: %s\n", station.status().message().c_str());
    return 1;
  }
  auto link = hwr::mapio::LcmLink::open(url);
  if (!link.ok()) {
    std::fprintf(stderr, "hwr-ground: %s\n", link.status().message().c_str());
    return 1;
  }
  hwr::mapio::GroundStation& g = *station.value();
  link->subscribe(hwr::mapio::kChannelMapChunk,
                  [&](const uint8_t* d, size_t n) { g.on_chunk_message(d, n, now_ns()); });
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::fprintf(stderr, "hwr-ground: listening on %s, storing under %s (%lld chunks already stored)\n",
               url.c_str(), out.c_str(), static_cast<long long>(g.store().chunks_stored()));

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
    g.service(t, [&](const hwr_lcm::chunk_ack_t& ack) {
      const hwr::core::Status st = link->publish(hwr::mapio::kChannelMapAck, ack);
      if (!st.ok()) HWR_LOG_WARN("ground", "ack not sent: %s", st.message().c_str());
    });
    if (t - last_maps > 1'000'000'000) {
      // Acknowledge what is stored before the (slow) map writing, so the robot is not kept waiting.
      g.service(t + g_force_ack_ns, [&](const hwr_lcm::chunk_ack_t& ack) {
        (void)link->publish(hwr::mapio::kChannelMapAck, ack);
      });
      const hwr::core::Status st = g.write_maps(false);
      if (!st.ok()) HWR_LOG_ERROR("ground", "writing segment maps: %s", st.message().c_str());
      last_maps = t;
    }
    if (status_s > 0 && (t - last_status) * 1e-9 >= status_s) {
      std::fprintf(stderr, "hwr-ground: %s\n", g.status_line(t).c_str());
      last_status = t;
    }
    // Idle since the last new chunk, or since start when none came (a restart after everything was stored).
    const int64_t idle_since = g.stats().last_chunk_ns > 0 ? g.stats().last_chunk_ns : started_ns;
    if (idle_exit_s >= 0 && (t - idle_since) * 1e-9 >= idle_exit_s) break;
  }
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
  std::printf("maps under %s/<robot>/<run>/maps (segment_*.ply/.pcd, merged.ply/.pcd)\n", out.c_str());
  return rc;
}
