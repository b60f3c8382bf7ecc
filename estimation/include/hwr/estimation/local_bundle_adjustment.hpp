#pragma once
// Sliding-window and full bundle adjustment over the tracker's keyframes and map points (paper
// eq. 5; issue #3 item 6). Builds a BaProblem from the newest `window_keyframes` keyframes (free,
// except the oldest window pose, which fixes the gauge), the older keyframes in the ring that
// observe the same points (held fixed, so the window stays attached to the map behind it), and
// every map point the window observes; solves it with the hand-written SparseBundleAdjuster; writes
// poses and points back; drops observations that are still outliers and, if there were any, solves
// once more without them.
// Problem storage and the solver workspace are allocated once, from the capacities.

#include <cstdint>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/estimation/ba_problem.hpp"
#include "hwr/estimation/ba_solver.hpp"
#include "hwr/estimation/keyframe_store.hpp"
#include "hwr/estimation/map_point_store.hpp"
#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::estimation {

struct LocalBaConfig {
  int window_keyframes = 8;
  int fixed_keyframes = 8;  // older keyframes observing window points, held fixed
  int max_points = 12'000;
  int max_observations = 120'000;
  BaOptions options;            // max_iterations etc.
  double outlier_chi2 = 5.991;  // 2-dof 95 %: observations above this (in sigma²) are dropped
  double max_depth_m = 40.0;    // points behind the camera or beyond this are dropped
};

struct LocalBaReport {
  BaSummary summary;
  int cameras = 0;
  int fixed_cameras = 0;
  int points = 0;
  int observations = 0;
  int observations_removed = 0;
  int points_removed = 0;
};

class LocalBundleAdjustment {
 public:
  LocalBundleAdjustment(const LocalBaConfig& config, int map_point_capacity);

  // Window ending at the newest keyframe. full = true: every keyframe in the ring, only the
  // oldest fixed (the end-of-run full BA; may allocate when the problem exceeds the window's
  // capacity — it builds its own solver then).
  core::Expected<LocalBaReport> run(KeyframeStore* keyframes, MapPointStore* points,
                                    const hal::PinholeIntrinsics& K, bool full = false);

  // The problem run() would solve next, built without solving or changing the stores (report
  // gets the counts; summary stays empty). For exporting the bundle adjustments of real runs
  // (hwr-robot --ba-export, hwr-bench ba). Valid until the next call.
  const BaProblem& build_problem(const KeyframeStore& keyframes, const MapPointStore& points,
                                 const hal::PinholeIntrinsics& K, bool full, LocalBaReport* report);

 private:
  core::Expected<LocalBaReport> run_once(KeyframeStore* keyframes, MapPointStore* points,
                                         const hal::PinholeIntrinsics& K, bool full);
  bool add_point(const MapPointStore& points, MapPointHandle h, int* ba_index);

  LocalBaConfig config_;
  BaProblem problem_;
  SparseBundleAdjuster solver_;
  std::vector<int32_t> point_to_ba_;      // map point slot → BaProblem point index (-1: not in)
  std::vector<int32_t> ba_to_point_;      // BaProblem point index → map point slot
  std::vector<int32_t> camera_keyframe_;  // BaProblem camera → keyframe id
  struct ObservationRef {
    int32_t keyframe_id;
    int32_t feature;
  };
  std::vector<ObservationRef> observation_ref_;
};

}  // namespace hwr::estimation
