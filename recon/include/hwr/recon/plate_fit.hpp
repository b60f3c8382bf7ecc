#pragma once
// Welding-plate reconstruction error (issue #4 item 5): how well the map reproduces the work pieces.
//
//  1. read_weld_groundtruth: the plates and seams hwr-sim writes into each run folder
//     (weld_groundtruth.yaml, docs/simulator.md), in the run's world frame.
//  2. fit_plate: one plate from map points inside a region of interest (the ground-truth plate's box
//     inflated by a margin; it stands in for a detection until the detection issue):
//       a. the visible face's plane: RANSAC over the ROI points with the normal within
//          max_normal_angle_rad of the ROI's ±z (a fillet web standing on its base plate is
//          perpendicular to it and never wins), then least squares (PCA) on the inliers, twice;
//       b. the face's rectangle in the plane, edge by edge (see "Edges" below), its in-plane rotation
//          from the slopes of the four edge lines;
//       c. length, width, the 4 face corners in the world frame, inlier count, plane RMS.
//  3. compute_ae: per plate |L - L_gt|, |W - W_gt| and corner errors against the ground-truth
//     corners of the same face; ae_mm = mean absolute dimension error over the plates seen.
//
// Edges. A map is point samples of the surface, or voxel means of them (recon::VoxelMap); taking the
// outermost point as the edge is biased inward by the sample spacing (up to half a voxel per edge).
// Both estimators below are unbiased for a straight edge under their sampling model. In the frame
// of the current rectangle, s is the coordinate along an edge's outward normal, t along the edge,
// e the current edge offset; points within corner_margin_m of a corner (along t) are not used.
//  - kRawPoints (band mean): the points with s in [e - B, e + B_out] are uniform in s on
//    [e - B, E(t)] with E(t) = a + b t the true edge, so E[s | t] = (e - B + a + b t) / 2: the
//    least-squares line of s over t, doubled, gives the edge's offset and slope. The points are
//    averaged, not located, so the estimate does not depend on the sample spacing, and symmetric
//    noise moves points across E without moving their mean. Iterated from a quantile start.
//  - kVoxelMeans (centroid inversion): a voxel mean is the centroid of the part of its cell's cross
//    section with the face that lies on the plate. For every boundary voxel near the current edge
//    (the cell one voxel further out in the face holds no face voxel), the cross section (cube of the
//    grid cut by the plane parallel to the face through the mean) is clipped by a candidate edge line
//    and the line is moved (bisection) until the clipped polygon's centroid matches the voxel mean;
//    the edge is then exact for any grid phase and rotation when the points inside each voxel sample
//    the surface uniformly. A boundary voxel may also hold a wall at the edge (the plate's own side
//    face below the face, a surface rising from the edge): the mean's height above the face gives
//    that wall's share w of the points (mean heights: the face's noise cut to the cell, the wall's
//    middle), and the wall's points sit on the edge line: (1 - w) c(d) + w d = s_mean. A line fit
//    with residual trimming over an edge's voxels gives its offset and slope. Started from the band
//    mean (biased outward by at most a voxel); an edge with too few boundary voxels keeps that.
// Edge-stage points. Raw points: only those on the open side of the face (0 <= h <= max(2.5 RMS,
// 1 mm) along the outward normal): the plate's side faces lie behind it, half of the face's points
// remain, unbiased; the band also ends at the first gap past the edge (a bench a plate thickness
// below a web's foot is a separate cluster). Voxel means: within h_max above the face and down to
// half the side's height in a cell below it (mixed boundary voxels), never within h_max of a plate
// thickness down (bench, other face), and not when the cell one voxel further out along the normal
// holds an off-face point (a surface crossing the face). Points nearer another plate's ground-truth
// box than this plate's are left out, so an edge shared with a coplanar butt partner (or a web's
// foot, coplanar with its base's side face) is bounded by the ground truth, not measured. Edges stay
// inside the ROI; one that stops at its boundary is flagged (PlateFit::at_roi_limit).
// Weights (kRawPoints only). A fine map stores voxel means of a grid finer than the depth noise
// (2 mm), each with the number of raw points merged into it: a mean is then close to a raw point, but
// a voxel holds many points where the surface was seen often and few near an edge, so the means
// taken as unweighted raw points over-represent the sparse parts and bias the edges. weights[i] is
// the multiplicity of point i (a voxel's count; finite and > 0, not necessarily an integer), and
// every statistic is the weighted one, so that a point of weight k gives the result of k copies:
//  - counts: the ROI's points, RANSAC's and the refined plane's inliers, the face points, each edge
//    band's points, and the min_inliers / min_edge_samples checks against them (PlateFit's
//    roi_points, inliers and edge_samples report the weight sums, rounded, saturating at INT_MAX);
//  - RANSAC's MSAC cost; the plane refinement (weighted centroid and scatter) and its RMS;
//  - the quantile start (quantiles of the weight-expanded list);
//  - the band mean: its histogram and gap test, its least-squares line, and each edge's weight in
//    the rotation update.
// RANSAC draws its minimal samples from the weight-expanded cloud (point i with probability
// w_i / sum w). For integer weights (sum below 2^53) the draws are exactly those of the cloud with
// each point repeated w_i times in place (same seed, same points picked), so the fit is the
// duplicated cloud's up to floating-point summation order; other weights draw a real position in
// [0, sum w). kVoxelMeans with weights is kInvalidArgument ("weights are for kRawPoints"): that
// model places each boundary voxel's mean in its own cell, one sample per voxel; a count is not a
// multiplicity there. What weights cannot undo: a voxel whose points come from two surfaces (at a
// web's foot, the web's face and the base's top in one 2 mm cell) has one mean between them.
// Viewpoint (kRawPoints, PlateFitConfig::viewpoint_world). Depth noise lies along the viewing rays:
// with the point where the points were seen from, each face point is placed in the face where its
// ray meets the fitted plane (the noise along the ray drops out) before the edge stage.
// Edges on a support (kRawPoints with a viewpoint; plate_edge_rays.hpp). A plate lying on a bench or
// the floor, seen at a grazing angle, is as thin as the noise: near an edge its face's points and
// the support's are moved by centimetres in the plane and by the plate's thickness across it, and
// the support beyond a far edge lies in the plate's shadow; the band mean, which expects points of
// the face alone, is pulled out to the ROI (seen: 40-80 mm on the sim lab's 10 mm floor plates). So,
// after the band mean, the face's height is re-taken from its interior, and every edge with a
// support beyond it (a median depth past the edge of 0.4-2.5 plate thicknesses) is placed where a
// model of face, plate side and support explains the measured ranges along the rays best. Edges
// without a support beyond (a butt partner's, a web's) keep their band-mean place.
// Not real time: allocates per call (an evaluation tool, not the mapping task's hot path).

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/recon/keyframe_cloud.hpp"

