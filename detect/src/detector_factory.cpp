#include "hwr/detect/detector_factory.hpp"

#include "hwr/detect/onnx_detector.hpp"
#if HWR_HAVE_TENSORRT
#include "hwr/detect/tensorrt_detector.hpp"
#endif

namespace hwr::detect {

namespace {

// The chosen model backend, or why not.
core::Expected<std::unique_ptr<Detector>> make_model_detector(const DetectorChoice& choice,
                                                              const hal::PinholeIntrinsics& K) {
  if (choice.backend == DetectorBackend::kOnnx) {
    auto d = OnnxDetector::create(choice.model, K);
    if (!d.ok()) return d.status();
    return std::unique_ptr<Detector>(std::move(d.value()));
  }
#if HWR_HAVE_TENSORRT
  auto d = TensorRtDetector::create(choice.model, K);
  if (!d.ok()) return d.status();
  return std::unique_ptr<Detector>(std::move(d.value()));
#else
  return core::Unavailable("tensorrt detector: engine '" + choice.model.model_path +
                           "' not loaded: built without TensorRT (NvInfer.h and libnvinfer were not found "
                           "when configuring; see HWR_WITH_TENSORRT)");
#endif
}

}  // namespace

const char* detector_backend_name(DetectorBackend backend) {
  switch (backend) {
    case DetectorBackend::kGeometry:
      return "geometry";
    case DetectorBackend::kOnnx:
      return "onnx";
    case DetectorBackend::kTensorRt:
      return "tensorrt";
  }
  return "?";
}

bool tensorrt_built() { return HWR_HAVE_TENSORRT != 0; }

core::Expected<MadeDetector> make_detector(const DetectorChoice& choice, const hal::PinholeIntrinsics& K) {
  MadeDetector made;
  if (choice.backend != DetectorBackend::kGeometry) {
    auto model = make_model_detector(choice, K);
    if (model.ok()) {
      made.detector = std::move(model.value());
      made.backend = choice.backend;
      return made;
    }
    made.fallback_reason = model.status().to_string();
  }
  auto geometry = GeometricSeamDetector::create(choice.geometry, K);
  if (!geometry.ok()) return geometry.status();
  made.detector = std::move(geometry.value());
  made.backend = DetectorBackend::kGeometry;
  return made;
}

}  // namespace hwr::detect
