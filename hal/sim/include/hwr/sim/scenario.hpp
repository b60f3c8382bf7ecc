#pragma once
// A simulation scenario: the scene, the walk through it, and every sensor's parameters. Built-in
// presets (`lab`, `outdoor`, `lab-revisit`, `outdoor-revisit`) are plain C++ (scenario.cpp);
// a YAML file names a preset with `base:` and overrides any field (nested maps merge field by
// field, lists replace), read strictly through core::ConfigDocument: unknown keys and wrong
// types are errors naming file:line and the dotted key. scenario_to_yaml() writes every
// effective parameter in the same layout, and that file loads back to the same scenario.
//
// Frames (docs/simulator.md): scene = ENU (x east, y north, z up) at the geodetic origin;
// imu = body x forward, y left, z up; cam = OpenCV (x right, y down, z forward);
// world = gravity-aligned frame at the first IMU pose (sim_calibration.hpp).

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/sim/camera_effects.hpp"
#include "hwr/sim/gnss_synth.hpp"
#include "hwr/sim/imu_synth.hpp"
#include "hwr/sim/mag_synth.hpp"
#include "hwr/sim/renderer.hpp"
#include "hwr/sim/scene_spec.hpp"
#include "hwr/sim/trajectory.hpp"

namespace hwr::sim {

struct CameraSpec {
  hal::PinholeIntrinsics intrinsics = default_intrinsics();
  double rate_hz = 30.0;
  // Mount on the IMU: translation in the IMU frame and angles relative to a level camera looking
  // along the IMU x axis (pitch_down tilts the optical axis towards the floor, so benches and
  // floor joints in front of the robot are in view).
  Eigen::Vector3d t_imu_cam_m{0.10, 0.0, 0.30};
  double pitch_down_deg = 18.0;
  double yaw_left_deg = 0.0;
  double roll_deg = 0.0;
  // Raw 16-bit depth units per metre: 5000 indoors (TUM), 1000 outdoors (20 m fits in 16 bits).
  double depth_scale = 5000.0;
  bool stereo = false;       // also render a right image (rectified pair, same intrinsics)
  double baseline_m = 0.12;  // right camera at +baseline along the left camera's x axis

  static hal::PinholeIntrinsics default_intrinsics() {
    hal::PinholeIntrinsics k;
    k.width = 640;
    k.height = 480;
    k.fx = k.fy = 525.0;
    k.cx = 319.5;
    k.cy = 239.5;
    return k;
  }
};

// T_imu_cam of the mount: R = Rz(yaw_left) Ry(pitch_down) Rx(roll) * R_level, where R_level
// takes OpenCV camera axes to the IMU's (z_cam = x_imu, x_cam = -y_imu, y_cam = -z_imu).
Eigen::Isometry3d camera_T_imu_cam(const CameraSpec& camera);
// The right camera of the stereo pair in the left camera's frame (pure +x translation).
Eigen::Isometry3d camera_T_cam_right(const CameraSpec& camera);

// From time_s on, the colour gain is `gain` (an exposure step), until the next event.
struct ExposureEvent {
  double time_s = 0.0;
  double gain = 1.0;
};

struct ScenarioSpec {
  std::string name;
  std::string base;   // preset it derives from (written to scenario_resolved.yaml)
  uint64_t seed = 1;  // sensor noise, magnetic disturbers, GNSS dropouts, image noise
  int64_t start_time_ns = 1'700'000'000'000'000'000;  // time stamp of the first sample
  double duration_s = 0.0;                            // > 0: stop the run early; 0: the whole trajectory
  SceneSpec scene;
  TrajectorySpec trajectory;
  CameraSpec camera;
  DepthNoiseSpec depth_noise;
  ExposureSpec exposure;  // base gain and pixel noise
  std::vector<ExposureEvent> exposure_events;
  RenderOptions render;
  ImuSpec imu;
  MagSpec mag;
  GnssSpec gnss;
};

std::vector<std::string> builtin_scenario_names();
// NotFound naming the known presets when `name` is not one.
core::Expected<ScenarioSpec> builtin_scenario(const std::string& name);

// YAML text -> scenario. `base: <preset>` starts from a preset (otherwise from defaults with an
// empty scene and no waypoints); every key given overrides. source_name appears in messages.
core::Expected<ScenarioSpec> parse_scenario_yaml(const std::string& yaml_text,
                                                 const std::string& source_name);
core::Expected<ScenarioSpec> load_scenario_file(const std::string& path);
// A preset name, or a path to a .yaml/.yml file.
core::Expected<ScenarioSpec> load_scenario(const std::string& name_or_path);
// Every effective parameter, loadable with parse_scenario_yaml().
std::string scenario_to_yaml(const ScenarioSpec& spec);

// Range and consistency checks beyond types (rates > 0, image size, depth scale, ...), naming
// the field. The trajectory and the scene have their own checks (Trajectory::build, Renderer).
core::Status validate_scenario(const ScenarioSpec& spec);

// Colour gain in effect at run time t_s (base gain until the first event).
double exposure_gain_at(const ScenarioSpec& spec, double t_s);
// Run length: duration_s if > 0, else the trajectory's.
double scenario_run_duration_s(const ScenarioSpec& spec, const Trajectory& trajectory);

}  // namespace hwr::sim
