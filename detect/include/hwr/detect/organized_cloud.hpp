#pragma once
// The keyframe's depth image back-projected into the camera frame on a regular pixel grid (paper
// eq. 3): p_cam = ((u - cx) z / fx, (v - cy) z / fy, z) at pixels (u, v) = (stride x, stride y).
// "Organized": grid neighbours are image neighbours, which the plane segmentation uses instead of a
// search. Sized once at create(); build() allocates nothing.

#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "hwr/core/status.hpp"
#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::detect {

struct OrganizedCloudConfig {
  int stride_px = 2;         // one grid point every stride pixels in u and v
  float min_depth_m = 0.3f;  // depth outside [min, max] is invalid
  float max_depth_m = 3.5f;
};

class OrganizedCloud {
 public:
  // Errors (kInvalidArgument): invalid K (zero size or focal length), stride < 1, an empty or
  // inverted depth range.
  static core::Expected<OrganizedCloud> create(const OrganizedCloudConfig& config,
                                               const hal::PinholeIntrinsics& K);

  // Back-projects depth_m (CV_32FC1, metres, K's size). A pixel that is not finite, <= 0 or outside
  // the depth range is invalid (counted, never an error). Errors: wrong type or size.
  core::Status build(const cv::Mat& depth_m);

  int width() const { return width_; }    // grid columns: K.width / stride (rounded up)
  int height() const { return height_; }  // grid rows
  int stride_px() const { return config_.stride_px; }
  float min_depth_m() const { return config_.min_depth_m; }  // the valid depth range
  float max_depth_m() const { return config_.max_depth_m; }
  bool valid(int x, int y) const { return valid_[static_cast<size_t>(y) * width_ + x] != 0; }
  // Camera frame, metres; meaningful only where valid().
  const Eigen::Vector3f& point(int x, int y) const { return points_[static_cast<size_t>(y) * width_ + x]; }
  int valid_count() const { return valid_count_; }
  const hal::PinholeIntrinsics& intrinsics() const { return K_; }

 private:
  OrganizedCloud(const OrganizedCloudConfig& config, const hal::PinholeIntrinsics& K);
  OrganizedCloudConfig config_;
  hal::PinholeIntrinsics K_;
  int width_ = 0, height_ = 0, valid_count_ = 0;
  std::vector<Eigen::Vector3f> points_;
  std::vector<unsigned char> valid_;
};

}  // namespace hwr::detect
