#pragma once
// The letterbox of a YOLO detector's input (issue #7 item 3): the keyframe's colour image scaled by
// one factor to fit the model's input, centred, the rest filled with grey 114 (Ultralytics' training
// pad), then an NCHW float blob (BGR -> RGB, / 255) by cv::dnn::blobFromImage. The model's boxes are
// in input pixels; model_to_image() undoes the letterbox. Coordinates are continuous (pixel i spans
// [i, i + 1)), as the models' box edges are: x_image = (x_model - pad_left) / scale_x.

#include <opencv2/core/mat.hpp>

#include "hwr/core/status.hpp"

namespace hwr::detect {

struct Letterbox {
  cv::Size image_size_px;    // the keyframe's
  cv::Size input_size_px;    // the model's
  cv::Size resized_size_px;  // the image scaled into the input: round(size * r), r = min(input / image)
  // Input pixels per image pixel along each axis: resized / image, equal to r up to the rounding of the
  // resized size (the exact inverse of cv::resize's mapping).
  double scale_x = 1.0, scale_y = 1.0;
  // Grey columns left of and rows above the image: half the spare, the odd pixel going right / below
  // (as Ultralytics' letterbox).
  int pad_left_px = 0, pad_top_px = 0;

  cv::Point2d model_to_image(const cv::Point2d& p_model_px) const {
    return {(p_model_px.x - pad_left_px) / scale_x, (p_model_px.y - pad_top_px) / scale_y};
  }
  cv::Point2d image_to_model(const cv::Point2d& p_image_px) const {
    return {p_image_px.x * scale_x + pad_left_px, p_image_px.y * scale_y + pad_top_px};
  }
};

constexpr int kLetterboxPadValue = 114;

// Errors (kInvalidArgument): a size not > 0.
core::Expected<Letterbox> make_letterbox(const cv::Size& image_size_px, const cv::Size& input_size_px);

// bgr (CV_8UC3, letterbox.image_size_px) -> *letterboxed_bgr (CV_8UC3, the input size: the image
// resized bilinearly into the grey frame) -> *blob (CV_32F, [1, 3, H, W], RGB in [0, 1]). Both outputs
// are reused when already of their size (no allocation then). Errors (kInvalidArgument): an empty
// image, one not CV_8UC3, one not of the letterbox's image size.
core::Status letterbox_blob(const cv::Mat& bgr, const Letterbox& letterbox, cv::Mat* letterboxed_bgr,
                            cv::Mat* blob);

}  // namespace hwr::detect
