#include "hwr/detect/organized_cloud.hpp"

#include <cmath>
#include <string>

namespace hwr::detect {
namespace {

int samples_along(int n, int stride) { return (n + stride - 1) / stride; }

}  // namespace

OrganizedCloud::OrganizedCloud(const OrganizedCloudConfig& config, const hal::PinholeIntrinsics& K)
    : config_(config),
      K_(K),
      width_(samples_along(K.width, config.stride_px)),
      height_(samples_along(K.height, config.stride_px)),
      points_(static_cast<size_t>(width_) * static_cast<size_t>(height_), Eigen::Vector3f::Zero()),
      valid_(static_cast<size_t>(width_) * static_cast<size_t>(height_), 0) {}

core::Expected<OrganizedCloud> OrganizedCloud::create(const OrganizedCloudConfig& config,
                                                      const hal::PinholeIntrinsics& K) {
  if (!K.valid()) {
    return core::InvalidArgument("organized cloud: invalid intrinsics (width " + std::to_string(K.width) +
                                 ", height " + std::to_string(K.height) + ", fx " + std::to_string(K.fx) +
                                 ", fy " + std::to_string(K.fy) + "): all must be > 0");
  }
  if (config.stride_px < 1) {
    return core::InvalidArgument("organized cloud: stride_px must be >= 1, got " +
                                 std::to_string(config.stride_px));
  }
  if (!(config.min_depth_m >= 0.0f) || !(config.max_depth_m > config.min_depth_m)) {
    return core::InvalidArgument("organized cloud: depth range needs 0 <= min_depth_m < max_depth_m, got [" +
                                 std::to_string(config.min_depth_m) + ", " +
                                 std::to_string(config.max_depth_m) + "]");
  }
  return OrganizedCloud(config, K);
}

core::Status OrganizedCloud::build(const cv::Mat& depth_m) {
  if (depth_m.type() != CV_32FC1 || depth_m.cols != K_.width || depth_m.rows != K_.height) {
    return core::InvalidArgument("organized cloud: depth must be CV_32FC1 of " + std::to_string(K_.width) +
                                 "x" + std::to_string(K_.height) + ", got type " +
                                 std::to_string(depth_m.type()) + " " + std::to_string(depth_m.cols) + "x" +
                                 std::to_string(depth_m.rows));
  }
  const int stride = config_.stride_px;
  const float min_m = config_.min_depth_m, max_m = config_.max_depth_m;
  // Eq. 3 in double, stored in float: the pixel ray's slope is exact, z carries the sensor's error.
  const double inv_fx = 1.0 / K_.fx, inv_fy = 1.0 / K_.fy;
  int valid_count = 0;
  for (int y = 0; y < height_; ++y) {
    const int v = y * stride;
    const float* row = depth_m.ptr<float>(v);
    const double ray_y = (v - K_.cy) * inv_fy;
    Eigen::Vector3f* p = points_.data() + static_cast<size_t>(y) * width_;
    unsigned char* ok = valid_.data() + static_cast<size_t>(y) * width_;
    for (int x = 0; x < width_; ++x) {
      const int u = x * stride;
      const float z = row[u];
      if (!std::isfinite(z) || !(z > 0.0f) || z < min_m || z > max_m) {
        ok[x] = 0;
        p[x].setZero();
        continue;
      }
      const double ray_x = (u - K_.cx) * inv_fx;
      p[x] = Eigen::Vector3f(static_cast<float>(ray_x * z), static_cast<float>(ray_y * z), z);
      ok[x] = 1;
      ++valid_count;
    }
  }
  valid_count_ = valid_count;
  return core::Status::Ok();
}

}  // namespace hwr::detect
