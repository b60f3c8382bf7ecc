#pragma once
// Renders and writes one simulated run in TUM RGB-D layout plus EuRoC-style sensor files
// (docs/simulator.md lists every file and column):
//   rgb/<t>.png, depth/<t>.png, [right/<t>.png], rgb.txt, depth.txt, [right.txt],
//   groundtruth.txt (T_world_cam at IMU rate), imu.csv, imu_state_groundtruth.csv, mag.csv,
//   [gnss.csv], calibration.yaml, weld_groundtruth.yaml, scenario_resolved.yaml
// Frame k's noise is seeded by (scenario seed, k), so any number of render threads gives
// byte-identical files. Every file is written under a temporary name and renamed when complete.

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/sim/scenario.hpp"

namespace hwr::sim {

struct RunOptions {
  std::string out_dir;
  double duration_s = 0.0;   // > 0 overrides the scenario's duration
  int threads = 1;           // render threads
  bool write_images = true;  // false: sensor streams, ground truth and calibration only
};

struct RunSummary {
  std::string scenario;
  std::string out_dir;
  size_t frames = 0;
  size_t imu_samples = 0;
  size_t mag_samples = 0;
  size_t gnss_samples = 0;
  double simulated_s = 0.0;
  double path_length_m = 0.0;  // floor path walked within the simulated time
  size_t joints = 0;
  std::vector<std::string> files;  // top-level files and folders written, relative to out_dir
};

// Called from the calling thread with frames done so far (also once at the end).
using RunProgress = std::function<void(size_t frames_done, size_t frames_total)>;

// Errors: scenario validation (trajectory, scene), an output folder that cannot be created or
// written (IoError naming the path), renderer failures.
core::Expected<RunSummary> write_run(const ScenarioSpec& spec, const RunOptions& options,
                                     const RunProgress& progress = {});

// The text of weld_groundtruth.yaml (docs/simulator.md): the scenario's plates and seams in the
// world frame of a run (T_world_scene = calibration's T_scene_world^-1). recon::parse_weld_groundtruth
// reads it.
std::string weld_groundtruth_yaml(const ScenarioSpec& spec, const Eigen::Isometry3d& T_world_scene);

// 16-bit depth image of a metric one: raw = round(depth_m * depth_scale); 0 stays 0 (invalid) and
// so does anything that does not fit in 16 bits (rather than clamping to a wrong depth).
void depth_to_u16(const cv::Mat& depth_m, double depth_scale, cv::Mat* depth_u16);

}  // namespace hwr::sim
