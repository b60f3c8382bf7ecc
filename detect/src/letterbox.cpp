#include "hwr/detect/letterbox.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <opencv2/dnn/dnn.hpp>
#include <opencv2/imgproc.hpp>

namespace hwr::detect {

namespace {

std::string size_text(const cv::Size& s) { return std::to_string(s.width) + "x" + std::to_string(s.height); }

}  // namespace

core::Expected<Letterbox> make_letterbox(const cv::Size& image_size_px, const cv::Size& input_size_px) {
  if (image_size_px.width <= 0 || image_size_px.height <= 0 || input_size_px.width <= 0 ||
      input_size_px.height <= 0) {
    return core::InvalidArgument("letterbox: image " + size_text(image_size_px) + " and model input " +
                                 size_text(input_size_px) + " must both be > 0");
  }
  Letterbox lb;
  lb.image_size_px = image_size_px;
  lb.input_size_px = input_size_px;
  const double r = std::min(static_cast<double>(input_size_px.width) / image_size_px.width,
                            static_cast<double>(input_size_px.height) / image_size_px.height);
  lb.resized_size_px.width =
      std::clamp(static_cast<int>(std::lround(image_size_px.width * r)), 1, input_size_px.width);
  lb.resized_size_px.height =
      std::clamp(static_cast<int>(std::lround(image_size_px.height * r)), 1, input_size_px.height);
  lb.scale_x = static_cast<double>(lb.resized_size_px.width) / image_size_px.width;
  lb.scale_y = static_cast<double>(lb.resized_size_px.height) / image_size_px.height;
  lb.pad_left_px = (input_size_px.width - lb.resized_size_px.width) / 2;
  lb.pad_top_px = (input_size_px.height - lb.resized_size_px.height) / 2;
  return lb;
}

core::Status letterbox_blob(const cv::Mat& bgr, const Letterbox& letterbox, cv::Mat* letterboxed_bgr,
                            cv::Mat* blob) {
  if (bgr.empty() || bgr.type() != CV_8UC3 || bgr.size() != letterbox.image_size_px) {
    return core::InvalidArgument("letterbox: the colour image must be CV_8UC3 of " +
                                 size_text(letterbox.image_size_px) + ", got type " +
                                 std::to_string(bgr.type()) + " " + size_text(bgr.size()));
  }
  letterboxed_bgr->create(letterbox.input_size_px, CV_8UC3);
  letterboxed_bgr->setTo(cv::Scalar::all(kLetterboxPadValue));
  cv::Mat inside = (*letterboxed_bgr)(
      cv::Rect(cv::Point(letterbox.pad_left_px, letterbox.pad_top_px), letterbox.resized_size_px));
  // resize() writes into the ROI's own memory: same size and type, so create() keeps the header.
  cv::resize(bgr, inside, letterbox.resized_size_px, 0, 0, cv::INTER_LINEAR);
  cv::dnn::blobFromImage(*letterboxed_bgr, *blob, 1.0 / 255.0, cv::Size(), cv::Scalar(), /*swapRB=*/true,
                         /*crop=*/false, CV_32F);
  return core::Status();
}

}  // namespace hwr::detect
