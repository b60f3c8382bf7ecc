#pragma once
// Welding-plate reconstruction error on the fine clouds of the map's welding regions (issue #4:
// AE, paper Table III; the fine cloud is fine_region_map.hpp). Evaluation only (needs the truth).
//
// Where to look for a plate. A map drifts (the lab's ATE is ~1.6 cm), so the ground truth's plate
// boxes, placed in the map's frame by one global alignment, miss the reconstructed plates by
// centimetres — more than the plates' edges need. A detector does not have that problem: it finds a
// plate on a keyframe and the map places it with that keyframe's estimated pose. The same is done
// here with the truth: a plate is measured in the region whose detection contains it, and its ROI is
// the true plate as seen from that region's keyframe, placed with the keyframe's pose in the map:
//   T_map_plate_roi = T_map_cam_est(t) * T_world_cam_true(t)^-1 * T_world_plate_true,
// t the region's detection time, T_map_cam_est(t) = T_map_region * T_cam_region^-1. The other plates
// are moved the same way (PlateRoi::others). The ROI's pose error is the map's *local* error at
// that place, which is what AE should include; its global drift is not.
//
// A plate belongs to the region whose true box (T_world_cam_true(t) * T_cam_region) holds its centre;
// with several, the one with the most fine points. The fit uses every fine point of the map (all
// segments, placed by the caller's T_map_segment) with its count as weight. Corner errors are
// taken against the plate's truth placed as its ROI is (the map's local error, not its drift).

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/recon/plate_fit.hpp"
#include "hwr/recon/truth_weld_regions.hpp"
#include "hwr/recon/weld_region.hpp"

namespace hwr::recon {

// One segment's fine cloud and regions (not owned), and where the caller places the segment.
struct FineSegmentView {
  const std::vector<StoredWeldRegion>* regions = nullptr;
  const std::vector<CloudPoint>* points_segment = nullptr;
  const std::vector<uint32_t>* counts = nullptr;  // parallel to points_segment
  Eigen::Isometry3d T_map_segment = Eigen::Isometry3d::Identity();
};

struct RegionAeConfig {
  double margin_in_plane_m = 0.04;  // plate_roi_from_truth's margins
  double margin_normal_m = 0.02;
  PlateFitConfig fit;  // kRawPoints; the counts are the weights
  // Fit with the region's viewpoint (PlateFitConfig::viewpoint_world; the viewpoint the placing
  // segment recorded).
  bool use_viewpoints = true;
  // Truth poses further than this from the detection time are not interpolated (no truth there).
  int64_t max_truth_gap_ns = 50'000'000;
};

struct RegionPlate {
  std::string plate;
  int64_t region_id = -1;  // -1: no region holds it (not detected)
  std::string region_label;
  PlateFit fit;
  PlateTruth
      truth_placed;  // the truth as the region's detection placed it (the ROI's and corners' reference)
  // Each fitted edge's signed offset from the placed truth's, outwards along the plate's +x, -x, +y,
  // -y (NaN when not seen): where a dimension error comes from.
  std::array<double, 4> edge_error_mm{};
};

struct RegionAeReport {
  AeReport ae;                      // over the plates that a region holds and the fit saw
  std::vector<RegionPlate> plates;  // ground-truth order
  int regions = 0;                  // distinct region ids over the segments
  int64_t fine_points = 0;
  int plates_in_regions = 0;
};

// Errors (kInvalidArgument): a view with null vectors or counts of another length than its points;
// an invalid fit config (fit_plate's errors).
core::Expected<RegionAeReport> compute_region_ae(const std::vector<FineSegmentView>& segments,
                                                 const WeldGroundTruth& gt,
                                                 const std::vector<core::StampedPose>& truth_T_world_cam,
                                                 const RegionAeConfig& config);

}  // namespace hwr::recon
