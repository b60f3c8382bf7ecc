#pragma once
// Fusion of one seam's detections over keyframes (issue #7: "seam endpoint error ... after fusing
// several keyframes"). Detections in the world frame that match a track (same kind, within
// match.max_angle_rad of its line, both ends within match.max_lateral_m of it, overlapping or
// touching its extent) join it; a track's line is the mean of its detections' midpoints along their
// mean direction, its extent the union of theirs, and each of its ends the median of the detected
// ends that a keyframe saw (Detection::end_observed): an end cut by the image border only widens the
// extent. A fused seam is a track of at least min_detections detections of which at least one is
// confident (not Detection::support_only: supporting detections count only towards a seam a confident
// one found); an end no keyframe saw is the extent's and unknown. When the table is full, a track with
// no confident detection makes room for a new one (the one that grew longest ago): the table stays
// bounded however many supporting detections a long run brings, and keeps every confirmed seam.

#include <array>
#include <cstdint>
#include <vector>

#include "hwr/detect/detection.hpp"
#include "hwr/detect/seam_metrics.hpp"

namespace hwr::detect {

struct SeamFusionConfig {
  SeamMatchConfig match;
  int min_detections = 2;  // a seam seen once is not reported
  int max_tracks = 256;    // tracks with a confident detection are kept; the others may be replaced
  // Seen ends kept per end of a track (the medians are of the first ones): bounded memory however long
  // the robot runs (at most max_tracks * 2 * this doubles).
  int max_ends_per_track = 1024;
};

struct FusedSeam {
  SeamSegment seam;  // world; end_known: some keyframe saw that end
  int detections = 0;
};

class SeamFusion {
 public:
  explicit SeamFusion(const SeamFusionConfig& config = {});
  // Adds a detection (its world members). False when it matched no track and the table is full of
  // tracks with a confident detection.
  bool add(const Detection& d);
  std::vector<FusedSeam> fused() const;
  int tracks() const { return static_cast<int>(tracks_.size()); }

 private:
  struct Track {
    SeamKind kind = SeamKind::kFillet;
    Eigen::Vector3d mid_sum = Eigen::Vector3d::Zero(), dir_sum = Eigen::Vector3d::Zero();
    int n = 0;
    int confident = 0;          // detections that are not support_only
    uint64_t grew = 0;          // when a detection last joined (add() calls)
    double t_lo = 0, t_hi = 0;  // extent along the line, from its point (the first detection's midpoint)
    Eigen::Vector3d origin = Eigen::Vector3d::Zero(), axis = Eigen::Vector3d::UnitX();  // the first's
    std::vector<double> ends_lo, ends_hi;  // observed ends along the axis
  };
  SeamFusionConfig config_;
  std::vector<Track> tracks_;
  uint64_t added_ = 0;  // add() calls
};

}  // namespace hwr::detect
