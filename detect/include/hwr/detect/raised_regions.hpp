#pragma once
// Plates lying flat on a support (issue #7 item 2, the butt joint's first cue): regions of a horizontal
// surface raised by a plate's thickness above the rest of it. A plate 8-15 mm thick is within a few
// sigma(z) of its bench or floor, so the plane segmentation often merges the two; averaged over a
// window of window_points x window_points grid points the step stands out (the noise across the
// surface is sigma(z) |n . r|, smaller still at the shallow angles a bench is seen at).
//
// A layer is a horizontal plane (normal within max_support_tilt_rad of world up) with the planes
// parallel to it (layer_max_angle_rad) within layer_max_offset_m of it: a support and the plate tops
// split from it. Its points' heights above the support (the layer's lowest plane, refitted without
// the raised points) are box-averaged; a point is raised when its mean height is at least half of
// min_thickness_m and the mean's standard error, sigma(z) |n . r| / sqrt(points in the window), is at
// most max_mean_sigma_fraction of min_thickness_m (farther away a plate cannot be told from its
// support). 4-connected raised points form a region; it is kept when it covers min_area_m2, lies on
// the support (at least min_support_fraction of its border's outer neighbours in the image are the
// support's points: plates lying on a bench have it all around them, 0.58-0.99 of it in the
// simulator's views, while a fillet's base plate has its web along one side and its side faces along
// the others, 0.21-0.27) and its own plane (fitted from its inner points) lies parallel to the support
// (max_top_tilt_rad; the simulator's plates: within 0.15 deg; a raised patch from a tilted fit of a
// surface seen edge-on, as a pallet's top 3 m away, is a ramp of 2 deg) at a plate's thickness above
// it. Camera frame throughout; sized at create(), find() allocates nothing.

#include <vector>

#include <Eigen/Core>

#include "hwr/core/status.hpp"
#include "hwr/detect/depth_noise.hpp"
#include "hwr/detect/organized_cloud.hpp"
#include "hwr/detect/plane_fit.hpp"
#include "hwr/detect/plane_segmentation.hpp"

namespace hwr::detect {

struct RaisedRegionConfig {
  double max_support_tilt_rad = 0.35;  // support normal within 20 deg of world up (as a fillet's base)
  double layer_max_angle_rad = 0.09;   // 5 deg
  double layer_max_offset_m = 0.03;
  int max_layers = 4;              // the largest horizontal planes' layers
  int min_layer_cells = 16;        // a layer's largest plane (plane segmentation cells)
  int window_points = 5;           // box mean of the heights (odd)
  double max_abs_height_m = 0.04;  // a point farther from the support is not the layer's
  double min_thickness_m = 0.006, max_thickness_m = 0.025;
  double max_mean_sigma_fraction = 0.34;
  double min_area_m2 = 0.03;
  double min_support_fraction = 0.45;
  double max_top_tilt_rad = 0.0105;  // 0.6 deg: a plate's top is parallel to its support
  int max_regions = 8;
};

struct RaisedRegion {
  PlaneFit support;             // the layer's lowest surface, refitted without the raised points
  PlaneFit top;                 // the region's own points
  double thickness_m = 0;       // top above the support at the top's centroid
  int points = 0;               // grid points
  double area_m2 = 0;           // on the support
  double support_fraction = 0;  // of its border's outer neighbours in the image, those on the support
  int min_x = 0, min_y = 0, max_x = 0, max_y = 0;  // grid bounding box (inclusive)
};

class RaisedRegionFinder {
 public:
  // For clouds of grid_width x grid_height points. Errors (kInvalidArgument): a config value out of
  // range, a grid smaller than the window.
  static core::Expected<RaisedRegionFinder> create(const RaisedRegionConfig& config,
                                                   const DepthNoiseModel& noise, int grid_width,
                                                   int grid_height);

  // Finds the raised regions of the segmented cloud (of the create() size; else none). up_cam: world
  // up in the camera frame (unit). Returns how many.
  int find(const OrganizedCloud& cloud, const PlaneSegmenter& planes, const Eigen::Vector3d& up_cam);

  int region_count() const { return static_cast<int>(regions_.size()); }
  const RaisedRegion& region(int i) const { return regions_[static_cast<size_t>(i)]; }
  // The region a grid point belongs to (-1: none).
  int region_label(int x, int y) const { return label_[static_cast<size_t>(y) * grid_width_ + x]; }
  // Whether a point of a region is inside it: its mean height at least 3/4 of the region's mean (the
  // box mean blurs a plate's border with its support over half a window; those points are not).
  bool inner(int x, int y) const { return inner_[static_cast<size_t>(y) * grid_width_ + x] != 0; }
  const RaisedRegionConfig& config() const { return config_; }

 private:
  RaisedRegionFinder(const RaisedRegionConfig& config, const DepthNoiseModel& noise, int grid_width,
                     int grid_height);
  struct Box {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // inclusive
  };
  void find_in_layer(const OrganizedCloud& cloud, const PlaneSegmenter& planes, const int* members,
                     int n_members, int support);
  void heights(const OrganizedCloud& cloud, const PlaneSegmenter& planes, const bool* in_layer,
               const PlaneFit& support, const Box& box);
  void box_means(const Box& box);

  RaisedRegionConfig config_;
  DepthNoiseModel noise_;
  int grid_width_ = 0, grid_height_ = 0;
  std::vector<float> height_;       // per grid point: height above the support, NaN: not the layer's
  std::vector<float> mean_height_;  // box mean, NaN: too few points or not the layer's
  std::vector<unsigned char> raised_;
  std::vector<double> sum_, count_;  // integral images, (width + 1) x (height + 1)
  std::vector<int> label_, queue_;
  std::vector<unsigned char> inner_;   // meaningful where label_ >= 0
  std::vector<RaisedRegion> regions_;  // capacity max_regions
};

}  // namespace hwr::detect
