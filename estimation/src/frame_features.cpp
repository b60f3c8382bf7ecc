#include "hwr/estimation/frame_features.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>

namespace hwr::estimation {

FrameFeatures::FrameFeatures(int capacity, int image_width, int image_height, int levels, float scale_factor)
    : capacity_(std::max(capacity, 0)),
      width_(image_width),
      height_(image_height),
      features_(static_cast<size_t>(capacity_)),
      descriptors_(static_cast<size_t>(capacity_) * kOrbDescriptorBytes, 0),
      grid_cols_(std::max(1, static_cast<int>(std::ceil(static_cast<float>(image_width) / kGridCellPx)))),
      grid_rows_(std::max(1, static_cast<int>(std::ceil(static_cast<float>(image_height) / kGridCellPx)))),
      cell_start_(static_cast<size_t>(grid_cols_ * grid_rows_ + 1), 0),
      cell_items_(static_cast<size_t>(capacity_), 0),
      cell_of_(static_cast<size_t>(capacity_), 0) {
  scale_per_octave.resize(static_cast<size_t>(std::max(levels, 1)));
  float s = 1.f;
  for (float& x : scale_per_octave) {
    x = s;
    s *= scale_factor;
  }
}

void FrameFeatures::clear() {
  size_ = 0;
  grid_valid_ = false;
}

cv::Mat FrameFeatures::descriptors() const {
  if (size_ == 0) return cv::Mat(0, kOrbDescriptorBytes, CV_8U);
  // cv::Mat has no const view; callers get read access by contract.
  return cv::Mat(size_, kOrbDescriptorBytes, CV_8U, const_cast<uint8_t*>(descriptors_.data()));
}

int FrameFeatures::push_back(const Feature& feature, const uint8_t* descriptor) {
  if (size_ >= capacity_) return -1;
  const int i = size_++;
  features_[static_cast<size_t>(i)] = feature;
  std::memcpy(this->descriptor(i), descriptor, kOrbDescriptorBytes);
  grid_valid_ = false;
  return i;
}

void FrameFeatures::build_grid() {
  const int cells = grid_cols_ * grid_rows_;
  std::fill(cell_start_.begin(), cell_start_.end(), 0);
  for (int i = 0; i < size_; ++i) {
    const Feature& f = features_[static_cast<size_t>(i)];
    const int cx = std::clamp(static_cast<int>(std::floor(f.u_px / kGridCellPx)), 0, grid_cols_ - 1);
    const int cy = std::clamp(static_cast<int>(std::floor(f.v_px / kGridCellPx)), 0, grid_rows_ - 1);
    const int c = cy * grid_cols_ + cx;
    cell_of_[static_cast<size_t>(i)] = c;
    ++cell_start_[static_cast<size_t>(c) + 1];
  }
  for (int c = 0; c < cells; ++c)
    cell_start_[static_cast<size_t>(c) + 1] += cell_start_[static_cast<size_t>(c)];
  // Fill with a running cursor per cell (cell_start_[c] shifted by one, restored after).
  for (int i = 0; i < size_; ++i) {
    const int c = cell_of_[static_cast<size_t>(i)];
    cell_items_[static_cast<size_t>(cell_start_[static_cast<size_t>(c)]++)] = i;
  }
  for (int c = cells; c > 0; --c)
    cell_start_[static_cast<size_t>(c)] = cell_start_[static_cast<size_t>(c) - 1];
  cell_start_[0] = 0;
  grid_valid_ = true;
}

int FrameFeatures::features_in_radius(float u, float v, float r, int min_octave, int max_octave, int* out,
                                      int max_out) const {
  const float r2 = r * r;
  int count = 0;
  auto consider = [&](int i) {
    const Feature& f = features_[static_cast<size_t>(i)];
    if (min_octave >= 0 && f.octave < min_octave) return;
    if (max_octave >= 0 && f.octave > max_octave) return;
    const float du = f.u_px - u, dv = f.v_px - v;
    if (du * du + dv * dv > r2) return;
    if (count < max_out) out[count++] = i;
  };
  if (!grid_valid_) {
    for (int i = 0; i < size_ && count < max_out; ++i) consider(i);
    return count;
  }
  // Clamped to the grid on both sides: features outside the image live in the border cells.
  auto cell_x = [&](float x) {
    return std::clamp(static_cast<int>(std::floor(x / kGridCellPx)), 0, grid_cols_ - 1);
  };
  auto cell_y = [&](float y) {
    return std::clamp(static_cast<int>(std::floor(y / kGridCellPx)), 0, grid_rows_ - 1);
  };
  const int x0 = cell_x(u - r), x1 = cell_x(u + r);
  const int y0 = cell_y(v - r), y1 = cell_y(v + r);
  for (int cy = y0; cy <= y1; ++cy) {
    for (int cx = x0; cx <= x1; ++cx) {
      const int c = cy * grid_cols_ + cx;
      const int end = cell_start_[static_cast<size_t>(c) + 1];
      for (int k = cell_start_[static_cast<size_t>(c)]; k < end; ++k) {
        consider(cell_items_[static_cast<size_t>(k)]);
        if (count >= max_out) return count;
      }
    }
  }
  return count;
}

}  // namespace hwr::estimation
