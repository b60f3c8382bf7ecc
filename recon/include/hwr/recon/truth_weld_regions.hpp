#pragma once
// The simulator's weld joints as a perfect detector would report them on a keyframe: one oriented
// box per joint around its plates, as a WeldRegion of source kSimTruth in the keyframe's camera
// frame. Until the detectors of issue #7 exist, these stand in for detections so that the fine
// cloud of the welding regions (fine_region_map.hpp) and its reconstruction error (region_ae.hpp)
// can be measured on the real pipeline (hwr-robot --regions truth, hwr-bench segmentation). The
// robot places each box with the keyframe's *estimated* pose, exactly as it will place a detector's
// output: only the detection is perfect, not the map.

#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/core/tum_trajectory.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/recon/plate_fit.hpp"
#include "hwr/recon/weld_region.hpp"

namespace hwr::recon {

struct TruthJointBox {
  std::string joint;                                              // the seam's (joint's) name
  Eigen::Isometry3d T_world_box = Eigen::Isometry3d::Identity();  // in the truth's world frame
  Eigen::Vector3d half_size_m = Eigen::Vector3d::Zero();
};

// T_world_cam_true at t by interpolation (core::se3_interpolate) between the two nearest samples of a
// time-sorted trajectory; false when t is outside it or the samples around t are more than max_gap_ns
// apart.
bool truth_pose_at(const std::vector<core::StampedPose>& truth, int64_t t_ns, int64_t max_gap_ns,
                   Eigen::Isometry3d* T_world_cam);

// One box per seam: the bounding box of its plates' corners in the axes of its first plate,
// inflated by margin_m on every side. A seam whose plates are all missing from the truth is skipped.
std::vector<TruthJointBox> truth_joint_boxes(const WeldGroundTruth& truth, double margin_m);

// The joints a camera at T_world_cam_true sees — the box centre between min_range_m and max_range_m
// along the optical axis and projecting inside the image — as detections on that keyframe
// (keyframe_id, t_ns), appended to *out (which is cleared first).
void truth_detections(const std::vector<TruthJointBox>& boxes, const Eigen::Isometry3d& T_world_cam_true,
                      const hal::PinholeIntrinsics& K, double min_range_m, double max_range_m,
                      int32_t keyframe_id, int64_t t_ns, std::vector<WeldRegion>* out);

}  // namespace hwr::recon
