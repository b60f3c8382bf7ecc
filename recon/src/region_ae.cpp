#include "hwr/recon/region_ae.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "hwr/core/se3.hpp"

namespace hwr::recon {
namespace {

// A region of the map, placed, with its detection's truth.
struct PlacedRegion {
  const StoredWeldRegion* stored = nullptr;
  Eigen::Isometry3d T_map_region = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_map_segment = Eigen::Isometry3d::Identity();  // of the segment placing it
  Eigen::Isometry3d T_world_region_true = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_map_world_true = Eigen::Isometry3d::Identity();  // the detection's local placement
  int64_t fine_points = 0;  // over all segments holding this region id
};

}  // namespace

core::Expected<RegionAeReport> compute_region_ae(const std::vector<FineSegmentView>& segments,
                                                 const WeldGroundTruth& gt,
                                                 const std::vector<core::StampedPose>& truth_T_world_cam,
                                                 const RegionAeConfig& config) {
  RegionAeReport report;
  // Every fine point in the map frame, with its count as weight.
  std::vector<CloudPoint> points;
  std::vector<float> weights;
  std::map<uint32_t, PlacedRegion> regions;  // by id: a region seen in several segments is one
  for (size_t k = 0; k < segments.size(); ++k) {
    const FineSegmentView& s = segments[k];
    if (s.regions == nullptr || s.points_segment == nullptr || s.counts == nullptr) {
      return core::InvalidArgument("region AE: segment view " + std::to_string(k) + " has a null vector");
    }
    if (s.counts->size() != s.points_segment->size()) {
      return core::InvalidArgument("region AE: segment view " + std::to_string(k) + " has " +
                                   std::to_string(s.counts->size()) + " counts for " +
                                   std::to_string(s.points_segment->size()) + " points");
    }
    const Eigen::Isometry3f T = s.T_map_segment.cast<float>();
    for (size_t i = 0; i < s.points_segment->size(); ++i) {
      CloudPoint p = (*s.points_segment)[i];
      const Eigen::Vector3f q = T * Eigen::Vector3f(p.x_m, p.y_m, p.z_m);
      p.x_m = q.x(), p.y_m = q.y(), p.z_m = q.z();
      points.push_back(p);
      weights.push_back(static_cast<float>((*s.counts)[i]));
    }
    for (const StoredWeldRegion& r : *s.regions) {
      PlacedRegion& placed = regions[r.region.id];
      // The region as its segment with the most fine points places it.
      if (placed.stored == nullptr || r.fine_points > placed.stored->fine_points) {
        placed.stored = &r;
        placed.T_map_region = s.T_map_segment * r.T_segment_region;
        placed.T_map_segment = s.T_map_segment;
      }
      placed.fine_points += r.fine_points;
    }
  }
  report.fine_points = static_cast<int64_t>(points.size());
  report.regions = static_cast<int>(regions.size());

  // Each region's detection in the truth: its keyframe's true pose.
  std::vector<PlacedRegion*> known;
  for (auto& [id, r] : regions) {
    Eigen::Isometry3d T_world_cam_true;
    if (!truth_pose_at(truth_T_world_cam, r.stored->region.t_ns, config.max_truth_gap_ns, &T_world_cam_true))
      continue;
    r.T_world_region_true = T_world_cam_true * r.stored->region.T_cam_region;
    const Eigen::Isometry3d T_map_cam_est =
        r.T_map_region * r.stored->region.T_cam_region.inverse(Eigen::Isometry);
    r.T_map_world_true = T_map_cam_est * T_world_cam_true.inverse(Eigen::Isometry);
    known.push_back(&r);
  }

  std::vector<PlateFit> fits(gt.plates.size());
  report.plates.resize(gt.plates.size());
  // Corner errors are taken against each plate's truth as its detection placed it (local error).
  WeldGroundTruth gt_placed = gt;
  for (size_t i = 0; i < gt.plates.size(); ++i) {
    RegionPlate& rp = report.plates[i];
    rp.plate = gt.plates[i].name;
    const Eigen::Vector3d centre = gt.plates[i].T_world_plate.translation();
    const PlacedRegion* best = nullptr;
    for (const PlacedRegion* r : known) {
      if (!inside_region_box(r->T_world_region_true.inverse(Eigen::Isometry) * centre,
                             r->stored->region.half_size_m))
        continue;
      if (best == nullptr || r->fine_points > best->fine_points) best = r;
    }
    if (best == nullptr) {
      rp.fit.reason = "no welding region holds it";
      fits[i] = rp.fit;
      continue;
    }
    ++report.plates_in_regions;
    rp.region_id = best->stored->region.id;
    rp.region_label = weld_region_label(best->stored->region);
    // The truth as the detection placed it.
    WeldGroundTruth local = gt;
    for (PlateTruth& p : local.plates) {
      p.T_world_plate = best->T_map_world_true * p.T_world_plate;
      for (Eigen::Vector3d& c : p.corners_world) c = best->T_map_world_true * c;
    }
    const PlateRoi roi = plate_roi_from_truth(local, i, config.margin_in_plane_m, config.margin_normal_m);
    PlateFitConfig fit_config = config.fit;
    fit_config.has_viewpoint =
        config.use_viewpoints && best->stored->viewpoint_segment != Eigen::Vector3d::Zero();
    fit_config.viewpoint_world = best->T_map_segment * best->stored->viewpoint_segment;
    auto fit = fit_plate(points.data(), points.size(), roi, fit_config, weights.data());
    if (!fit.ok()) return fit.status();
    rp.fit = fit.value();
    fits[i] = rp.fit;
    gt_placed.plates[i] = local.plates[i];
    rp.truth_placed = local.plates[i];
    rp.edge_error_mm.fill(std::numeric_limits<double>::quiet_NaN());
    if (rp.fit.seen) {
      // The fitted corners in the placed truth's plate frame: the two corners on each side of an edge.
      const Eigen::Isometry3d T_plate_map = local.plates[i].T_world_plate.inverse(Eigen::Isometry);
      const Eigen::Vector3d half = 0.5 * local.plates[i].size_m;
      double sum[4] = {0, 0, 0, 0};
      int n[4] = {0, 0, 0, 0};
      for (const Eigen::Vector3d& c : rp.fit.corners_world) {
        const Eigen::Vector3d q = T_plate_map * c;
        const int kx = q.x() >= 0 ? 0 : 1, ky = q.y() >= 0 ? 2 : 3;
        sum[kx] += std::fabs(q.x()) - half.x(), ++n[kx];
        sum[ky] += std::fabs(q.y()) - half.y(), ++n[ky];
      }
      for (int k = 0; k < 4; ++k)
        if (n[k] > 0) rp.edge_error_mm[static_cast<size_t>(k)] = 1e3 * sum[k] / n[k];
    }
  }
  auto ae = compute_ae(fits, gt_placed);
  if (!ae.ok()) return ae.status();
  report.ae = ae.value();
  return report;
}

}  // namespace hwr::recon
