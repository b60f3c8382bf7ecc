#pragma once
// The learned detector on the host (issue #7 item 3): a YOLO detection model in ONNX run by OpenCV DNN
// on the CPU. detect() = letterbox -> forward -> decode -> lift -> place in the world
// (model_postprocess.hpp). Both heads are read: YOLOv10's NMS-free [1, K, 6] (the paper's retrained
// model) and the raw [1, 4 + C, N] that needs NMS (yolo_decode.hpp); the head's layout is told from the
// output's shape at create().
//
// create() loads the model and runs one forward pass on a grey image of the keyframe's size, so that
// an unusable model fails there, with the path and the problem, and never on a keyframe:
//   kNotFound        the file does not exist;
//   kParseError      not a readable ONNX model (truncated, corrupt, not ONNX);
//   kInvalidArgument incompatible: the forward pass fails (an input other than [1, 3, S, S] with S the
//                    configured input_size_px), or the output is no YOLO head for the configured
//                    classes; or a bad config value.
// The first of the model's outputs is the head. detector_factory.hpp falls back to the geometric
// detector on any of these. OpenCV's importer also logs its own error lines to stderr.

#include <memory>

#include <opencv2/dnn/dnn.hpp>

#include "hwr/detect/detector.hpp"
#include "hwr/detect/model_postprocess.hpp"

namespace hwr::detect {

using OnnxDetectorConfig = ModelDetectorConfig;

class OnnxDetector final : public Detector {
 public:
  static core::Expected<std::unique_ptr<OnnxDetector>> create(const OnnxDetectorConfig& config,
                                                              const hal::PinholeIntrinsics& K);

  DetectionSource source() const override { return DetectionSource::kModel; }
  // Needs view.bgr (CV_8UC3) and view.depth_m (CV_32FC1), both of K's size. Errors: kInvalidArgument
  // for a missing or wrong image; kInternal if the forward pass fails on a model create() ran.
  core::Status detect(const KeyframeView& view, DetectionList* out) override;

  const YoloHead& head() const { return post_.head(); }
  const ModelDetectorStats& last_stats() const { return stats_; }

 private:
  OnnxDetector(cv::dnn::Net net, std::string output_name, ModelPostprocess post);
  cv::dnn::Net net_;
  std::string output_name_;
  ModelPostprocess post_;
  cv::Mat letterboxed_bgr_, blob_, output_;
  ModelDetectorStats stats_;
};

}  // namespace hwr::detect
