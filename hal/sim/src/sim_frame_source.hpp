#pragma once
// Private to hwr_sim: what a simulated run is made of, computed rather than read: the validated
// scenario and its walk, the world frame, every sensor stream with its ground truth, and frame
// k's images. write_run (run_writer.hpp) stores these in files; open_sim_live_log
// (sim_live_log.hpp) hands them to the replay directly. Both call the same functions, so a live
// frame is the written frame before file quantisation.

#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "hwr/core/status.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/hal/mag_sample.hpp"
#include "hwr/sim/gnss_synth.hpp"
#include "hwr/sim/imu_synth.hpp"
#include "hwr/sim/renderer.hpp"
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/trajectory.hpp"

namespace hwr::sim {

// A scenario ready to simulate. Immutable after prepare_sim_run: frames may be rendered from
// several threads at once.
struct SimRunSetup {
  ScenarioSpec spec;  // duration override applied
  Trajectory trajectory;
  double duration_s = 0.0;  // simulated run length
  int64_t t0_ns = 0;        // time stamp of the first sample of every stream
  Eigen::Isometry3d T_scene_world = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_scene = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_imu_cam = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_cam_right = Eigen::Isometry3d::Identity();
  std::vector<int64_t> frame_offsets_ns;  // camera instants from t0 (sample_times.hpp)
};

// Validates the scenario and builds its walk; duration_s > 0 cuts the run (hwr-sim --duration).
// Errors are the ones hwr-sim prints: validate_scenario's, and "scenario '<name>': <why>" for the
// trajectory.
core::Expected<SimRunSetup> prepare_sim_run(const ScenarioSpec& spec, double duration_s);

// The Embree scene of the run; errors "scenario '<name>': <why>".
core::Expected<std::unique_ptr<Renderer>> create_sim_renderer(const SimRunSetup& run);

struct SimGroundTruthRow {
  int64_t t_ns = 0;
  Eigen::Isometry3d T_world_imu = Eigen::Isometry3d::Identity();
  Eigen::Vector3d v_world_mps = Eigen::Vector3d::Zero();
};

// Every non-image stream of the run, exactly as the files hold them before printing.
struct SimStreams {
  std::vector<ImuRecord> imu;
  std::vector<SimGroundTruthRow> groundtruth_imu;          // at the IMU instants
  std::vector<core::StampedPose> groundtruth_T_world_cam;  // at the IMU instants
  std::vector<hal::MagSample> mag;                         // empty when the scenario has none
  std::vector<GnssRecord> gnss;                            // empty when the scenario has none
};

SimStreams synthesize_sim_streams(const SimRunSetup& run);

// Pose of the (left) camera at run time offset_ns.
Eigen::Isometry3d sim_T_scene_cam(const SimRunSetup& run, int64_t offset_ns);

// Renders frame k (k < frame_offsets_ns.size()) with the sensor effects: depth noise keyed by
// (seed, k), exposure gain of the frame's time and pixel noise keyed by (seed, k). bgr CV_8UC3,
// depth_m CV_32FC1 (metric, before quantisation). Stereo scenarios also fill right_gray
// (CV_8UC1) through right_bgr (caller scratch); both are untouched otherwise. Buffers are
// reallocated only when their size or type differs. Thread-safe for distinct buffers.
void render_sim_frame(const SimRunSetup& run, const Renderer& renderer, size_t k, cv::Mat* bgr,
                      cv::Mat* depth_m, cv::Mat* right_bgr, cv::Mat* right_gray);

// The 16-bit value a depth file stores for depth_m: round(depth_m * depth_scale), 0 when that is
// not in 1..65535 (no measurement, or too far for 16 bits: invalid rather than clamped).
inline uint16_t depth_raw_u16(float depth_m, double depth_scale) {
  const double raw = std::round(static_cast<double>(depth_m) * depth_scale);
  return (raw > 0.0 && raw <= 65535.0) ? static_cast<uint16_t>(raw) : 0;
}

// Sets to 0 the pixels whose depth a 16-bit file could not store (depth_raw_u16 == 0), so a live
// frame and the frame read back from the files are invalid at the same pixels. Returns the
// number of invalid pixels.
uint32_t invalidate_unstorable_depth(double depth_scale, cv::Mat* depth_m);

}  // namespace hwr::sim
