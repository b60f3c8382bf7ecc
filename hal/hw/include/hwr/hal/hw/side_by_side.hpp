#pragma once
// The ZED's side-by-side video frame split into its two eyes (hardware.md "Video": V4L2_PIX_FMT_YUYV,
// both eyes in one frame of 2·W × H, the left eye in the left half). The driver's buffer is wrapped
// in place as a CV_8UC2 image (YUYV: per pixel Y then alternately U or V; a pair of pixels Y0 U Y1 V
// shares its chroma), each half taken as a column ROI and converted with cv::cvtColor
// (COLOR_YUV2GRAY_YUYV for the gray eyes that stereo matching wants, COLOR_YUV2BGR_YUYV for the left
// colour image). The halves start on a pixel-pair boundary only when W is even, so W must be even.
// Nothing is copied besides the conversions, and nothing is allocated once the outputs have their
// size: the caller owns them and sizes them once (or passes empty images, allocated on first use).

#include <cstddef>
#include <cstdint>

#include <opencv2/core/mat.hpp>

#include "hwr/core/status.hpp"

namespace hwr::hal::hw {

// One side-by-side YUYV frame as V4L2 hands it over (not owned; valid while the buffer is dequeued).
struct YuyvFrameView {
  const uint8_t* data = nullptr;
  size_t size_bytes = 0;  // bytes valid at data (v4l2_buffer.bytesused)
  int width_px = 0;       // the whole frame: 2 × the eye width
  int height_px = 0;
  size_t stride_bytes = 0;  // bytes from one row to the next (v4l2_pix_format.bytesperline) ≥ 2·width_px
};

// Fills the eyes from one frame. Outputs (any may be null to skip it): left_gray and right_gray
// CV_8UC1 W×H, left_bgr CV_8UC3 W×H (W = width_px / 2). An empty output is allocated; a non-empty one
// must already have that size and type (it is then written in place, no allocation), otherwise
// kInvalidArgument: a buffer sized for another camera mode is a configuration error, not something
// to paper over. Other errors: a null or short buffer (kCorruptData: the frame is incomplete), a
// stride below 2·width_px bytes, a non-positive size, an odd eye width (kInvalidArgument), and the
// same image passed twice.
core::Status split_side_by_side_yuyv(const YuyvFrameView& frame, cv::Mat* left_gray, cv::Mat* right_gray,
                                     cv::Mat* left_bgr);

}  // namespace hwr::hal::hw
