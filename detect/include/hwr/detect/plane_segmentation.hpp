#pragma once
// Planar regions of an organized cloud by cell fits, region growing and region joining (after Feng
// et al., "Fast plane extraction in organized point clouds using agglomerative hierarchical
// clustering", ICRA 2014; hand-written: OpenCV's core has no plane segmentation). The grid is cut
// into square cells of cell_points x cell_points grid points (partial cells at the right and bottom
// border are not cells); a cell is planar when enough of its points are valid and their RMS
// distance to their plane, taken along the viewing ray, is within the depth noise there. Regions
// grow from the most planar cells over 4-adjacent planar cells that lie on the region's plane (its
// moments refitted as it grows), then adjacent regions that lie on one plane are joined. "Lie on
// one plane": normals within merge_angle_rad (or within the noise of the normals where that cannot
// resolve it), the smaller one's centroid within the noise of the larger one's plane, and a joint
// fit that costs no more squared distance than the noise explains (detail in the .cpp). Regions of
// at least min_plane_cells cells that hold a 2x2 block of cells are the planes. Sized once at
// create(); segment() allocates nothing.

#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/detect/depth_noise.hpp"
#include "hwr/detect/organized_cloud.hpp"
#include "hwr/detect/plane_fit.hpp"

namespace hwr::detect {

struct PlaneSegmentationConfig {
  int cell_points = 6;               // cell side in grid points (stride 2: 12 px, 3.3 cm at 1.45 m)
  double cell_min_valid = 0.75;      // fraction of a cell's points that must be valid
  double cell_max_rms_sigmas = 2.0;  // planar cell: RMS along the ray <= this * sigma(z) + cell_rms_floor_m
  double cell_rms_floor_m = 0.0005;
  double merge_angle_rad = 0.21;     // 12 deg between a cell's (or region's) normal and a region's
  double merge_offset_sigmas = 3.0;  // |n_R . c_cell - d_R| <= this * sigma(z) + merge_offset_floor_m;
                                     // also the joint-fit test's bound, in sigmas
  double merge_offset_floor_m = 0.002;
  int min_plane_cells = 4;
  int max_planes = 64;  // the largest regions are kept
};

struct PlaneRegion {
  PlaneFit fit;          // camera frame
  PlaneMoments moments;  // of its cells' valid points
  int cells = 0;
  int min_cx = 0, min_cy = 0, max_cx = 0, max_cy = 0;  // cell bounding box (inclusive)
};

class PlaneSegmenter {
 public:
  // For clouds of grid_width x grid_height points. Errors (kInvalidArgument): a config value out of
  // range, a grid smaller than one cell.
  static core::Expected<PlaneSegmenter> create(const PlaneSegmentationConfig& config,
                                               const DepthNoiseModel& noise, int grid_width, int grid_height);

  // Segments the cloud (of the create() size; else kInvalidArgument). Planes are sorted by cell count,
  // largest first.
  core::Status segment(const OrganizedCloud& cloud);

  int plane_count() const { return static_cast<int>(planes_.size()); }
  const PlaneRegion& plane(int i) const { return planes_[static_cast<size_t>(i)]; }
  int cells_x() const { return cells_x_; }
  int cells_y() const { return cells_y_; }
  int cell_points() const { return config_.cell_points; }
  // The plane index of a cell (-1: none) and of a grid point: its cell's for a valid point of a cell in
  // a plane; a valid point of any other cell (non-planar, in a region too small, or a partial cell at
  // the right/bottom border) takes the nearest plane of its 8 neighbouring cells when within
  // merge_offset_sigmas sigma(z) + merge_offset_floor_m of it (design section 3.2c: the borders of a
  // plane and the points next to a corner); -1 otherwise and for an invalid point.
  int cell_label(int cx, int cy) const { return cell_label_[static_cast<size_t>(cy) * cells_x_ + cx]; }
  int point_label(const OrganizedCloud& cloud, int x, int y) const {
    return cloud.valid(x, y) ? point_label_[static_cast<size_t>(y) * grid_width_ + x] : -1;
  }
  const PlaneSegmentationConfig& config() const { return config_; }

 private:
  PlaneSegmenter(const PlaneSegmentationConfig& config, const DepthNoiseModel& noise, int grid_width,
                 int grid_height);
  PlaneSegmentationConfig config_;
  DepthNoiseModel noise_;
  int grid_width_ = 0, grid_height_ = 0, cells_x_ = 0, cells_y_ = 0;
  std::vector<PlaneMoments> cell_moments_;
  std::vector<PlaneFit> cell_fit_;
  std::vector<unsigned char> cell_planar_;
  std::vector<int> cell_order_;   // planar cells, most planar first (the seeds' order)
  std::vector<int> queue_;        // cells to grow from; then the regions' order
  std::vector<int> cell_label_;   // region, then plane index per cell
  std::vector<int> point_label_;  // plane index per grid point
  std::vector<int> plane_of_region_;
  std::vector<PlaneRegion> regions_;  // scratch, capacity cells
  std::vector<PlaneRegion> planes_;   // capacity max_planes
};

}  // namespace hwr::detect
