#include "hwr/detect/onnx_detector.hpp"

#include <filesystem>
#include <string>
#include <system_error>

namespace hwr::detect {

namespace {

// OpenCV's own message, on one line.
std::string cv_error_text(const cv::Exception& e) {
  std::string s = e.err.empty() ? std::string(e.what()) : e.err;
  for (char& ch : s) {
    if (ch == '\n' || ch == '\r') ch = ' ';
  }
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

// The forward pass's head blob, its errors as values.
core::Status forward(cv::dnn::Net* net, const cv::Mat& blob, const std::string& output_name,
                     cv::Mat* output) {
  try {
    net->setInput(blob);
    *output = net->forward(output_name);
  } catch (const cv::Exception& e) {
    return core::Internal(cv_error_text(e));
  }
  return core::Status();
}

}  // namespace

OnnxDetector::OnnxDetector(cv::dnn::Net net, std::string output_name, ModelPostprocess post)
    : net_(std::move(net)), output_name_(std::move(output_name)), post_(std::move(post)) {}

core::Expected<std::unique_ptr<OnnxDetector>> OnnxDetector::create(const OnnxDetectorConfig& config,
                                                                   const hal::PinholeIntrinsics& K) {
  HWR_RETURN_IF_ERROR(validate_model_config(config));
  if (!K.valid()) return core::InvalidArgument("onnx detector: invalid intrinsics (all sizes must be > 0)");
  const std::string& path = config.model_path;
  const std::string model = "onnx detector: model '" + path + "'";
  if (path.empty()) return core::InvalidArgument("onnx detector: no model path given");
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return core::NotFound(model + " not found");
  if (!std::filesystem::is_regular_file(path, ec)) return core::InvalidArgument(model + " is not a file");

  cv::dnn::Net net;
  try {
    net = cv::dnn::readNetFromONNX(path);
  } catch (const cv::Exception& e) {
    return core::ParseError(model +
                            " is not a readable ONNX model (truncated or corrupt?): " + cv_error_text(e));
  }
  if (net.empty()) return core::ParseError(model + " is not a readable ONNX model: it holds no network");
  const std::vector<std::string> outputs = net.getUnconnectedOutLayersNames();
  if (outputs.empty()) return core::InvalidArgument(model + " is incompatible: it has no output");

  // One forward pass on a grey keyframe: the input size and the head's layout are checked here, once.
  auto letterbox =
      make_letterbox(cv::Size(K.width, K.height), cv::Size(config.input_size_px, config.input_size_px));
  if (!letterbox.ok()) return letterbox.status();
  const cv::Mat grey(K.height, K.width, CV_8UC3, cv::Scalar::all(kLetterboxPadValue));
  cv::Mat letterboxed, blob, output;
  HWR_RETURN_IF_ERROR(letterbox_blob(grey, letterbox.value(), &letterboxed, &blob));
  const std::string input =
      "[1, 3, " + std::to_string(config.input_size_px) + ", " + std::to_string(config.input_size_px) + "]";
  const core::Status ran = forward(&net, blob, outputs.front(), &output);
  if (!ran.ok()) {
    return core::InvalidArgument(
        model + " is incompatible: a forward pass on a " + input +
        " input failed (is the model's input that size? set input_size_px): " + ran.message());
  }
  auto head = yolo_head_from_shape(mat_shape(output), static_cast<int>(config.class_names.size()));
  if (!head.ok()) return core::InvalidArgument(model + " is incompatible: " + head.status().message());
  if (output.type() != CV_32F) {
    return core::InvalidArgument(model + " is incompatible: its output is not float32 (OpenCV type " +
                                 std::to_string(output.type()) + ")");
  }
  auto post = ModelPostprocess::create(config, head.value(), K);
  if (!post.ok()) return post.status();
  return std::unique_ptr<OnnxDetector>(
      new OnnxDetector(std::move(net), outputs.front(), std::move(post.value())));
}

core::Status OnnxDetector::detect(const KeyframeView& view, DetectionList* out) {
  if (out == nullptr) return core::InvalidArgument("onnx detector: no output list");
  out->clear();
  stats_ = ModelDetectorStats{};
  HWR_RETURN_IF_ERROR(post_.check_view(view, "onnx detector"));
  HWR_RETURN_IF_ERROR(letterbox_blob(*view.bgr, post_.letterbox(), &letterboxed_bgr_, &blob_));
  const core::Status ran = forward(&net_, blob_, output_name_, &output_);
  if (!ran.ok()) return core::Internal("onnx detector: forward pass failed: " + ran.message());
  return post_.run(output_, view, out, &stats_);
}

}  // namespace hwr::detect
