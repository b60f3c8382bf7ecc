// `hwr-bench frame`: the whole pose-estimation pipeline (issue #3) over every sequence present,
// beside OpenCV-contrib's cv::rgbd::RgbdOdometry (frame to frame) on the same frames in the same
// run. Per sequence: ATE RMSE (hwr-eval's definition: SE(3) alignment, TUM association), the
// per-frame time of the tracking path (the camera task: IMU propagation to the frame time,
// features, matching, pose, keyframe insertion) on this thread, the sliding-window bundle
// adjustment per keyframe (the mapping task), heap allocations per frame after warm-up, and
// the peer's ATE and time. Table I of the paper compares per-frame time; these are our rows.
//
//   hwr-bench frame [--sequences teddy,lab,outdoor] [--duration S] [--no-peer] [--config FILE]
//                   [--traj-out DIR]
//
// --config takes hwr-robot's estimation settings (YAML, section estimation:), so a setting can be
// benched before it becomes the default. --traj-out writes, per sequence, the trajectories the ATEs
// are taken on (TUM format): DIR/<sequence>_groundtruth.tum, _ours.tum and _rgbd_odometry.tum
// (`hwr-bench paper` plots them).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include "sample_stats.hpp"
#include "bench_command.hpp"
#include "bench_sequences.hpp"
#include "hwr/core/alloc_counter.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/estimation/estimator_config.hpp"
#include "hwr/estimation/offline_run.hpp"
#include "hwr/estimation/trajectory_metrics.hpp"
#include "hwr/hal/replay_source.hpp"
#include "rgbd_odometry_peer.hpp"

namespace hwr::bench {
namespace {

constexpr size_t kWarmupFrames = 30;

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t k =
      std::min(v.size() - 1, static_cast<size_t>(std::ceil(q * static_cast<double>(v.size())) - 1));
  return v[k];
}

double mean(const std::vector<double>& v) {
  return v.empty() ? 0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

// DIR/<sequence>_<what>.tum (a scenario path's '/' and '.' written '_').
void write_trajectory(const std::string& dir, const std::string& sequence, const char* what,
                      const std::vector<core::StampedPose>& poses) {
  if (dir.empty()) return;
  std::string name = sequence;
  for (char& c : name)
    if (c == '/' || c == '.') c = '_';
  const std::string path = dir + "/" + name + "_" + what + ".tum";
  const core::Status st =
      core::write_tum_trajectory(path, poses, "hwr-bench frame: " + sequence + " " + what);
  if (!st.ok()) std::fprintf(stderr, "hwr-bench frame: --traj-out: %s\n", st.message().c_str());
}

double ate_rmse(const std::vector<core::StampedPose>& gt, const std::vector<core::StampedPose>& est,
                size_t* pairs) {
  auto ate = estimation::compute_ate(gt, est, estimation::AteOptions{});
  if (!ate.ok()) {
    *pairs = 0;
    return NAN;
  }
  *pairs = ate->pairs;
  return ate->translation_m.rmse;
}

int run_frame(int argc, char** argv) {
  std::string sequences = "teddy,lab,outdoor";
  double duration_s = 0;
  bool peer = true;
  std::string traj_dir;
  estimation::PoseEstimatorConfig config;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a.rfind("--sequences=", 0) == 0) {
      sequences = a.substr(12);
    } else if (a == "--sequences" && i + 1 < argc) {
      sequences = argv[++i];
    } else if (a.rfind("--duration=", 0) == 0) {
      duration_s = std::atof(a.c_str() + 11);
    } else if (a == "--duration" && i + 1 < argc) {
      duration_s = std::atof(argv[++i]);
    } else if (a == "--traj-out" && i + 1 < argc) {
      traj_dir = argv[++i];
      std::error_code ec;
      std::filesystem::create_directories(traj_dir, ec);
      if (ec) {
        std::fprintf(stderr, "hwr-bench frame: --traj-out %s: %s\n", traj_dir.c_str(), ec.message().c_str());
        return 2;
      }
    } else if (a == "--no-peer") {
      peer = false;
    } else if (a == "--config" && i + 1 < argc) {
      auto loaded = estimation::load_estimator_config(argv[++i]);
      if (!loaded.ok()) {
        std::fprintf(stderr, "hwr-bench frame: --config: %s\n", loaded.status().message().c_str());
        return 2;
      }
      config = loaded.value();
    } else {
      std::fprintf(stderr, "hwr-bench frame: unknown option '%s'\n", a.c_str());
      return 2;
    }
  }
  std::vector<std::string> names;
  std::stringstream ss(sequences);
  for (std::string n; std::getline(ss, n, ',');) {
    if (!n.empty()) names.push_back(n);
  }

