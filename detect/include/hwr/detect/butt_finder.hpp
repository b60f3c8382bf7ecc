#pragma once
// Butt joints (issue #7 item 2): two plates lying side by side on a support with a 2-3 mm root gap.
// The gap is a third of a pixel at 1.5-2.5 m and below the depth noise, so no single pixel shows it.
// What a camera does see is a raised region (raised_regions.hpp: plate tops a plate's thickness above
// their bench or floor) crossed by a straight line of pixels that look into the gap: darker than the
// plate tops beside them (its walls face sideways and get little light) and, seen along the seam,
// deeper (the ray reaches the support). Each such pixel alone is lost in the texture and the noise;
// counted along the line they are not.
//
// Per raised region (its inner points; raised_regions.hpp): a pixel's place on the plate-top plane is
// where its ray meets the plane (fitted from thousands of points; the ray is exact), so a line on the
// plane collects exactly the pixels whose rays cross it. The seam runs along the plates' edges: the
// candidate directions are the two axes of the region's smallest enclosing rectangle, each swept by
// +-direction_range_rad in direction_step_rad. Per direction the pixels are binned across it (bin_px
// wide in the image at the region's centre) in `segments` parts along it, and at each offset the line
// window (centre_px wide) is tested for two cues:
//  - dark: a pixel is dark when its grey level is below dark_ratio times both its neighbours
//    dark_offset_px away across the line's image direction. The line window's dark count is tested
//    against the part's rate p0 of dark pixels as a binomial whose variance is inflated by the
//    overdispersion phi that the texture gives the window counts (phi: the median over all offsets of
//    the squared binomial z, over 0.455, the median of chi-square(1); at least 1). Texture parallel
//    to the line (brushed steel) raises phi and so lowers the line's significance;
//  - depth: the mean depth residual (measured minus the plane's depth along the ray) of the line
//    window minus the mean of the means of the two windows side_gap_px beside it (side_px wide each),
//    against the noise model: sigma(z) sqrt(1 / n_line + 1 / (4 n_left) + 1 / (4 n_right)).
// Each cue's significance is the sum of its parts' z over sqrt(parts), leaving out the largest part
// (a texture blob or stroke is dark in one part only) and needing at least three parts with pixels,
// all but one of them at min_segment_z or more. The line's significance is the largest of the two and,
// where both are measured, their Stouffer sum (z_dark + z_depth) / sqrt(2) (their noises are
// independent: the texture, the stereo noise); the most significant line at least min_plate_width_m
// inside the region on both sides is the seam when it reaches min_z, and a supporting detection
// (Detection::support_only) when it reaches support_z only. A single plate's outer edge (a step down to the
// support), the bench's edge and box edges lie outside any region or at its border; texture strokes are
// short, curved or one-sided.
//
// The seam lies on the plate-top plane (the gap's centre line on the top faces). Its ends are the
// plates' ends: per side of the seam, the depth image's pixels in a band beside it (end_band_near_m to
// end_band_far_m away; placed where their rays cross the top plane, with their measured heights above
// the support) in bins one pixel long; the step down at each end is where the running sum of (height
// - thickness / 2) from the middle outwards peaks (the least-squares step between the two known
// levels), moved into the outer bin by that bin's share of the thickness; the inner ends of the two
// sides. An end whose face the camera sees (the ray to it runs inwards along the seam) is moved in by
// thickness |r . u| / (2 |r . n|): the face's pixels cross the top plane beyond the end, and the step
// at half the thickness lies half way along them. An end is observed when it projects end_margin_px
// inside the image and the support is seen beyond it (within end_search_m). Without a colour image
// only the depth cue is tested. Camera frame throughout; sized at create(), find() allocates nothing.

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "hwr/core/status.hpp"
#include "hwr/detect/depth_noise.hpp"
#include "hwr/detect/detection.hpp"
#include "hwr/detect/organized_cloud.hpp"
#include "hwr/detect/raised_regions.hpp"
#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::detect {

