#pragma once
// Depth from a calibrated stereo pair: rectification (cv::stereoRectify, Bouguet's method) and
// semi-global matching (cv::StereoSGBM, Hirschmüller, PAMI 2008). Rectification maps are built
// once at construction; each pair is remapped into preallocated buffers, matched, and turned into
// metric depth Z = f·B/d (f: rectified focal length in px, B: baseline in m, d: disparity in px).
//
// Output is an RgbdFrame in the RECTIFIED left camera: bgr is the rectified left image (the left
// colour image remapped with the left rectification maps when the caller has one, as the ZED's
// YUYV video does; otherwise the gray left replicated to three channels, as for EuRoC), depth_m its
// depth (0 = no match or outside [min, max]), right_gray the rectified right image, intrinsics the
// rectified pinhole (no distortion). Matching always runs on the gray pair.
// The rectified camera is rotated against the original left camera by T_cam0_rect (no
// translation), so a body-to-camera extrinsic composes as T_body_rect = T_body_cam0 · T_cam0_rect.

#include <cstdint>
#include <memory>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "hwr/core/status.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/hal/rgbd_frame.hpp"

namespace cv {
class StereoSGBM;
}

namespace hwr::hal {

struct StereoRig {
  PinholeIntrinsics left;   // with radial-tangential distortion (k1 k2 p1 p2 k3)
  PinholeIntrinsics right;  // same image size as left
  Eigen::Isometry3d T_left_right = Eigen::Isometry3d::Identity();  // p_left = T_left_right · p_right
};

// Defaults suit 752x480 EuRoC-like images (f ~ 450 px, B ~ 0.11 m: 64 px of disparity reaches
// down to ~0.8 m). P1/P2 follow OpenCV's recommendation 8·c·b² and 32·c·b² (c = 1 channel).
struct StereoSgbmParams {
  int min_disparity = 0;
  int num_disparities = 64;  // > 0, multiple of 16
  int block_size = 5;        // odd, 1..11 recommended
  int p1 = 8 * 5 * 5;
  int p2 = 32 * 5 * 5;
  int disp12_max_diff = 1;  // left-right check tolerance in px (< 0 disables)
  int pre_filter_cap = 31;
  int uniqueness_ratio = 10;      // percent margin of the best cost over the second best
  int speckle_window_size = 100;  // 0 disables speckle filtering
  int speckle_range = 2;          // disparity variation within a speckle (px)
  bool full_dp = false;           // true: 8-direction MODE_HH (slower, more memory)
  double rectify_alpha = 0.0;     // cv::stereoRectify alpha: 0 = only valid pixels, 1 = all source pixels
  double min_depth_m = 0.2;       // depths outside [min, max] are set to 0 (invalid)
  double max_depth_m = 20.0;
};

class StereoDepth {
 public:
  // Validates the rig (same image size, positive focal lengths, non-zero baseline) and the
  // parameters, then builds the rectification maps.
  static core::Expected<StereoDepth> create(const StereoRig& rig, const StereoSgbmParams& params = {});

  // left_gray/right_gray: CV_8UC1 at the rig's resolution (or CV_8UC3, converted to gray). Fills
  // *out (buffers reused when sizes match); out->t_ns = t_ns, out->seq = seq.
  core::Status compute(const cv::Mat& left_gray, const cv::Mat& right_gray, int64_t t_ns, uint64_t seq,
                       RgbdFrame* out);
  // The same, and out->bgr is left_bgr (CV_8UC3 at the rig's resolution, the same exposure as
  // left_gray, e.g. both converted from one YUYV frame) through the left rectification maps, in
  // place of the replicated gray. Matching still uses left_gray / right_gray. No allocation when
  // out->bgr already has that size and type.
  core::Status compute(const cv::Mat& left_gray, const cv::Mat& right_gray, const cv::Mat& left_bgr,
                       int64_t t_ns, uint64_t seq, RgbdFrame* out);

  const PinholeIntrinsics& rectified_intrinsics() const { return rect_; }
  // Rotation from the rectified left camera to the original left camera (translation zero).
  const Eigen::Isometry3d& T_cam0_rect() const { return T_cam0_rect_; }
  double baseline_m() const { return baseline_m_; }
  const StereoSgbmParams& params() const { return params_; }

 private:
  StereoDepth() = default;
  // left_bgr null: out->bgr is the rectified gray left replicated.
  core::Status compute_impl(const cv::Mat& left_gray, const cv::Mat& right_gray, const cv::Mat* left_bgr,
                            int64_t t_ns, uint64_t seq, RgbdFrame* out);

  StereoSgbmParams params_;
  PinholeIntrinsics rect_;
  Eigen::Isometry3d T_cam0_rect_ = Eigen::Isometry3d::Identity();
  double baseline_m_ = 0;
  cv::Mat map_left_[2];  // CV_16SC2 + CV_16UC1 fixed-point maps
  cv::Mat map_right_[2];
  cv::Mat rect_left_;  // CV_8UC1
  cv::Mat gray_scratch_[2];
  cv::Mat disparity_;  // CV_16SC1, 4 fractional bits
  std::shared_ptr<cv::StereoSGBM> sgbm_;
};

}  // namespace hwr::hal
