#pragma once
// A learned detector's 2D box lifted to a 3D detection with the keyframe's depth (issue #7 item 3).
// The model gives a region of the image, not a line; the depth inside it gives the 3D box:
//   1. the box's pixels (every stride-th; a pixel is in when its centre is: the box edges are
//      continuous coordinates, pixel i spans [i, i + 1)) with valid depth (finite, within
//      [min_depth_m, max_depth_m]), back-projected with K (eq. 3);
//   2. a depth band around their median, max(band_min_m, band_mads * 1.4826 MAD) wide on each side:
//      the background seen past the plates' edges (a 2D box is a rectangle) is dropped;
//   3. the dominant plane of the band's points: RANSAC (a fixed seed: the same input gives the same
//      box), inliers within plane_inlier_sigmas sigma(z) + 2 mm of it at the median depth, refitted by
//      total least squares (plane_fit.hpp), the normal towards the camera;
//   4. the box: z = that normal, x = the inliers' principal direction within the plane (the long
//      side; pointing to the image's right), y = z x x; its extent along each axis the extent_quantile
//      / 1 - extent_quantile points of all the band's points (the web standing on a base counts), at
//      least min_half_size_m each way.
// The seam is the box's x-axis through its centre, end to end: the model's approximation (a region,
// not a line), so neither end counts as observed. Both plate normals are the dominant plane's (one
// plane is fitted). Too few points (valid, in the band, on the plane) is no detection, never an
// error. Sized at create() for the whole image; lift() allocates nothing.

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "hwr/core/status.hpp"
#include "hwr/detect/depth_noise.hpp"
#include "hwr/detect/detection.hpp"
#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::detect {

struct BoxLiftConfig {
  int stride_px = 2;         // every stride-th pixel of the box in u and v
  float min_depth_m = 0.3f;  // the geometric detector's depth range (organized_cloud.hpp)
  float max_depth_m = 3.5f;
  int min_points = 50;  // fewer valid points, band points or plane inliers: no detection
  double band_mads = 3.0;
  double band_min_m = 0.05;
  int ransac_iterations = 64;
  double plane_inlier_sigmas = 3.0;
  double extent_quantile = 0.02;
  double min_half_size_m = 0.005;
  DepthNoiseModel noise;
};

enum class LiftOutcome : uint8_t { kLifted = 0, kTooFewDepth, kNoPlane };

class BoxLifter {
 public:
  // Errors (kInvalidArgument): invalid K, a config value out of range (named).
  static core::Expected<BoxLifter> create(const BoxLiftConfig& config, const hal::PinholeIntrinsics& K);

  // On kLifted fills d's camera-frame members (seam_cam, end_observed, T_cam_box, half_size_m,
  // plate_normal_cam, box_px: the 3D box's corners projected, clipped to the image); the rest of *d
  // is left alone. Errors (kInvalidArgument): depth_m not CV_32FC1 of K's size.
  core::Expected<LiftOutcome> lift(const cv::Mat& depth_m, const cv::Rect2f& box_px, Detection* d);

  const BoxLiftConfig& config() const { return config_; }

 private:
  BoxLifter(const BoxLiftConfig& config, const hal::PinholeIntrinsics& K);
  // Median of values[0, n) (reorders them).
  static double median(std::vector<double>* values, int n);
  // The q-quantile of values[0, n) (reorders them).
  static double quantile(std::vector<double>* values, int n, double q);

  BoxLiftConfig config_;
  hal::PinholeIntrinsics K_;
  std::vector<Eigen::Vector3d> points_;  // the box's valid points, then the band's (compacted)
  std::vector<double> scratch_;
  std::vector<unsigned char> inlier_;
};

}  // namespace hwr::detect
