#include "hwr/hal/stereo_depth.hpp"

#include <cmath>
#include <string>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace hwr::hal {
namespace {

cv::Mat camera_matrix(const PinholeIntrinsics& k) {
  return (cv::Mat_<double>(3, 3) << k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
}

cv::Mat distortion(const PinholeIntrinsics& k) {
  cv::Mat d(1, 5, CV_64F);
  for (int i = 0; i < 5; ++i) d.at<double>(0, i) = k.distortion[static_cast<size_t>(i)];
  return d;
}

std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

}  // namespace

core::Expected<StereoDepth> StereoDepth::create(const StereoRig& rig, const StereoSgbmParams& params) {
  if (!rig.left.valid() || !rig.right.valid()) {
    return core::InvalidArgument("StereoDepth: both cameras need a positive size and focal length");
  }
  if (rig.left.width != rig.right.width || rig.left.height != rig.right.height) {
    return core::InvalidArgument("StereoDepth: left camera is " + size_text(rig.left.width, rig.left.height) +
                                 ", right is " + size_text(rig.right.width, rig.right.height));
  }
  if (params.num_disparities <= 0 || params.num_disparities % 16 != 0) {
    return core::InvalidArgument("StereoDepth: num_disparities must be a positive multiple of 16, got " +
                                 std::to_string(params.num_disparities));
  }
  if (params.block_size < 1 || params.block_size % 2 == 0) {
    return core::InvalidArgument("StereoDepth: block_size must be odd and >= 1, got " +
                                 std::to_string(params.block_size));
  }
  if (!(params.min_depth_m >= 0) || !(params.max_depth_m > params.min_depth_m)) {
    return core::InvalidArgument("StereoDepth: need 0 <= min_depth_m < max_depth_m");
  }

  StereoDepth sd;
  sd.params_ = params;
  const cv::Size size(rig.left.width, rig.left.height);
  const cv::Mat K1 = camera_matrix(rig.left);
  const cv::Mat K2 = camera_matrix(rig.right);
  const cv::Mat D1 = distortion(rig.left);
  const cv::Mat D2 = distortion(rig.right);
  // OpenCV wants the motion from the first to the second camera: p_right = R · p_left + T.
  const Eigen::Isometry3d T_right_left = rig.T_left_right.inverse();
  cv::Mat R(3, 3, CV_64F);
  cv::Mat T(3, 1, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) R.at<double>(r, c) = T_right_left.linear()(r, c);
    T.at<double>(r, 0) = T_right_left.translation()[r];
  }
  if (cv::norm(T) < 1e-6) return core::InvalidArgument("StereoDepth: the two cameras have no baseline");

  cv::Mat R1, R2, P1, P2, Q;
  cv::stereoRectify(K1, D1, K2, D2, size, R, T, R1, R2, P1, P2, Q, cv::CALIB_ZERO_DISPARITY,
                    params.rectify_alpha, size);
  // Horizontal rig: P2 = [f 0 cx -f·B; 0 f cy 0; 0 0 1 0] (Bouguet); B > 0 when the right camera
  // is to the right of the left one.
  const double f = P1.at<double>(0, 0);
  sd.baseline_m_ = -P2.at<double>(0, 3) / P2.at<double>(0, 0);
  if (std::fabs(P2.at<double>(1, 3)) > 1e-6 * std::fabs(P2.at<double>(0, 3))) {
    return core::InvalidArgument("StereoDepth: rig is not horizontal (vertical rectification not supported)");
  }
  if (!(sd.baseline_m_ > 0)) {
    return core::InvalidArgument(
        "StereoDepth: the right camera is not to the right of the left one "
        "(check T_left_right or swap the cameras)");
  }
  sd.rect_.width = size.width;
  sd.rect_.height = size.height;
  sd.rect_.fx = f;
  sd.rect_.fy = P1.at<double>(1, 1);
  sd.rect_.cx = P1.at<double>(0, 2);
  sd.rect_.cy = P1.at<double>(1, 2);
  // R1 rotates original-left coordinates into the rectified frame: p_rect = R1 · p_cam0.
  Eigen::Matrix3d R1e;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) R1e(r, c) = R1.at<double>(r, c);
  }
  sd.T_cam0_rect_.setIdentity();
  sd.T_cam0_rect_.linear() = R1e.transpose();

  cv::initUndistortRectifyMap(K1, D1, R1, P1, size, CV_16SC2, sd.map_left_[0], sd.map_left_[1]);
  cv::initUndistortRectifyMap(K2, D2, R2, P2, size, CV_16SC2, sd.map_right_[0], sd.map_right_[1]);
  sd.rect_left_.create(size, CV_8UC1);
  sd.disparity_.create(size, CV_16SC1);
  sd.sgbm_ = cv::StereoSGBM::create(params.min_disparity, params.num_disparities, params.block_size,
                                    params.p1, params.p2, params.disp12_max_diff, params.pre_filter_cap,
                                    params.uniqueness_ratio, params.speckle_window_size, params.speckle_range,
                                    params.full_dp ? cv::StereoSGBM::MODE_HH : cv::StereoSGBM::MODE_SGBM);
  return sd;
}

