// `hwr-bench rgbd-odometry-peer`: OpenCV-contrib's cv::rgbd::RgbdOdometry (rgbd_odometry_peer.hpp)
// alone over one source, scored like hwr-eval (ATE RMSE after SE(3) alignment, TUM association).
// It is the yardstick of issue #3's speed acceptance; the issue quotes about 2.10 cm ATE at about
// 16 ms per frame on TUM fr3/teddy.
//
//   hwr-bench rgbd-odometry-peer [--source tum:DIR|sim:DIR] [--traj-out FILE] [--frames N] [--threads N]
//
// --threads N sets OpenCV's thread count (default: OpenCV's own choice, all cores). Wall time per
// call is the figure; the CPU time of the process per call is printed beside it because on a
// shared machine wall time also counts other processes' slices.
//
// Ground truth: DIR/groundtruth.txt (TUM format, T_world_cam, for both kinds).

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <string>
#include <vector>

#include <opencv2/core/utility.hpp>

#include "bench_command.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/estimation/trajectory_metrics.hpp"
#include "hwr/hal/replay_source.hpp"
#include "rgbd_odometry_peer.hpp"

// The simulator's run reader, when this build has the simulator (hwr-bench links hwr::sim then).
#if defined(HWR_WITH_SIM)
#define HWR_PEER_BENCH_SIM HWR_WITH_SIM
#elif __has_include("hwr/sim/sim_run_replay.hpp")
#define HWR_PEER_BENCH_SIM 1
#else
#define HWR_PEER_BENCH_SIM 0
#endif
#if HWR_PEER_BENCH_SIM
#include "hwr/sim/sim_run_replay.hpp"
#endif

