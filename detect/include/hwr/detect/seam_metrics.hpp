#pragma once
// Scoring detected seams against the truth (issue #7 acceptance: seam precision and recall, endpoint
// error). A detection matches a true seam of its kind when the two are within max_angle_rad, both
// detected ends lie within max_lateral_m of the true line, and they overlap along it by min_overlap of
// the shorter; matches are one to one, the largest overlaps first. precision = matched detections /
// detections, recall = matched truths / truths. Endpoint errors are taken only between ends known on
// both sides: a detected end the detector saw (Detection::end_observed) and a true end in view.

#include <array>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "hwr/detect/depth_noise.hpp"
#include "hwr/detect/detection.hpp"
#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::detect {

struct SeamSegment {
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();  // world, metres
  SeamKind kind = SeamKind::kFillet;
  std::array<bool, 2> end_known{true, true};
  // A fillet's seam is in view only from its open side (the base's side of the web): a camera at c
  // sees it only when (c - a) . open_side > 0. Zero: from any side (a butt).
  Eigen::Vector3d open_side = Eigen::Vector3d::Zero();
};

SeamSegment seam_of(const Detection& d);  // seam_world, kind, end_observed

// Distance of p from the line through a along the unit direction u (metres).
double distance_to_line_m(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& u);

struct SeamMatchConfig {
  double max_angle_rad = 0.175;  // 10 deg
  double max_lateral_m = 0.02;
  double min_overlap = 0.5;
};

struct SeamMatch {
  int detected = -1, truth = -1;
  double lateral_m = 0;                    // the larger distance of the detected ends to the true line
  std::array<double, 2> endpoint_m{0, 0};  // detected end k against the true end it pairs with
  std::array<bool, 2> endpoint_valid{false, false};
};

struct SeamScore {
  int detections = 0, truths = 0, matched = 0;
  std::vector<SeamMatch> matches;
  double precision() const { return detections > 0 ? static_cast<double>(matched) / detections : 1.0; }
  double recall() const { return truths > 0 ? static_cast<double>(matched) / truths : 1.0; }
};

SeamScore score_seams(const std::vector<SeamSegment>& detected, const std::vector<SeamSegment>& truth,
                      const SeamMatchConfig& config = {});

// The part of a true seam a camera sees: its samples (every 5 mm) in front of the camera within
// [min_range_m, max_range_m], projecting at least 5 px inside the image, from its open side, and not
// hidden (the depth image at the sample no nearer than the sample by more than 2 sigma(z) + 3 mm).
// *out spans the first to the last such sample; an end is known when its own sample is seen. False
// when under min_length_m of it is seen.
bool visible_seam_part(const SeamSegment& truth_world, const Eigen::Isometry3d& T_world_cam,
                       const hal::PinholeIntrinsics& K, const cv::Mat& depth_m, const DepthNoiseModel& noise,
                       double min_range_m, double max_range_m, double min_length_m, SeamSegment* out);

}  // namespace hwr::detect