namespace hwr::recon {

// ---------------------------------------------------------------------------------------------
// Ground truth (weld_groundtruth.yaml)

struct PlateTruth {
  std::string name;
  Eigen::Vector3d size_m = Eigen::Vector3d::Zero();  // length (plate x), width (plate y), thickness (plate z)
  Eigen::Isometry3d T_world_plate = Eigen::Isometry3d::Identity();  // plate frame at the box centre
  // Corner i at plate-local (sx L/2, sy W/2, sz T/2), sx = bit 2 of i, sy = bit 1, sz = bit 0 (set: +).
  std::array<Eigen::Vector3d, 8> corners_world{};
};

enum class SeamType { kFillet, kButt };

struct SeamTruth {
  std::string name;
  SeamType type = SeamType::kFillet;
  Eigen::Vector3d start_world = Eigen::Vector3d::Zero();
  Eigen::Vector3d end_world = Eigen::Vector3d::Zero();
  std::array<std::string, 2> plates;  // names of two plates of the file
};

struct WeldGroundTruth {
  std::string scenario;
  std::vector<PlateTruth> plates;
  std::vector<SeamTruth> seams;
};

// Errors: kNotFound / kIoError (file), kParseError (YAML syntax, a missing or unknown key, a wrong
// type, frame other than "world", sizes not positive, T_world_plate not a rigid transform, corners
// that disagree with T_world_plate and size_m by more than 1 mm, duplicate plate names, a seam whose
// type is not fillet|butt or whose plates are not two plates of the file). Messages name the file,
// the line and the key.
core::Expected<WeldGroundTruth> read_weld_groundtruth(const std::string& path);
core::Expected<WeldGroundTruth> parse_weld_groundtruth(const std::string& yaml_text,
                                                       const std::string& source_name);

// ---------------------------------------------------------------------------------------------
// Cloud file (hwr-eval ae --cloud; hwr-robot --cloud-out): a headerless array of CloudPoint
// records, 16 bytes each, little-endian: x_m, y_m, z_m as IEEE-754 binary32, then r, g, b, flags as
// one byte each. The frame is the writer's (hwr-robot writes the world frame of its estimate).

inline constexpr size_t kCloudRecordBytes = 16;
static_assert(sizeof(CloudPoint) == kCloudRecordBytes, "CloudPoint must stay 16 bytes (cloud file record)");

// Errors: kNotFound / kIoError (file); kCorruptData: a size that is not a multiple of 16 bytes, or
// a record with a non-finite coordinate (the record index is named).
core::Expected<std::vector<CloudPoint>> read_cloud_file(const std::string& path);
// Writes atomically (core::write_file_atomic).
core::Status write_cloud_file(const std::string& path, const CloudPoint* points, size_t n);

// ---------------------------------------------------------------------------------------------
// Plate fit

// An oriented box in the world frame: centre and axes from T_world_box, half sizes along its axes.
struct OrientedBox {
  Eigen::Isometry3d T_world_box = Eigen::Isometry3d::Identity();
  Eigen::Vector3d half_size_m = Eigen::Vector3d::Zero();
  // Euclidean distance from the point to the box, 0 inside.
  double distance_m(const Eigen::Vector3d& p_world_m) const;
};

// Where to look for one plate: its (approximate) pose and size, the margins that inflate its box into
// the ROI, and the boxes of the other plates: a point nearer one of them than this plate's box is
// theirs.
struct PlateRoi {
  Eigen::Isometry3d T_world_plate = Eigen::Isometry3d::Identity();
  Eigen::Vector3d size_m = Eigen::Vector3d::Zero();
  double margin_in_plane_m = 0.04;  // added to L/2 and W/2
  double margin_normal_m = 0.02;    // added to T/2
  std::vector<OrientedBox> others;
};

// How the points sample the surface (see "Edges" above).
enum class CloudSampling { kRawPoints, kVoxelMeans };

struct PlateFitConfig {
  CloudSampling sampling = CloudSampling::kRawPoints;
  double voxel_m = 0.0;  // kVoxelMeans: the grid's cell side (VoxelMapConfig::voxel_m)
  // kVoxelMeans: the frame the voxel keys were computed in (floor(p_grid / voxel_m)): the map's
  // frame, i.e. T_world_map when the points were moved into the world after voxelisation.
  Eigen::Isometry3d T_world_grid = Eigen::Isometry3d::Identity();