  std::vector<double> all_ms, all_ba_ms;
  uint64_t steady_allocs = 0, steady_orb_allocs = 0, steady_frames = 0;
  std::vector<std::string> keys;
  std::printf("%-9s %-16s %6s %6s %10s %9s %9s %9s %8s %9s\n", "sequence", "method", "frames", "lost",
              "ATE [m]", "ATE [%]", "mean ms", "p99 ms", "allocs*", "BA ms/kf");
  for (const std::string& name : names) {
    auto seq = open_sequence(name, duration_s);
    if (!seq.ok()) {
      std::fprintf(stderr, "hwr-bench frame: %s: %s\n", name.c_str(), seq.status().message().c_str());
      return 1;
    }
    // Ours.
    estimation::OfflineRunOptions opt;
    opt.estimator = config;
    // Allocations per frame of the tracking path, and of OpenCV's ORB inside it.
    std::vector<uint64_t> frame_allocs, frame_orb_allocs;
    uint64_t before = 0;
    core::StageAllocations orb;
    opt.on_start = [&](estimation::PoseEstimator& e) {
      e.tracker().set_extract_hook(&core::StageAllocations::hook, &orb);
    };
    opt.around_track = [&](size_t, bool is_before) {
      if (is_before) {
        before = core::thread_allocation_counts().allocations;
        orb.allocations = 0;
      } else {
        frame_allocs.push_back(core::thread_allocation_counts().allocations - before);
        frame_orb_allocs.push_back(orb.allocations);
      }
    };
    auto run = estimation::run_offline(seq->log, opt);
    if (!run.ok()) {
      std::fprintf(stderr, "hwr-bench frame: %s: %s\n", name.c_str(), run.status().message().c_str());
      return 1;
    }
    std::vector<double> ms, ba_ms;
    // Mean per stage of the tracking path (ms): imu, extract, match, pose, keyframe.
    double stage_ms[5] = {0, 0, 0, 0, 0};
    uint64_t allocs = 0, orb_allocs = 0, counted = 0;
    for (size_t i = 0; i < run->timings.size(); ++i) {
      const auto& t = run->timings[i];
      if (t.state == estimation::TrackState::kWaiting) continue;
      ms.push_back(t.total_ns * 1e-6);
      stage_ms[0] += t.imu_ns * 1e-6;
      stage_ms[1] += t.track.extract_ns * 1e-6;
      stage_ms[2] += t.track.match_ns * 1e-6;
      stage_ms[3] += t.track.pose_ns * 1e-6;
      stage_ms[4] += t.track.keyframe_ns * 1e-6;
      if (t.local_ba_ns > 0) ba_ms.push_back(t.local_ba_ns * 1e-6);
      // Allocations of steady-state, non-keyframe frames after warm-up.
      if (i >= kWarmupFrames && i < frame_allocs.size() && !t.keyframe) {
        allocs += frame_allocs[i] - frame_orb_allocs[i];
        orb_allocs += frame_orb_allocs[i];
        ++counted;
      }
    }
    steady_allocs += allocs;
    steady_orb_allocs += orb_allocs;
    steady_frames += counted;
    all_ms.insert(all_ms.end(), ms.begin(), ms.end());
    all_ba_ms.insert(all_ba_ms.end(), ba_ms.begin(), ba_ms.end());
    size_t pairs = 0;
    const double ate = ate_rmse(seq->groundtruth, run->trajectory, &pairs);
    const double ate_pct = seq->path_length_m > 0 ? 100.0 * ate / seq->path_length_m : NAN;
    const double allocs_pf = counted ? static_cast<double>(allocs) / static_cast<double>(counted) : 0;
    std::printf("%-9s %-16s %6zu %6llu %10.4f %9.3f %9.2f %9.2f %8.1f %9.1f\n", name.c_str(), "hwr (ours)",
                run->frames, static_cast<unsigned long long>(run->counters.tracker.lost), ate, ate_pct,
                mean(ms), percentile(ms, 0.99), allocs_pf, mean(ba_ms));
    const char* stage_names[5] = {"imu", "extract", "match", "pose", "keyframe"};
    std::printf("%-9s %-16s", "", "  stages [ms]");
    for (int k = 0; k < 5; ++k) {
      stage_ms[k] = ms.empty() ? 0 : stage_ms[k] / static_cast<double>(ms.size());
      std::printf(" %s %.2f", stage_names[k], stage_ms[k]);
    }
    std::printf("\n");
    char line[256];
    std::snprintf(line, sizeof(line), "ate_m_%s=%.5f", name.c_str(), ate);
    keys.push_back(line);
    for (int k = 0; k < 5; ++k) {
      std::snprintf(line, sizeof(line), "stage_ms_%s_%s=%.3f", stage_names[k], name.c_str(), stage_ms[k]);
      keys.push_back(line);
    }
    if (seq->path_length_m > 0) {
      std::snprintf(line, sizeof(line), "ate_pct_%s=%.4f", name.c_str(), ate_pct);
      keys.push_back(line);
    }
    std::snprintf(line, sizeof(line), "frame_ms_mean_%s=%.3f", name.c_str(), mean(ms));
    keys.push_back(line);
    std::snprintf(line, sizeof(line), "frame_ms_p99_%s=%.3f", name.c_str(), percentile(ms, 0.99));
    keys.push_back(line);
    std::snprintf(line, sizeof(line), "frame_ms_sd_%s=%.3f", name.c_str(), sample_sd(ms));
    keys.push_back(line);
    write_trajectory(traj_dir, name, "groundtruth", seq->groundtruth);
    write_trajectory(traj_dir, name, "ours", run->trajectory);
    std::snprintf(line, sizeof(line), "ate_m_%s_before_full_ba=%.5f", name.c_str(),
                  ate_rmse(seq->groundtruth, run->trajectory_before_full_ba, &pairs));
    keys.push_back(line);

    if (!peer) continue;
#if HWR_HAVE_OPENCV_RGBD
    auto seq2 = open_sequence(name, duration_s);  // a fresh loader: frames are loaded in order again
    if (!seq2.ok()) return 1;
    auto p = run_rgbd_odometry(seq2->log);
    if (!p.ok()) {
      std::fprintf(stderr, "hwr-bench frame: peer on %s: %s\n", name.c_str(), p.status().message().c_str());
      continue;
    }
    const double pate = ate_rmse(seq->groundtruth, p->T_world_cam, &pairs);
    std::printf("%-9s %-16s %6zu %6d %10.4f %9.3f %9.2f %9.2f %8s %9s\n", name.c_str(), "RgbdOdometry",
                p->frame_ms.size(), p->failures, pate,
                seq->path_length_m > 0 ? 100.0 * pate / seq->path_length_m : NAN, mean(p->frame_ms),
                percentile(p->frame_ms, 0.99), "-", "-");
    std::snprintf(line, sizeof(line), "ate_m_%s_rgbd_odometry=%.5f", name.c_str(), pate);
    keys.push_back(line);
    std::snprintf(line, sizeof(line), "rgbd_odometry_ms_mean_%s=%.3f", name.c_str(), mean(p->frame_ms));
    keys.push_back(line);
    std::snprintf(line, sizeof(line), "rgbd_odometry_ms_sd_%s=%.3f", name.c_str(), sample_sd(p->frame_ms));
    keys.push_back(line);
    write_trajectory(traj_dir, name, "rgbd_odometry", p->T_world_cam);
    std::snprintf(line, sizeof(line), "speedup_vs_rgbd_odometry_%s=%.2f", name.c_str(),
                  mean(ms) > 0 ? mean(p->frame_ms) / mean(ms) : 0.0);
    keys.push_back(line);
#else
    std::printf("%-9s %-16s (OpenCV rgbd module not built in)\n", name.c_str(), "RgbdOdometry");
#endif
  }
  std::printf("paper (Jetson AGX, Table I): 162.4 +- 19.1 ms per frame; ORB-SLAM3 158.2; VINS-RGBD 56.0\n");
  for (const auto& k : keys) std::printf("%s\n", k.c_str());
  std::printf("frame_ms_mean=%.3f\n", mean(all_ms));
  std::printf("frame_ms_p99=%.3f\n", percentile(all_ms, 0.99));
  std::printf("local_ba_ms_mean=%.3f\n", mean(all_ba_ms));
  // Steady-state frames that make no keyframe, after warm-up. OpenCV's ORB (inside the extraction
  // stage) is counted apart: it is the one stage that still allocates.
  std::printf("allocs_per_frame=%.2f\n",
              steady_frames ? static_cast<double>(steady_allocs) / static_cast<double>(steady_frames) : 0.0);
  std::printf(
      "allocs_per_frame_opencv_orb=%.2f\n",
      steady_frames ? static_cast<double>(steady_orb_allocs) / static_cast<double>(steady_frames) : 0.0);
  return 0;
}

}  // namespace

HWR_BENCH_COMMAND(
    frame, "frame",
    "pose-estimation pipeline per frame (time, ATE, allocations) beside OpenCV RgbdOdometry "
    "[--sequences teddy,lab,outdoor] [--duration S] [--no-peer] [--config FILE] [--traj-out DIR]",
    run_frame);

}  // namespace hwr::bench