core::Status StereoDepth::compute(const cv::Mat& left_gray, const cv::Mat& right_gray, int64_t t_ns,
                                  uint64_t seq, RgbdFrame* out) {
  return compute_impl(left_gray, right_gray, nullptr, t_ns, seq, out);
}

core::Status StereoDepth::compute(const cv::Mat& left_gray, const cv::Mat& right_gray,
                                  const cv::Mat& left_bgr, int64_t t_ns, uint64_t seq, RgbdFrame* out) {
  if (left_bgr.cols != rect_.width || left_bgr.rows != rect_.height || left_bgr.type() != CV_8UC3) {
    return core::InvalidArgument("StereoDepth: left colour image is " +
                                 size_text(left_bgr.cols, left_bgr.rows) + " type " +
                                 std::to_string(left_bgr.type()) + ", expected " +
                                 size_text(rect_.width, rect_.height) + " 8-bit BGR (CV_8UC3)");
  }
  if (left_bgr.data == out->bgr.data) {  // cv::remap cannot work in place
    return core::InvalidArgument("StereoDepth: the left colour image is the output frame's bgr");
  }
  return compute_impl(left_gray, right_gray, &left_bgr, t_ns, seq, out);
}

core::Status StereoDepth::compute_impl(const cv::Mat& left_gray, const cv::Mat& right_gray,
                                       const cv::Mat* left_bgr, int64_t t_ns, uint64_t seq, RgbdFrame* out) {
  const cv::Mat* in[2] = {&left_gray, &right_gray};
  for (int c = 0; c < 2; ++c) {
    const cv::Mat& m = *in[c];
    if (m.cols != rect_.width || m.rows != rect_.height || (m.type() != CV_8UC1 && m.type() != CV_8UC3)) {
      return core::InvalidArgument(std::string("StereoDepth: ") + (c == 0 ? "left" : "right") + " image is " +
                                   size_text(m.cols, m.rows) + " type " + std::to_string(m.type()) +
                                   ", expected " + size_text(rect_.width, rect_.height) + " 8-bit gray");
    }
    if (m.type() == CV_8UC3) cv::cvtColor(m, gray_scratch_[c], cv::COLOR_BGR2GRAY);
  }
  const cv::Mat& l = left_gray.type() == CV_8UC1 ? left_gray : gray_scratch_[0];
  const cv::Mat& r = right_gray.type() == CV_8UC1 ? right_gray : gray_scratch_[1];
  cv::remap(l, rect_left_, map_left_[0], map_left_[1], cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0);
  cv::remap(r, out->right_gray, map_right_[0], map_right_[1], cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0);
  sgbm_->compute(rect_left_, out->right_gray, disparity_);

  // Z = f·B/d with d = raw/16 (StereoSGBM's 4 fractional bits); raw <= 0 marks no match.
  const double fb16 = rect_.fx * baseline_m_ * 16.0;
  out->depth_m.create(disparity_.size(), CV_32FC1);
  uint32_t invalid = 0;
  for (int y = 0; y < disparity_.rows; ++y) {
    const int16_t* d = disparity_.ptr<int16_t>(y);
    float* z = out->depth_m.ptr<float>(y);
    for (int x = 0; x < disparity_.cols; ++x) {
      const double depth = d[x] > 0 ? fb16 / d[x] : 0.0;
      if (depth > params_.min_depth_m && depth <= params_.max_depth_m) {
        z[x] = static_cast<float>(depth);
      } else {
        z[x] = 0.0f;
        ++invalid;
      }
    }
  }
  if (left_bgr != nullptr) {
    // The same maps as the gray left, so colour and depth share the rectified pixel grid.
    cv::remap(*left_bgr, out->bgr, map_left_[0], map_left_[1], cv::INTER_LINEAR, cv::BORDER_CONSTANT,
              cv::Scalar::all(0));
  } else {
    cv::cvtColor(rect_left_, out->bgr, cv::COLOR_GRAY2BGR);
  }
  out->invalid_depth_px = invalid;
  out->intrinsics = rect_;
  out->t_ns = t_ns;
  out->seq = seq;
  return core::Status::Ok();
}

}  // namespace hwr::hal
