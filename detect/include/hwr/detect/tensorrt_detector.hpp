#pragma once
// The learned detector on the AGX (issue #7 item 3): the same YOLO model as a serialized TensorRT
// engine (.engine / .plan, built on the device with trtexec from the ONNX file: engines are tied to
// the TensorRT version and the GPU). The input and output tensors are found by their I/O mode and
// bound by name (TensorRT >= 8.5's named-tensor API, the only one in 10); the forward pass runs on its
// own CUDA stream; the letterbox, decoding, lift and placement are the ONNX backend's
// (model_postprocess.hpp).
//
// Compiled only when CMake finds TensorRT (NvInfer.h, libnvinfer) and the CUDA runtime
// (HWR_WITH_TENSORRT, detect/CMakeLists.txt); detector_factory.hpp says when it was not. Not run
// here: this host has neither; the code was only syntax-checked against TensorRT's headers
// (docs/detection.md).
//
// create() deserializes the engine and runs one forward pass, so that an unusable engine fails there
// with the path and the problem: kNotFound (no file), kIoError (unreadable), kParseError (not an
// engine this TensorRT can read: TensorRT's own message), kInvalidArgument (not one float input
// [1, 3, S, S] with S the configured input_size_px, no float output that is a YOLO head for the
// configured classes), kUnavailable (CUDA: no device, out of memory).

#include <memory>

#include "hwr/detect/detector.hpp"
#include "hwr/detect/model_postprocess.hpp"

namespace hwr::detect {

using TensorRtDetectorConfig = ModelDetectorConfig;

class TensorRtDetector final : public Detector {
 public:
  static core::Expected<std::unique_ptr<TensorRtDetector>> create(const TensorRtDetectorConfig& config,
                                                                  const hal::PinholeIntrinsics& K);
  ~TensorRtDetector() override;

  DetectionSource source() const override { return DetectionSource::kModel; }
  // As OnnxDetector::detect; kUnavailable when CUDA or TensorRT fails on a keyframe.
  core::Status detect(const KeyframeView& view, DetectionList* out) override;

  const YoloHead& head() const { return post_.head(); }
  const ModelDetectorStats& last_stats() const { return stats_; }

 private:
  struct Engine;  // TensorRT runtime, engine and context, CUDA stream and buffers (tensorrt_detector.cpp)
  TensorRtDetector(std::unique_ptr<Engine> engine, ModelPostprocess post);
  std::unique_ptr<Engine> engine_;
  ModelPostprocess post_;
  cv::Mat letterboxed_bgr_, blob_, output_;
  ModelDetectorStats stats_;
};

}  // namespace hwr::detect