struct ButtConfig {
  double direction_range_rad = 0.026;  // +-1.5 deg around each axis of the enclosing rectangle
  double direction_step_rad = 0.0044;  // 0.25 deg
  double bin_px = 0.5;
  double centre_px = 1.0, side_gap_px = 1.0, side_px = 1.0;
  int max_bins = 2048;  // across a region (wider regions get wider bins)
  int segments = 4;     // parts along the line (3-8)
  double min_segment_z = 1.0;
  int min_window_samples = 8;  // pixels in a window of one part
  double dark_ratio = 0.85;
  double dark_offset_px = 2.0;
  double min_plate_width_m = 0.1;  // the seam lies this far inside the region on both sides
  double min_z = 5.0;
  double support_z = 3.5;              // in (0, min_z]; min_z: no supporting detections
  double max_depth_residual_m = 0.05;  // a pixel's residual is clipped to this (holes, mixed pixels)
  double min_length_m = 0.2, max_length_m = 2.0;
  double end_band_near_m = 0.01, end_band_far_m = 0.08;
  double end_search_m = 0.1;  // the step down is sought this far beyond the region
  int end_margin_px = 12;     // an end projecting within this of the border is not observed
  double box_margin_m = 0.05;
};

class ButtFinder {
 public:
  // For images of K's size and clouds built from them. Errors (kInvalidArgument): a config value out
  // of range, invalid K.
  static core::Expected<ButtFinder> create(const ButtConfig& config, const DepthNoiseModel& noise,
                                           const hal::PinholeIntrinsics& K);

  // Appends the butt joints on the raised regions to *out (camera-frame members). bgr: CV_8UC3 of
  // K's size or null (then only the depth cue counts); depth_m: the cloud's depth image. Returns how
  // many were appended (stops when out is full); images of another size or type give none.
  int find(const OrganizedCloud& cloud, const RaisedRegionFinder& raised, const cv::Mat* bgr,
           const cv::Mat& depth_m, DetectionList* out);

  const ButtConfig& config() const { return config_; }

 private:
  // A pixel of a region: where its ray meets the plate-top plane (plane coordinates, metres), its depth
  // residual (NaN: no depth) and whether it is dark across each candidate direction (bit i).
  struct Sample {
    float a1 = 0, a2 = 0, residual = 0;
    uint8_t dark = 0;
  };
  // The best line of a region: direction angle phi in the plane basis, offset rho across it.
  struct Line {
    double phi = 0, rho = 0, z = 0;
    bool found = false;
  };
  struct Plane2d {  // the plate-top plane: a point, its in-plane basis, its normal
    Eigen::Vector3d origin, e1, e2, normal;
  };
  int collect_border(const OrganizedCloud& cloud, const RaisedRegionFinder& raised, int region,
                     const Plane2d& plane);
  int hull(int n_points);
  bool rectangle_axes(int n_hull, double* phi) const;
  int collect_samples(const OrganizedCloud& cloud, const RaisedRegionFinder& raised, int region,
                      const Plane2d& plane, const double* phi, const cv::Mat* bgr, const cv::Mat& depth_m);
  void sweep_direction(const Plane2d& plane, int n_samples, int n_hull, double phi_c, int axis, bool use_dark,
                       double sigma_z_m, Line* best);
  bool seam_ends(const OrganizedCloud& cloud, const cv::Mat& depth_m, const RaisedRegion& region,
                 const Plane2d& plane, const Line& line, int n_hull, double* t0, double* t1,
                 std::array<bool, 2>* seen_beyond);
  bool on_plane(const Plane2d& plane, double u, double v, Eigen::Vector2f* a, double* depth_m) const;
  Eigen::Vector2d image_direction(const Plane2d& plane, const Eigen::Vector3d& along) const;

  ButtConfig config_;
  DepthNoiseModel noise_;
  hal::PinholeIntrinsics K_;
  std::vector<Sample> samples_;          // K.width x K.height
  std::vector<Eigen::Vector2f> points_;  // a region's border points on the plane
  std::vector<Eigen::Vector2f> hull_;    // their convex hull
  // A profile: per part and bin (prefix sums along the bins), the pixels, the dark ones, the depth
  // residuals and the pixels with depth.
  std::vector<double> n_, dark_, depth_sum_, depth_n_;
  std::vector<double> scratch_;          // a part's squared window z (their median)
  std::vector<double> end_sum_, end_n_;  // the ends' bins: height sums and counts, per side
};

}  // namespace hwr::detect
