#pragma once
// Test helper: frames of a simulator scenario rendered live (colour, depth, ground-truth camera pose),
// and a stored keyframe record made from ORB features, for tests that build prior maps.
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "hwr/estimation/frame_features.hpp"
#include "hwr/hal/rgbd_frame.hpp"
#include "hwr/recon/map_store.hpp"
#include "hwr/recon/voxel_map.hpp"
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/sim_live_log.hpp"

namespace hwr::testing {

// Calls fn(frame index, frame, T_world_cam truth, intrinsics) for frames first, first + step, ...
// below last of the scenario. Fails the test when the scenario or a frame cannot be made.
inline void for_each_sim_frame(
    const std::string& scenario, size_t first, size_t last, size_t step,
    const std::function<void(size_t, const hal::RgbdFrame&, const Eigen::Isometry3d&,
                             const hal::PinholeIntrinsics&)>& fn) {
  auto spec = sim::load_scenario(scenario);
  ASSERT_TRUE(spec.ok()) << spec.status().message();
  auto live = sim::open_sim_live_log(spec.value(), static_cast<double>(last + 10) / spec->camera.rate_hz);
  ASSERT_TRUE(live.ok()) << live.status().message();
  const hal::PinholeIntrinsics K = live->log.info.intrinsics;
  hal::RgbdFrame f;
  f.bgr.create(K.height, K.width, CV_8UC3);
  f.depth_m.create(K.height, K.width, CV_32FC1);
  for (size_t i = first; i < last; i += step) {
    ASSERT_LT(i, live->log.frame_t_ns.size());
    ASSERT_TRUE(live->log.load_frame(i, &f).ok());
    fn(i, f, live->groundtruth_T_world_cam_at_frames[i].T_world_body, K);
  }
}

// A stored keyframe of the features at T_world_cam.
inline recon::StoredKeyframe stored_keyframe(const estimation::FrameFeatures& features,
                                             const Eigen::Isometry3d& T_world_cam, int32_t id, int64_t t_ns) {
  recon::StoredKeyframe s;
  s.id = id;
  s.t_ns = t_ns;
  s.T_world_cam = T_world_cam;
  for (int k = 0; k < features.size(); ++k) {
    const estimation::Feature& ft = features.feature(k);
    s.features.push_back({ft.u_px, ft.v_px, ft.depth_m, static_cast<uint8_t>(ft.octave)});
    s.descriptors.insert(s.descriptors.end(), features.descriptor(k), features.descriptor(k) + 32);
  }
  return s;
}

// The voxel means of `map` appended to `out` as points (colour and flags zero).
inline void append_voxel_points(const recon::VoxelMap& map, std::vector<recon::CloudPoint>* out) {
  map.for_each([&](const recon::Voxel& v) {
    recon::CloudPoint p;
    p.x_m = v.x_m;
    p.y_m = v.y_m;
    p.z_m = v.z_m;
    out->push_back(p);
  });
}

}  // namespace hwr::testing
