#pragma once
// One camera frame as the rest of the pipeline sees it, whatever the source (ZED 2i stereo,
// TUM RGB-D, EuRoC stereo, simulator). Depth is metric float in the colour camera's frame and
// pixel grid; an invalid pixel holds exactly 0 (drivers turn NaN, inf, negative and
// out-of-range values into 0 and count them in invalid_depth_px).

#include <cstdint>

#include <opencv2/core/mat.hpp>

#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::hal {

struct RgbdFrame {
  int64_t t_ns = 0;    // exposure time on the sensor clock
  uint64_t seq = 0;    // frame counter of the source, gaps mean dropped frames
  cv::Mat bgr;         // CV_8UC3
  cv::Mat depth_m;     // CV_32FC1, 0 = invalid
  cv::Mat right_gray;  // CV_8UC1 rectified right image for stereo sources; empty otherwise
  PinholeIntrinsics intrinsics;
  uint32_t invalid_depth_px = 0;
};

}  // namespace hwr::hal
