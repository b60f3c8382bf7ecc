#include "hwr/hal/hw/side_by_side.hpp"

#include <limits>
#include <string>

#include <opencv2/imgproc.hpp>

namespace hwr::hal::hw {
namespace {

std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

// A sized output must match the eye (see the header); checked for all outputs before any is
// allocated, so a refused call leaves every output as it was.
core::Status check_output(const cv::Mat* out, const char* name, int width, int height, int type) {
  if (out == nullptr || out->empty()) return core::Status::Ok();
  if (out->cols != width || out->rows != height || out->type() != type) {
    return core::InvalidArgument(std::string("side-by-side split: ") + name + " image is " +
                                 size_text(out->cols, out->rows) + " type " + std::to_string(out->type()) +
                                 ", the frame's eye is " + size_text(width, height) + " type " +
                                 std::to_string(type) + " (outputs sized for another camera mode?)");
  }
  return core::Status::Ok();
}

}  // namespace

core::Status split_side_by_side_yuyv(const YuyvFrameView& frame, cv::Mat* left_gray, cv::Mat* right_gray,
                                     cv::Mat* left_bgr) {
  const int w = frame.width_px;
  const int h = frame.height_px;
  if (w <= 0 || h <= 0) {
    return core::InvalidArgument("side-by-side split: frame size " + size_text(w, h) + " is not positive");
  }
  if (w % 4 != 0) {
    return core::InvalidArgument("side-by-side split: frame width " + std::to_string(w) +
                                 " gives an eye width of " + std::to_string(w / 2) + (w % 2 ? ".5" : "") +
                                 "; YUYV shares chroma between pixel pairs, so the eye width must be even");
  }
  const size_t row_bytes = static_cast<size_t>(w) * 2;  // YUYV: 2 bytes per pixel
  if (frame.stride_bytes < row_bytes) {
    return core::InvalidArgument("side-by-side split: stride " + std::to_string(frame.stride_bytes) +
                                 " bytes is less than a " + std::to_string(w) + "-pixel YUYV row (" +
                                 std::to_string(row_bytes) + " bytes)");
  }
  if (frame.stride_bytes > static_cast<size_t>(std::numeric_limits<int>::max())) {
    return core::InvalidArgument("side-by-side split: stride " + std::to_string(frame.stride_bytes) +
                                 " bytes is implausible");
  }
  // The last row needs only its pixels, not a whole stride (drivers may not pad the last row).
  const size_t needed = frame.stride_bytes * static_cast<size_t>(h - 1) + row_bytes;
  if (frame.data == nullptr || frame.size_bytes < needed) {
    return core::CorruptData("side-by-side split: the buffer holds " +
                             std::to_string(frame.data == nullptr ? 0 : frame.size_bytes) + " bytes, a " +
                             size_text(w, h) + " YUYV frame with stride " +
                             std::to_string(frame.stride_bytes) + " needs " + std::to_string(needed) +
                             " (an incomplete frame)");
  }
  if ((left_gray != nullptr && (left_gray == right_gray || left_gray == left_bgr)) ||
      (right_gray != nullptr && right_gray == left_bgr)) {
    return core::InvalidArgument("side-by-side split: the same image was passed for two outputs");
  }
  const int eye_w = w / 2;
  HWR_RETURN_IF_ERROR(check_output(left_gray, "left gray", eye_w, h, CV_8UC1));
  HWR_RETURN_IF_ERROR(check_output(right_gray, "right gray", eye_w, h, CV_8UC1));
  HWR_RETURN_IF_ERROR(check_output(left_bgr, "left BGR", eye_w, h, CV_8UC3));

  // The driver's buffer wrapped in place: one CV_8UC2 element per pixel, rows frame.stride_bytes
  // apart. cv::Mat takes a non-const pointer; nothing here writes through it.
  const cv::Mat yuyv(h, w, CV_8UC2, const_cast<uint8_t*>(frame.data), frame.stride_bytes);
  const cv::Mat left = yuyv.colRange(0, eye_w);  // column ROIs: same rows, offset start, no copy
  const cv::Mat right = yuyv.colRange(eye_w, w);
  // cvtColor writes into an output of the right size and type without reallocating it (and
  // allocates an empty one once).
  if (left_gray != nullptr) cv::cvtColor(left, *left_gray, cv::COLOR_YUV2GRAY_YUYV);
  if (right_gray != nullptr) cv::cvtColor(right, *right_gray, cv::COLOR_YUV2GRAY_YUYV);
  if (left_bgr != nullptr) cv::cvtColor(left, *left_bgr, cv::COLOR_YUV2BGR_YUYV);
  return core::Status::Ok();
}

}  // namespace hwr::hal::hw
