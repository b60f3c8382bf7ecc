#pragma once
// Sensor effects applied to a noise-free render: depth noise that grows with range, holes
// (missing depth in blobs and at grazing angles), and exposure changes of the colour image.
// Deterministic: every function takes a seed, so a frame's noise depends only on (seed, frame).

#include <cstdint>

#include <opencv2/core/mat.hpp>

namespace hwr::sim {

struct DepthNoiseSpec {
  bool enabled = true;
  // Axial noise sigma(z) = sigma_const_m + sigma_quad_per_m * z^2 (stereo/structured-light
  // depth error grows with the square of range).
  double sigma_const_m = 0.0010;
  double sigma_quad_per_m = 0.0015;
  // Fraction of the image lost in random hole blobs, and the blob radius in pixels.
  double hole_fraction = 0.01;
  int hole_radius_px = 6;
  // Pixels whose depth differs from a 4-neighbour by more than this fraction of their depth
  // (depth discontinuities) become invalid, as in real stereo/ToF sensors. The same test removes
  // surfaces seen at grazing angles, where neighbouring depths drift apart. 0 disables it.
  double edge_dropout_ratio = 0.0;
};

struct ExposureSpec {
  double gain = 1.0;               // multiplies intensities (an exposure jump is a gain step)
  double pixel_noise_sigma = 2.0;  // additive Gaussian noise in 8-bit levels
};

// depth_m: CV_32FC1 in/out; invalid pixels (0) stay 0. Order: discontinuities are found on the
// input, then noise, hole blobs and the dropout are applied. The noise at pixel i depends only on
// (seed, i). Allocation-free after the first call with a given size (scratch buffers are
// thread_local and reused).
void apply_depth_noise(const DepthNoiseSpec& spec, uint64_t seed, cv::Mat* depth_m);
// bgr: CV_8UC3 in/out, saturating.
void apply_exposure(const ExposureSpec& spec, uint64_t seed, cv::Mat* bgr);

}  // namespace hwr::sim
