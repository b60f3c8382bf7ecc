#pragma once
// Which detector the robot runs (issue #7 item 3): the geometric seam detector, or a learned model
// through ONNX (OpenCV DNN, the host) or TensorRT (the AGX). A model that cannot be used (missing,
// corrupt, incompatible file; TensorRT not built in) never stops the robot: make_detector() returns the
// geometric detector instead, with the model's error as fallback_reason for the caller to log
// ("model X unusable: <reason>; falling back to the geometric seam detector").

#include <memory>
#include <string>

#include "hwr/detect/detector.hpp"
#include "hwr/detect/geometric_seam_detector.hpp"
#include "hwr/detect/model_postprocess.hpp"

namespace hwr::detect {

enum class DetectorBackend : uint8_t { kGeometry = 0, kOnnx, kTensorRt };
const char* detector_backend_name(DetectorBackend backend);  // "geometry", "onnx", "tensorrt"

struct DetectorChoice {
  DetectorBackend backend = DetectorBackend::kGeometry;
  ModelDetectorConfig model;     // kOnnx, kTensorRt: model.model_path (the .onnx file / the engine)
  GeometricSeamConfig geometry;  // kGeometry, and the fallback
};

struct MadeDetector {
  std::unique_ptr<Detector> detector;
  DetectorBackend backend = DetectorBackend::kGeometry;  // what detector is
  // Empty when the chosen backend was made; else why the model is unusable (its status, one line:
  // "not found: onnx detector: model 'x.onnx' not found"), and detector is the geometric one.
  std::string fallback_reason;
  bool fell_back() const { return !fallback_reason.empty(); }
};

// Whether this build has the TensorRT backend (HWR_WITH_TENSORRT found TensorRT).
bool tensorrt_built();

// Errors only when the geometric detector itself cannot be made (invalid K, a bad geometry config).
core::Expected<MadeDetector> make_detector(const DetectorChoice& choice, const hal::PinholeIntrinsics& K);

}  // namespace hwr::detect
