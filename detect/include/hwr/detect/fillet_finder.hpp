#pragma once
// Fillet (T) joints from planes (issue #7 item 2): a web plate standing on a base plate. Among the
// segmented planes, a base (normal within max_base_tilt_rad of world up) and a web (perpendicular to
// it within max_perpendicular_dev_rad) that meet (cells of one within adjacency_cells of the other's:
// the cells across the corner are not planar) in a concave corner (each plane's centroid on the
// camera side of the other) are a candidate. The seam is the planes' intersection line, refitted from
// the points of each plate in a band next to it (from band_near_m, or band_near_sigmas sigma(z) when
// more, over band_far_m - band_near_m from the other plate's plane): the base plate and the bench
// under it merge into one plane (a 1 cm plate is within the depth noise), and the band keeps the seam
// on the plate's own surface; a band whose plane turns beyond band_max_turn_rad from its plate's
// (narrow and noisy, far away) keeps the plate's normal and refits its offset only. The seam's ends
// are the end_quantile / 1 - end_quantile points of the web's band along the line, clipped to the
// base's, less the quantile's inset. Gates (precision): length, web height, and a free top edge —
// above the web's top edge the depth must be farther than the web by free_min_jump_m and by twice the
// run along the ray after which a surface at the edge's height would be met, or absent: a thin plate
// stands free, while a box on the floor (its top face recedes just behind the front face's edge) or a
// wall does not. Camera frame throughout; sized at create(), find() allocates nothing.

#include <vector>

#include <Eigen/Core>

#include "hwr/core/status.hpp"
#include "hwr/detect/depth_noise.hpp"
#include "hwr/detect/detection.hpp"
#include "hwr/detect/organized_cloud.hpp"
#include "hwr/detect/plane_segmentation.hpp"

namespace hwr::detect {

struct FilletConfig {
  double max_perpendicular_dev_rad = 0.21;  // |90 deg - angle(base, web)| <= 12 deg
  double max_base_tilt_rad = 0.35;          // base normal within 20 deg of world up
  int adjacency_cells = 2;
  int min_adjacent_cells = 3;
  double band_near_m = 0.01;        // the corner's mixed centimetre is skipped...
  double band_near_sigmas = 2.5;    // ... or this many sigma(z), if more: far away the noise mixes the plates
  double band_far_m = 0.06;         // the band is band_far_m - band_near_m wide
  double band_inlier_sigmas = 3.0;  // a band point lies within this many sigma(z) (+ 2 mm) of its plate
  double band_max_turn_rad = 0.05;  // a band's plane turned further from its plate's: offset refit only
  int min_band_points = 30;         // per plate
  double min_length_m = 0.15, max_length_m = 2.0;
  double min_web_height_m = 0.05, max_web_height_m = 0.5;
  double web_height_quantile = 0.98;
  double free_probe_above_m = 0.03;  // probes this far above the web's top edge, in the web's plane
  double free_min_jump_m = 0.05;
  double min_free_fraction = 0.6;  // of the probes that land in the image
  int free_probes = 16;
  double end_quantile = 0.005;
  int end_margin_px = 12;         // an end projecting within this of the border is not observed
  double max_base_width_m = 0.6;  // the box's extent across the seam on the base side, at most
  double box_margin_m = 0.05;     // the box around the plates grows by this (as the truth's boxes)
};

class FilletFinder {
 public:
  // max_points: the most grid points a cloud has (OrganizedCloud width * height). Errors
  // (kInvalidArgument): a config value out of range, max_points < 1.
  static core::Expected<FilletFinder> create(const FilletConfig& config, const DepthNoiseModel& noise,
                                             int max_points);

  // Appends the fillets among the planes to *out (camera-frame members; place_in_world() is the
  // caller's). up_cam: world up in the camera frame (unit). Returns how many were appended (stops when
  // out is full).
  int find(const OrganizedCloud& cloud, const PlaneSegmenter& planes, const Eigen::Vector3d& up_cam,
           DetectionList* out);

  const FilletConfig& config() const { return config_; }

 private:
  // One candidate's seam as the steps of find() refine it (camera frame).
  struct Seam {
    PlaneFit base, web;  // refitted from their bands
    Eigen::Vector3d p0 = Eigen::Vector3d::Zero(), dir = Eigen::Vector3d::UnitX();  // the line
    int web_band_points = 0;
    double t0 = 0, t1 = 0;             // the ends along dir from p0
    double height_m = 0, width_m = 0;  // the web's height, the base's width
  };
  // A point's band tests at depth z: inlier tolerance, the band's start and end from the other plate.
  struct BandLimits {
    double tol_m = 0, near_m = 0, far_m = 0;
  };
  BandLimits band_limits(double z_m) const;
  bool fit_seam_line(const OrganizedCloud& cloud, const PlaneFit& base0, const PlaneFit& web0, Seam* seam);
  bool fit_seam_extent(const OrganizedCloud& cloud, Seam* seam);
  bool fit_plate_sizes(const OrganizedCloud& cloud, Seam* seam);
  bool top_edge_free(const OrganizedCloud& cloud, const Seam& seam) const;
  Detection to_detection(const hal::PinholeIntrinsics& K, const Seam& seam) const;

  FilletConfig config_;
  DepthNoiseModel noise_;
  std::vector<float> along_web_, along_base_, heights_, widths_;  // scratch, max_points each
};

}  // namespace hwr::detect
