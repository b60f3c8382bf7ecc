#pragma once
// `hwr-bench paper`'s trajectory plots (issue #9 item 3; the paper's Fig. 3): the top view (world
// x-y, metres; the simulator's world is z up) of each estimate, aligned to the ground truth as its ATE
// aligns it (SE(3), hwr-eval's definition), drawn over the ground truth, one PNG per sequence, with
// OpenCV's drawing functions.

#include <string>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/core/tum_trajectory.hpp"

namespace hwr::bench::paper {

struct PlotTrack {
  std::string label;  // legend text, ASCII (OpenCV's Hershey fonts)
  std::vector<core::StampedPose> poses;
  int bgr[3] = {0, 0, 0};
  bool thick = false;  // drawn wider (the ground truth, under the estimates)
};

// Writes a PNG (width x height pixels) with equal scales on both axes, a grid with ticks at 1, 2 or 5
// x 10^k m, the axes labelled "x [m]" / "y [m]", the title, a legend, and each track's start (circle)
// and end (square).
core::Status write_trajectory_png(const std::string& path, const std::string& title,
                                  const std::vector<PlotTrack>& tracks, int width = 1100, int height = 900);

// The estimate moved into the ground truth's frame by the rigid alignment of its ATE
// (estimation::compute_ate, default options), and the ATE RMSE of that alignment.
struct AlignedTrack {
  std::vector<core::StampedPose> poses;
  double ate_rmse_m = 0;
  size_t pairs = 0;
};
core::Expected<AlignedTrack> align_to_groundtruth(const std::vector<core::StampedPose>& groundtruth,
                                                  const std::vector<core::StampedPose>& estimate);

// The ground-truth poses within [first, last] time of the estimate (a dataset's ground truth may cover
// a longer sequence than the frames run).
std::vector<core::StampedPose> groundtruth_span(const std::vector<core::StampedPose>& groundtruth,
                                                const std::vector<core::StampedPose>& estimate);

}  // namespace hwr::bench::paper
