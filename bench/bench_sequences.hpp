#pragma once
// The sequences the pipeline benches run on: `teddy` (TUM fr3/teddy, 200 frames, from
// ../shared/data) and any simulator scenario by name (`lab`, `outdoor`, or a scenario YAML),
// rendered live. Sim sequences also carry the weld work pieces' ground truth in the run's world frame.

#include <string>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/hal/replay_source.hpp"
#if HWR_WITH_SIM
#include "hwr/sim/scene_spec.hpp"
#endif

namespace hwr::bench {

struct Sequence {
  std::string name;
  hal::ReplayLog log;
  std::vector<core::StampedPose> groundtruth;  // T_world_cam (at the frame times for sim)
  double path_length_m = 0;
#if HWR_WITH_SIM
  sim::SceneGroundTruth weld_truth_world;  // plates and seams in the run's world frame
  std::string weld_truth_yaml;             // the same as hwr-sim's weld_groundtruth.yaml
#endif
};

// How a sim sequence's colour is rendered, on top of its scenario's render options: area_sampling and
// shadows switch those on (a scenario's own are kept), ambient_occlusion_rays > 0 replaces the
// scenario's ray count (sim::RenderOptions; the presets have all three off).
struct SimRendering {
  bool area_sampling = false;
  bool shadows = false;
  int ambient_occlusion_rays = 0;
};

// duration_s > 0 cuts a sim sequence (hwr-sim --duration). Both it and `rendering` are ignored for
// teddy.
core::Expected<Sequence> open_sequence(const std::string& name, double duration_s,
                                       const SimRendering& rendering = {});

}  // namespace hwr::bench
