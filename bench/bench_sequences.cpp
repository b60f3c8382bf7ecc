#include "bench_sequences.hpp"

#if HWR_WITH_SIM
#include "hwr/sim/renderer.hpp"
#include "hwr/sim/run_writer.hpp"
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/sim_live_log.hpp"
#endif

namespace hwr::bench {
namespace {
const std::string kTeddy = HWR_DATA_DIR "/tum-fr3-teddy-200/rgbd_dataset_freiburg3_teddy";
}  // namespace

core::Expected<Sequence> open_sequence(const std::string& name, double duration_s,
                                       const SimRendering& rendering) {
  Sequence s;
  s.name = name;
  if (name == "teddy") {
    auto log = hal::open_dataset_log("tum:" + kTeddy);
    if (!log.ok()) return log.status();
    s.log = std::move(log.value());
    auto gt = core::read_tum_trajectory(kTeddy + "/groundtruth.txt");
    if (!gt.ok()) return gt.status();
    s.groundtruth = std::move(gt.value());
    return s;
  }
#if HWR_WITH_SIM
  auto spec = sim::load_scenario(name);
  if (!spec.ok()) return spec.status();
  spec->render.area_sampling = spec->render.area_sampling || rendering.area_sampling;
  spec->render.shadows = spec->render.shadows || rendering.shadows;
  if (rendering.ambient_occlusion_rays > 0)
    spec->render.ambient_occlusion_rays = rendering.ambient_occlusion_rays;
  auto live = sim::open_sim_live_log(spec.value(), duration_s);
  if (!live.ok()) return live.status();
  s.log = std::move(live->log);
  s.groundtruth = std::move(live->groundtruth_T_world_cam_at_frames);
  s.path_length_m = live->path_length_m;
  // Scene-frame truth moved into the run's world frame (what hwr-sim writes to weld_groundtruth.yaml).
  const Eigen::Isometry3d T_world_scene = live->calibration.T_scene_world.inverse();
  s.weld_truth_yaml = sim::weld_groundtruth_yaml(spec.value(), T_world_scene);
  s.weld_truth_world = sim::scene_ground_truth(spec->scene);
  for (auto& p : s.weld_truth_world.plates) {
    p.T_scene_plate = T_world_scene * p.T_scene_plate;
    for (auto& c : p.corners_scene) c = T_world_scene * c;
  }
  for (auto& seam : s.weld_truth_world.seams) {
    seam.start_scene = T_world_scene * seam.start_scene;
    seam.end_scene = T_world_scene * seam.end_scene;
  }
  return s;
#else
  (void)duration_s;
  (void)rendering;
  return core::Unavailable("sequence " + name + ": this build has no simulator");
#endif
}

}  // namespace hwr::bench
