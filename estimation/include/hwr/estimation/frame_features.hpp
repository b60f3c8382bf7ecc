#pragma once
// The ORB features of one image (paper item 6: features matched between frames and keyframes),
// with the depth and back-projected point of each keypoint where the depth image has one (eq. 3).
// All storage is sized for `capacity` features at construction and only refilled afterwards
// (ARCHITECTURE.md firmware rules); copying one FrameFeatures onto another of the same capacity does
// not allocate.
//
// A uniform grid over the image answers "features within r px of (u, v)" without allocating; the
// extractor rebuilds it after each extraction (build_grid()). Until it is rebuilt (after a
// push_back), queries fall back to a linear scan, so results are always correct.

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "hwr/estimation/descriptor.hpp"

namespace hwr::estimation {

struct Feature {
  float u_px = 0, v_px = 0;  // level-0 pixel coordinates
  int octave = 0;            // pyramid level
  float angle_deg = 0, response = 0;
  float depth_m = 0;                                  // 0 = no valid depth at the keypoint
  Eigen::Vector3d p_cam_m = Eigen::Vector3d::Zero();  // back-projected (eq. 3) when depth_m > 0
};

class FrameFeatures {
 public:
  // levels / scale_factor only fill scale_per_octave until an extractor overwrites it.
  FrameFeatures(int capacity, int image_width, int image_height, int levels = 8, float scale_factor = 1.2f);

  int capacity() const { return capacity_; }
  int size() const { return size_; }
  int image_width() const { return width_; }
  int image_height() const { return height_; }
  void clear();

  const Feature& feature(int i) const { return features_[static_cast<size_t>(i)]; }
  Feature& feature(int i) { return features_[static_cast<size_t>(i)]; }
  const uint8_t* descriptor(int i) const {
    return &descriptors_[static_cast<size_t>(i) * kOrbDescriptorBytes];
  }
  uint8_t* descriptor(int i) { return &descriptors_[static_cast<size_t>(i) * kOrbDescriptorBytes]; }
  // size() x 32 CV_8U header over the storage (no copy); valid until the next clear/push_back/copy.
  cv::Mat descriptors() const;

  // Appends a feature and its 32-byte descriptor; returns its index, or -1 when full. Invalidates
  // the grid until build_grid().
  int push_back(const Feature& feature, const uint8_t* descriptor);

  // Rebuilds the radius-query grid over the current features (counting sort; no allocation).
  void build_grid();
  bool grid_valid() const { return grid_valid_; }

  // Indices of features within r px (Euclidean, level-0 pixels) of (u, v) with
  // min_octave <= octave <= max_octave (a negative bound means unbounded; -1/-1: any octave).
  // Writes up to max_out indices into out, returns the count. Allocation-free.
  int features_in_radius(float u, float v, float r, int min_octave, int max_octave, int* out,
                         int max_out) const;

  // Scale of each pyramid level relative to level 0: scale_factor^octave. Sized at construction.
  std::vector<float> scale_per_octave;
  // Scale of an octave, clamped to the table (1 for negative octaves).
  float scale(int octave) const {
    if (octave <= 0 || scale_per_octave.empty()) return 1.f;
    const size_t k = static_cast<size_t>(octave) < scale_per_octave.size() ? static_cast<size_t>(octave)
                                                                           : scale_per_octave.size() - 1;
    return scale_per_octave[k];
  }

 private:
  static constexpr float kGridCellPx = 16.f;
  int capacity_;
  int width_, height_;
  int size_ = 0;
  std::vector<Feature> features_;
  std::vector<uint8_t> descriptors_;
  // Grid: features of cell c are cell_items_[cell_start_[c] .. cell_start_[c + 1]).
  int grid_cols_, grid_rows_;
  std::vector<int> cell_start_;
  std::vector<int> cell_items_;
  std::vector<int> cell_of_;  // scratch: cell of each feature while building
  bool grid_valid_ = false;
};

}  // namespace hwr::estimation
