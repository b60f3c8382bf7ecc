#pragma once
// A scenario simulated on the fly as a replay log (`hwr-robot --source sim:lab`,
// `sim:FILE.yaml`): the same run hwr-sim would write (run_writer.hpp), without the files. The
// IMU, magnetometer and GNSS samples and the ground truth are synthesized when the log is opened
// (seconds for a whole walk); each camera frame is rendered when the replay's prefetch thread
// asks for it (hal::ReplaySource), so the pipeline starts at once and nothing is written.
//
//   auto spec = load_scenario("lab");                    // preset name or YAML file
//   auto live = open_sim_live_log(spec.value(), 60.0);   // the first 60 s
//   hal::SensorStreamsConfig cfg;  cfg.stereo = live->log.info.stereo;  ...
//   auto src = hal::ReplaySource::create(std::move(live->log), &streams);
//
// Frame k equals the written frame k: the same colour image (exactly), the same right image
// (gray, stereo scenarios), and the same depth before 16-bit quantisation: within
// 1/depth_scale metres, and invalid (0) at exactly the pixels the depth PNG holds 0.
// Samples are the written CSVs' before printing; t_ns, seq (= k) and intrinsics as in the files.

#include <memory>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/hal/replay_source.hpp"
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/sim_calibration.hpp"

namespace hwr::sim {

struct SimLiveLog {
  // info: name "sim-live:<scenario>", intrinsics, T_imu_cam, rates, has_imu/mag/gnss, stereo,
  // first/last sample time; the sample vectors; frame_t_ns; load_frame renders frame i (called
  // on the replay's prefetch thread; it holds the renderer and its scratch, and a copy of the
  // log shares them behind a mutex).
  hal::ReplayLog log;
  SimCalibration calibration;  // what hwr-sim writes to calibration.yaml
  // T_world_cam at the IMU instants (groundtruth.txt) and exactly at frame_t_ns.
  std::vector<core::StampedPose> groundtruth_T_world_cam;
  std::vector<core::StampedPose> groundtruth_T_world_cam_at_frames;
  double path_length_m = 0;  // floor path walked within the simulated time
};

// spec: from load_scenario(name_or_path). duration_s > 0 cuts the run (hwr-sim --duration), 0
// simulates the whole scenario. Errors are hwr-sim's for the same scenario (validation, the walk,
// the scene, each naming the scenario or field), and InvalidArgument for a negative or
// non-finite duration_s.
core::Expected<SimLiveLog> open_sim_live_log(const ScenarioSpec& spec, double duration_s = 0);

}  // namespace hwr::sim