namespace hwr::bench {
namespace {

const std::string kTeddy = HWR_DATA_DIR "/tum-fr3-teddy-200/rgbd_dataset_freiburg3_teddy";

struct Source {
  std::string sequence;  // key suffix: "teddy", the simulator's scenario name, ...
  hal::ReplayLog log;
  std::string groundtruth_path;
};

// "rgbd_dataset_freiburg3_teddy" → "teddy"; anything else: the folder name, lower-case
// alphanumerics and '_' only.
std::string sequence_name(std::string dir) {
  while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
  std::string base = dir.substr(dir.find_last_of('/') + 1);
  const std::string tum_prefix = "rgbd_dataset_freiburg";
  if (base.rfind(tum_prefix, 0) == 0 && base.size() > tum_prefix.size() + 2) {
    base = base.substr(tum_prefix.size() + 2);  // the digit and the '_'
  }
  for (char& c : base) {
    c = std::isalnum(static_cast<unsigned char>(c)) ? static_cast<char>(std::tolower(c)) : '_';
  }
  return base;
}

core::Expected<Source> open_source(const std::string& spec) {
  const size_t colon = spec.find(':');
  const std::string kind = colon == std::string::npos ? "" : spec.substr(0, colon);
  const std::string dir = colon == std::string::npos ? "" : spec.substr(colon + 1);
  Source s;
  s.groundtruth_path = dir + "/groundtruth.txt";
  if (kind == "tum") {
    auto log = hal::open_dataset_log(spec);
    if (!log.ok()) return log.status();
    s.log = std::move(log).value();
    s.sequence = sequence_name(dir);
    return s;
  }
  if (kind == "sim") {
#if HWR_PEER_BENCH_SIM
    auto run = sim::open_sim_run_log(dir);
    if (!run.ok()) return run.status();
    s.log = std::move(run->log);
    s.sequence = sequence_name(run->calibration.scenario.empty() ? dir : run->calibration.scenario);
    return s;
#else
    return core::Unavailable("source '" + spec + "': this build has no simulator");
#endif
  }
  return core::InvalidArgument("source '" + spec + "': expected tum:DIR or sim:DIR");
}

double mean(const std::vector<double>& v) {
  return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

// Nearest-rank percentile.
double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double rank = std::ceil(q * static_cast<double>(v.size()));
  return v[std::min(v.size() - 1, static_cast<size_t>(std::max(1.0, rank)) - 1)];
}

int run_peer(int argc, char** argv) {
  std::string source = "tum:" + kTeddy;
  std::string traj_out;
  size_t max_frames = 0;
  int threads = -1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&](const char* name, std::string* out) {
      const std::string eq = std::string(name) + "=";
      if (a.rfind(eq, 0) == 0) {
        *out = a.substr(eq.size());
        return true;
      }
      if (a == name && i + 1 < argc) {
        *out = argv[++i];
        return true;
      }
      return false;
    };
    std::string v;
    if (value("--source", &source) || value("--traj-out", &traj_out)) continue;
    if (value("--frames", &v)) {
      max_frames = static_cast<size_t>(std::max(0L, std::atol(v.c_str())));
      continue;
    }
    if (value("--threads", &v)) {
      threads = std::atoi(v.c_str());
      if (threads < 1) {
        std::fprintf(stderr, "rgbd-odometry-peer: --threads wants a count >= 1, got '%s'\n", v.c_str());
        return 2;
      }
      continue;
    }
    std::fprintf(stderr,
                 "rgbd-odometry-peer: unknown or incomplete argument '%s' (use --source tum:DIR|sim:DIR, "
                 "--traj-out FILE, --frames N, --threads N)\n",
                 a.c_str());
    return 2;
  }
  if (!rgbd_odometry_available()) {
    std::printf("rgbd-odometry-peer: unavailable (hwr-bench built without OpenCV contrib rgbd)\n");
    return 0;
  }
  if (threads > 0) cv::setNumThreads(threads);
  auto src = open_source(source);
  if (!src.ok()) {
    std::fprintf(stderr, "rgbd-odometry-peer: %s\n", src.status().to_string().c_str());
    return 1;
  }
  auto gt = core::read_tum_trajectory(src->groundtruth_path);
  if (!gt.ok()) {
    std::fprintf(stderr, "rgbd-odometry-peer: ground truth: %s\n", gt.status().to_string().c_str());
    return 1;
  }
  const RgbdOdometryOptions options = [&] {
    RgbdOdometryOptions o = rgbd_odometry_options_for(src->log.info);
    o.max_frames = max_frames;
    return o;
  }();
  auto run = run_rgbd_odometry(src->log, options);
  if (!run.ok()) {
    std::fprintf(stderr, "rgbd-odometry-peer: %s\n", run.status().to_string().c_str());
    return 1;
  }
  if (!traj_out.empty()) {
    const core::Status st = core::write_tum_trajectory(
        traj_out, run->T_world_cam, "cv::rgbd::RgbdOdometry frame to frame, T_world_cam, " + source);
    if (!st.ok()) {
      std::fprintf(stderr, "rgbd-odometry-peer: %s\n", st.to_string().c_str());
      return 1;
    }
  }
  auto ate = estimation::compute_ate(gt.value(), run->T_world_cam);
  if (!ate.ok()) {
    std::fprintf(stderr, "rgbd-odometry-peer: ATE: %s\n", ate.status().to_string().c_str());
    return 1;
  }
  const std::vector<double>& ms = run->frame_ms;
  const std::vector<double>& cpu_ms = run->frame_cpu_ms;
  std::printf("rgbd-odometry-peer: cv::rgbd::RgbdOdometry frame to frame on %s\n", source.c_str());
  std::printf("  depth %.2f-%.2f m, OpenCV %s, %d OpenCV threads\n", options.min_depth_m, options.max_depth_m,
              CV_VERSION, cv::getNumThreads());
  std::printf("  %-10s %7s %8s %6s %11s %11s %10s %9s %9s %9s %9s %9s\n", "sequence", "frames", "calls",
              "fail", "ATE rmse m", "ATE max m", "gt pairs", "mean ms", "p50 ms", "p99 ms", "max ms",
              "cpu ms");
  std::printf("  %-10s %7zu %8zu %6d %11.4f %11.4f %10zu %9.2f %9.2f %9.2f %9.2f %9.2f\n",
              src->sequence.c_str(), run->T_world_cam.size(), ms.size(), run->failures,
              ate->translation_m.rmse, ate->translation_m.max, ate->pairs, mean(ms), percentile(ms, 0.5),
              percentile(ms, 0.99), ms.empty() ? 0.0 : *std::max_element(ms.begin(), ms.end()), mean(cpu_ms));
  if (!traj_out.empty()) std::printf("  trajectory: %s\n", traj_out.c_str());
  std::printf("rgbd_odometry_ms_mean=%.3f\n", mean(ms));
  std::printf("rgbd_odometry_ms_p99=%.3f\n", percentile(ms, 0.99));
  std::printf("rgbd_odometry_cpu_ms_mean=%.3f\n", mean(cpu_ms));
  std::printf("rgbd_odometry_failures_%s=%d\n", src->sequence.c_str(), run->failures);
  std::printf("ate_m_%s_rgbd_odometry=%.5f\n", src->sequence.c_str(), ate->translation_m.rmse);
  return 0;
}

}  // namespace

HWR_BENCH_COMMAND(rgbd_odometry_peer, "rgbd-odometry-peer",
                  "OpenCV RgbdOdometry peer: ATE and ms/frame [--source tum:DIR|sim:DIR] [--traj-out FILE] "
                  "[--frames N] [--threads N]",
                  run_peer);

}  // namespace hwr::bench