  double max_normal_angle_rad = 0.35;  // ~20 deg: face normal against the ROI's ±z
  double plane_inlier_m = 0.005;       // RANSAC and refinement
  int ransac_iterations = 300;
  uint32_t seed = 1;          // RANSAC sampling is deterministic
  int min_inliers = 50;       // fewer: not seen
  double edge_band_m = 0.01;  // B of the band mean (3 B for the first 3 updates)
  // B_out of the band mean: how far past the current edge points count (at least 3 plane RMS).
  // Short, so that a surface a centimetre past the edge (the bench under a web) does not count.
  double edge_band_out_m = 0.005;
  double corner_margin_m = 0.03;  // edge samples this close to a corner are not used (>= 2 voxels)
  int min_edge_samples = 5;       // points (band mean) or voxels (inversion) per edge; fewer: not seen
  int max_iterations = 12;        // rectangle updates
  // kRawPoints: where the points were seen from (world frame), when known. Depth noise lies along the
  // viewing rays, so noise that lifts a face point off the face (h) also moves it in the face, towards
  // the camera for h > 0. Keeping only the open side of the face (h >= 0, "Edge-stage points") then
  // keeps the points moved towards the camera, and every edge follows (in the sim lab: -1.2 mm on
  // every plate's length, +3 mm on a base plate's width). With a viewpoint, each face point's place in
  // the face is taken where its ray from the viewpoint meets the fitted plane (its h is kept for the
  // selection): the ray-plane intersection undoes the noise along the ray. One viewpoint for all
  // points (a region's mean camera centre, StoredWeldRegion::viewpoint_segment) is an approximation
  // for views from elsewhere; rays within ~11 deg of the face (|cos| < 0.2 to its normal) are left.
  bool has_viewpoint = false;
  Eigen::Vector3d viewpoint_world = Eigen::Vector3d::Zero();
  // kRawPoints with a viewpoint: edges on a support (header, "Edges on a support"). After the band
  // mean, the face's height is taken again as the weighted median height of the points at least
  // support_interior_inset_m inside the rectangle; then an edge whose points between
  // support_probe_from_m and support_probe_to_m past it lie at a median depth D below the face with
  // D in [support_depth_min_ratio, support_depth_max_ratio] x the ROI's thickness is placed by the
  // ray model within support_search_m of its band-mean place, with D measured (or the ROI's
  // thickness, support_depth_from_roi).
  bool support_edges = true;
  double support_interior_inset_m = 0.03;
  double support_probe_from_m = 0.015, support_probe_to_m = 0.04;
  double support_band_in_m = 0.03;  // samples from this far inside the edge
  double support_depth_min_ratio = 0.4, support_depth_max_ratio = 2.5;
  bool support_depth_from_roi = false;
  double support_search_m = 0.02;
  double support_min_weight = 100;
};

struct PlateFit {
  bool seen = false;
  std::string reason;  // why not seen (too few points, an edge without samples)
  int roi_points = 0;  // points in the ROI after exclusion (with weights: their sum, rounded)
  int inliers = 0;     // within plane_inlier_m of the fitted face (with weights: their sum, rounded)
  double plane_rms_m = 0;
  // Outward unit normal of the fitted face (the plate's body is behind it) and a point on it.
  Eigen::Vector3d normal_world = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d face_centre_world = Eigen::Vector3d::Zero();
  int face_sign = 1;  // +1: the ROI's +z face (top of a base plate), -1: the -z face
  double length_m = 0, width_m = 0;
  // Face corners in the world frame, counter-clockwise about normal_world, starting at the corner
  // at (-L/2, -W/2) of the fitted rectangle's axes (its length axis ~ the ROI's x).
  std::array<Eigen::Vector3d, 4> corners_world{};
  // Per edge (+x, +y, -x, -y of the ROI): points (with weights: their sum, rounded) or voxels used.
  std::array<int, 4> edge_samples{};
  // kVoxelMeans: edges with fewer than min_edge_samples boundary voxels, left at their band-mean
  // place (biased outward by up to half a voxel).
  int edges_from_band_mean = 0;
  // An edge ended at the ROI's boundary: the face could not be told from its surroundings there (a
  // floor or bench as high as the face within the map's noise, a coplanar neighbour).
  bool at_roi_limit = false;
  int iterations = 0;
  // Edges placed by the ray model on a support (PlateFitConfig::support_edges), +x, +y, -x, -y.
  std::array<bool, 4> edge_on_support{};
  int edges_on_support = 0;
};

// weights: nullptr (every point counts once), or n multiplicities (header, "Weights").
// Errors (kInvalidArgument): a non-positive ROI size or margin, a config value out of range
// (kVoxelMeans without a positive voxel_m, thresholds not positive), a weight that is not finite and
// positive (its index is named), weights with kVoxelMeans. A plate with too few points is not an
// error: PlateFit::seen is false and reason says why.
core::Expected<PlateFit> fit_plate(const CloudPoint* points, size_t n, const PlateRoi& roi,
                                   const PlateFitConfig& config, const float* weights = nullptr);

// The ROI of plate i of the ground truth (4 cm in plane, 2 cm along the normal by default), with
// every other plate of the file in PlateRoi::others.
PlateRoi plate_roi_from_truth(const WeldGroundTruth& gt, size_t i, double margin_in_plane_m = 0.04,
                              double margin_normal_m = 0.02);

// ---------------------------------------------------------------------------------------------
// Reconstruction error

struct PlateAe {
  std::string name;
  bool seen = false;
  std::string reason;
  double length_m = 0, width_m = 0;  // fitted
  double gt_length_m = 0, gt_width_m = 0;
  double length_error_mm = 0, width_error_mm = 0;  // |fitted - ground truth|
  // Each fitted corner against the nearest ground-truth corner of the fitted face (face_sign).
  std::array<double, 4> corner_error_mm{};
  double mean_corner_error_mm = 0;
};

struct AeReport {
  std::vector<PlateAe> plates;  // ground-truth order
  int plates_seen = 0;
  int plates_total = 0;
  double ae_mm = 0;         // mean of |dL| and |dW| over the plates seen; NaN when none is seen
  double ae_corner_mm = 0;  // mean corner error over the plates seen; NaN when none is seen
};

// fits[i] is the fit of gt.plates[i]. Error (kInvalidArgument): sizes differ.
core::Expected<AeReport> compute_ae(const std::vector<PlateFit>& fits, const WeldGroundTruth& gt);

}  // namespace hwr::recon
