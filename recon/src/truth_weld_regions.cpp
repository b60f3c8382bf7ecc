#include "hwr/recon/truth_weld_regions.hpp"

#include <algorithm>
#include <limits>

#include "hwr/core/se3.hpp"

namespace hwr::recon {

bool truth_pose_at(const std::vector<core::StampedPose>& truth, int64_t t_ns, int64_t max_gap_ns,
                   Eigen::Isometry3d* T_world_cam) {
  if (truth.empty()) return false;
  const auto it = std::lower_bound(truth.begin(), truth.end(), t_ns,
                                   [](const core::StampedPose& p, int64_t t) { return p.t_ns < t; });
  if (it != truth.end() && it->t_ns == t_ns) {
    *T_world_cam = it->T_world_body;
    return true;
  }
  if (it == truth.begin() || it == truth.end()) return false;
  const core::StampedPose& a = *(it - 1);
  const core::StampedPose& b = *it;
  if (b.t_ns - a.t_ns > max_gap_ns) return false;
  const double alpha = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  *T_world_cam = core::se3_interpolate(a.T_world_body, b.T_world_body, alpha);
  return true;
}

std::vector<TruthJointBox> truth_joint_boxes(const WeldGroundTruth& truth, double margin_m) {
  std::vector<TruthJointBox> out;
  for (const SeamTruth& seam : truth.seams) {
    std::vector<const PlateTruth*> plates;
    for (const PlateTruth& p : truth.plates)
      if (p.name == seam.plates[0] || p.name == seam.plates[1]) plates.push_back(&p);
    if (plates.empty()) continue;
    // Axes of the first plate; the box is the plates' corners' extent along them.
    const Eigen::Isometry3d T_world_axes = plates.front()->T_world_plate;
    const Eigen::Isometry3d T_axes_world = T_world_axes.inverse(Eigen::Isometry);
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (const PlateTruth* p : plates) {
      for (const Eigen::Vector3d& c : p->corners_world) {
        const Eigen::Vector3d q = T_axes_world * c;
        lo = lo.cwiseMin(q);
        hi = hi.cwiseMax(q);
      }
    }
    TruthJointBox b;
    b.joint = seam.name;
    b.T_world_box = T_world_axes;
    b.T_world_box.translation() = T_world_axes * (0.5 * (lo + hi));
    b.half_size_m = 0.5 * (hi - lo) + Eigen::Vector3d::Constant(margin_m);
    out.push_back(b);
  }
  return out;
}

void truth_detections(const std::vector<TruthJointBox>& boxes, const Eigen::Isometry3d& T_world_cam_true,
                      const hal::PinholeIntrinsics& K, double min_range_m, double max_range_m,
                      int32_t keyframe_id, int64_t t_ns, std::vector<WeldRegion>* out) {
  out->clear();
  const Eigen::Isometry3d T_cam_world = T_world_cam_true.inverse(Eigen::Isometry);
  for (const TruthJointBox& b : boxes) {
    const Eigen::Isometry3d T_cam_box = T_cam_world * b.T_world_box;
    const Eigen::Vector3d c = T_cam_box.translation();
    if (!(c.z() >= min_range_m && c.z() <= max_range_m)) continue;
    const double u = K.fx * c.x() / c.z() + K.cx, v = K.fy * c.y() / c.z() + K.cy;
    if (!(u >= 0 && v >= 0 && u <= K.width - 1 && v <= K.height - 1)) continue;
    WeldRegion r;
    r.source = WeldRegionSource::kSimTruth;
    r.confidence = 1.0f;
    set_weld_region_label(&r, b.joint);
    r.keyframe_id = keyframe_id;
    r.t_ns = t_ns;
    r.T_cam_region = T_cam_box;
    r.half_size_m = b.half_size_m;
    out->push_back(r);
  }
}

}  // namespace hwr::recon
