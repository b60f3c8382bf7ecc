#include "sim_frame_source.hpp"

#include <utility>

#include <opencv2/imgproc.hpp>

#include "hwr/core/time.hpp"
#include "hwr/sim/camera_effects.hpp"
#include "hwr/sim/mag_synth.hpp"
#include "hwr/sim/random.hpp"
#include "hwr/sim/sample_times.hpp"
#include "hwr/sim/world_frame.hpp"

namespace hwr::sim {

core::Expected<SimRunSetup> prepare_sim_run(const ScenarioSpec& spec, double duration_s) {
  SimRunSetup run;
  run.spec = spec;
  if (duration_s > 0.0) run.spec.duration_s = duration_s;
  HWR_RETURN_IF_ERROR(validate_scenario(run.spec));
  auto traj = Trajectory::build(run.spec.trajectory);
  if (!traj.ok())
    return core::InvalidArgument("scenario '" + run.spec.name + "': " + traj.status().message());
  run.trajectory = std::move(traj.value());
  run.duration_s = scenario_run_duration_s(run.spec, run.trajectory);
  run.t0_ns = run.spec.start_time_ns;
  run.T_scene_world = world_frame_from_first_imu_pose(run.trajectory.evaluate(0.0).T_scene_imu);
  run.T_world_scene = run.T_scene_world.inverse();
  run.T_imu_cam = camera_T_imu_cam(run.spec.camera);
  run.T_cam_right = camera_T_cam_right(run.spec.camera);
  run.frame_offsets_ns = sample_offsets_ns(run.spec.camera.rate_hz, run.duration_s);
  return run;
}

core::Expected<std::unique_ptr<Renderer>> create_sim_renderer(const SimRunSetup& run) {
  auto r = Renderer::create(run.spec.scene);
  if (!r.ok()) return core::InvalidArgument("scenario '" + run.spec.name + "': " + r.status().message());
  return std::move(r.value());
}

SimStreams synthesize_sim_streams(const SimRunSetup& run) {
  const ScenarioSpec& spec = run.spec;
  SimStreams s;
  s.imu = synthesize_imu(run.trajectory, spec.imu, spec.seed, run.duration_s, run.t0_ns);
  s.groundtruth_imu.resize(s.imu.size());
  s.groundtruth_T_world_cam.resize(s.imu.size());
  for (size_t k = 0; k < s.imu.size(); ++k) {
    const TrajectoryState st = run.trajectory.evaluate(core::ns_to_s(s.imu[k].sample.t_ns - run.t0_ns));
    SimGroundTruthRow& gt = s.groundtruth_imu[k];
    gt.t_ns = s.imu[k].sample.t_ns;
    gt.T_world_imu = run.T_world_scene * st.T_scene_imu;
    gt.v_world_mps = run.T_world_scene.linear() * st.v_scene_mps;
    s.groundtruth_T_world_cam[k].t_ns = gt.t_ns;
    s.groundtruth_T_world_cam[k].T_world_body = gt.T_world_imu * run.T_imu_cam;
  }
  if (spec.mag.enabled) {
    const std::vector<MagDipole> dipoles = mag_dipoles_for_scene(spec.scene, spec.mag, spec.seed);
    s.mag = synthesize_mag(run.trajectory, spec.mag, dipoles, spec.seed, run.duration_s, run.t0_ns);
  }
  if (spec.gnss.enabled)
    s.gnss = synthesize_gnss(run.trajectory, spec.gnss, spec.seed, run.duration_s, run.t0_ns);
  return s;
}

Eigen::Isometry3d sim_T_scene_cam(const SimRunSetup& run, int64_t offset_ns) {
  return run.trajectory.evaluate(core::ns_to_s(offset_ns)).T_scene_imu * run.T_imu_cam;
}

void render_sim_frame(const SimRunSetup& run, const Renderer& renderer, size_t k, cv::Mat* bgr,
                      cv::Mat* depth_m, cv::Mat* right_bgr, cv::Mat* right_gray) {
  const ScenarioSpec& spec = run.spec;
  const double t_s = core::ns_to_s(run.frame_offsets_ns[k]);
  const Eigen::Isometry3d T_scene_cam = sim_T_scene_cam(run, run.frame_offsets_ns[k]);
  renderer.render(T_scene_cam, spec.camera.intrinsics, spec.render, bgr, depth_m);
  apply_depth_noise(spec.depth_noise, derive_seed(spec.seed, RandomStream::kDepthNoise, k), depth_m);
  ExposureSpec exposure = spec.exposure;
  exposure.gain = exposure_gain_at(spec, t_s);
  apply_exposure(exposure, derive_seed(spec.seed, RandomStream::kExposure, k), bgr);
  if (!spec.camera.stereo) return;
  // The right camera has its own pixel noise; its depth is not a sensor output.
  renderer.render(T_scene_cam * run.T_cam_right, spec.camera.intrinsics, spec.render, right_bgr, nullptr);
  apply_exposure(exposure, derive_seed(spec.seed, RandomStream::kExposureRight, k), right_bgr);
  cv::cvtColor(*right_bgr, *right_gray, cv::COLOR_BGR2GRAY);
}

uint32_t invalidate_unstorable_depth(double depth_scale, cv::Mat* depth_m) {
  uint32_t invalid = 0;
  for (int r = 0; r < depth_m->rows; ++r) {
    float* d = depth_m->ptr<float>(r);
    for (int c = 0; c < depth_m->cols; ++c) {
      if (depth_raw_u16(d[c], depth_scale) == 0) {
        d[c] = 0.0f;
        ++invalid;
      }
    }
  }
  return invalid;
}

}  // namespace hwr::sim
