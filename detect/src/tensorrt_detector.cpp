// Built only with TensorRT (detect/CMakeLists.txt, HWR_WITH_TENSORRT); syntax-checked only on the
// development host (docs/detection.md).
#include "hwr/detect/tensorrt_detector.hpp"

#include <cuda_runtime_api.h>

#include <NvInfer.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <system_error>
#include <vector>

namespace hwr::detect {

namespace {

// TensorRT reports through a logger; the library prints nothing (STYLE.md 5): the last error is kept
// for the status that follows.
class KeepLastError final : public nvinfer1::ILogger {
 public:
  void log(Severity severity, const char* msg) noexcept override {
    if (severity <= Severity::kERROR && msg != nullptr) last_error_ = msg;
  }
  const std::string& last_error() const { return last_error_; }

 private:
  std::string last_error_;
};

std::string dims_text(const nvinfer1::Dims& d) {
  std::vector<int> shape(static_cast<size_t>(d.nbDims > 0 ? d.nbDims : 0));
  for (int i = 0; i < d.nbDims; ++i) shape[static_cast<size_t>(i)] = static_cast<int>(d.d[i]);
  return shape_text(shape);
}

core::Status cuda_status(cudaError_t err, const std::string& what) {
  if (err == cudaSuccess) return core::Status();
  return core::Unavailable("tensorrt detector: " + what + ": " + cudaGetErrorString(err));
}

}  // namespace

struct TensorRtDetector::Engine {
  KeepLastError logger;
  std::unique_ptr<nvinfer1::IRuntime> runtime;
  std::unique_ptr<nvinfer1::ICudaEngine> engine;
  std::unique_ptr<nvinfer1::IExecutionContext> context;
  cudaStream_t stream = nullptr;
  void* input_device = nullptr;
  void* output_device = nullptr;
  size_t input_bytes = 0, output_bytes = 0;
  std::string input_name, output_name;
  std::vector<int> output_shape;

  ~Engine() {
    if (input_device != nullptr) cudaFree(input_device);
    if (output_device != nullptr) cudaFree(output_device);
    if (stream != nullptr) cudaStreamDestroy(stream);
    context.reset();  // before the engine, the engine before the runtime
    engine.reset();
    runtime.reset();
  }

  // blob ([1, 3, S, S] float) in, *output (the head's shape, float) out.
  core::Status forward(const cv::Mat& blob, cv::Mat* output) {
    if (blob.total() * blob.elemSize() != input_bytes) {
      return core::InvalidArgument("tensorrt detector: input blob of " +
                                   std::to_string(blob.total() * blob.elemSize()) +
                                   " bytes, the engine takes " + std::to_string(input_bytes));
    }
    output->create(static_cast<int>(output_shape.size()), output_shape.data(), CV_32F);
    HWR_RETURN_IF_ERROR(
        cuda_status(cudaMemcpyAsync(input_device, blob.ptr(), input_bytes, cudaMemcpyHostToDevice, stream),
                    "copy to device"));
    if (!context->enqueueV3(stream)) {
      return core::Unavailable("tensorrt detector: inference failed: " + logger.last_error());
    }
    HWR_RETURN_IF_ERROR(cuda_status(
        cudaMemcpyAsync(output->ptr(), output_device, output_bytes, cudaMemcpyDeviceToHost, stream),
        "copy from device"));
    return cuda_status(cudaStreamSynchronize(stream), "inference");
  }
};

TensorRtDetector::TensorRtDetector(std::unique_ptr<Engine> engine, ModelPostprocess post)
    : engine_(std::move(engine)), post_(std::move(post)) {}

TensorRtDetector::~TensorRtDetector() = default;

core::Expected<std::unique_ptr<TensorRtDetector>> TensorRtDetector::create(
    const TensorRtDetectorConfig& config, const hal::PinholeIntrinsics& K) {
  HWR_RETURN_IF_ERROR(validate_model_config(config));
  if (!K.valid())
    return core::InvalidArgument("tensorrt detector: invalid intrinsics (all sizes must be > 0)");
  const std::string& path = config.model_path;
  const std::string model = "tensorrt detector: engine '" + path + "'";
  if (path.empty()) return core::InvalidArgument("tensorrt detector: no engine path given");
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return core::NotFound(model + " not found");
  std::ifstream file(path, std::ios::binary);
  const std::vector<char> bytes((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  if (!file.good() && !file.eof()) return core::IoError(model + " could not be read");
  if (bytes.empty()) return core::ParseError(model + " is empty");

  auto e = std::make_unique<Engine>();
  e->runtime.reset(nvinfer1::createInferRuntime(e->logger));
  if (!e->runtime)
    return core::Unavailable(model + ": TensorRT runtime not created: " + e->logger.last_error());
  e->engine.reset(e->runtime->deserializeCudaEngine(bytes.data(), bytes.size()));
  if (!e->engine) {
    return core::ParseError(
        model + " is not an engine TensorRT " + std::to_string(NV_TENSORRT_MAJOR) + "." +
        std::to_string(NV_TENSORRT_MINOR) +
        " can read on this GPU (truncated, corrupt, or built by another version): " + e->logger.last_error());
  }

  // One float input [1, 3, S, S] (a dynamic one is set to it) and the first float output.
  const int32_t io_count = e->engine->getNbIOTensors();
  int inputs = 0;
  for (int32_t i = 0; i < io_count; ++i) {
    const char* name = e->engine->getIOTensorName(i);
    const bool is_input = e->engine->getTensorIOMode(name) == nvinfer1::TensorIOMode::kINPUT;
    if (is_input) ++inputs, e->input_name = name;
    if (!is_input && e->output_name.empty()) e->output_name = name;
  }
  if (inputs != 1 || e->output_name.empty()) {
    return core::InvalidArgument(model + " is incompatible: it has " + std::to_string(inputs) +
                                 " inputs and " + (e->output_name.empty() ? "no" : "an") +
                                 " output; expected one image input and the detection head");
  }
  const int s = config.input_size_px;
  const std::string want_input = "[1, 3, " + std::to_string(s) + ", " + std::to_string(s) + "]";
  nvinfer1::Dims in = e->engine->getTensorShape(e->input_name.c_str());
  const bool fits = in.nbDims == 4 && (in.d[0] == 1 || in.d[0] == -1) && in.d[1] == 3 &&
                    (in.d[2] == s || in.d[2] == -1) && (in.d[3] == s || in.d[3] == -1);
  if (!fits || e->engine->getTensorDataType(e->input_name.c_str()) != nvinfer1::DataType::kFLOAT ||
      e->engine->getTensorDataType(e->output_name.c_str()) != nvinfer1::DataType::kFLOAT) {
    return core::InvalidArgument(model + " is incompatible: input '" + e->input_name + "' is " +
                                 dims_text(in) + ", expected float " + want_input +
                                 " (set input_size_px), and a float output");
  }
  e->context.reset(e->engine->createExecutionContext());
  if (!e->context) return core::Unavailable(model + ": no execution context: " + e->logger.last_error());
  in.d[0] = 1, in.d[2] = s, in.d[3] = s;
  if (!e->context->setInputShape(e->input_name.c_str(), in)) {
    return core::InvalidArgument(model + " is incompatible: input " + want_input +
                                 " refused: " + e->logger.last_error());
  }
  const nvinfer1::Dims out = e->context->getTensorShape(e->output_name.c_str());
  size_t out_count = 1;
  for (int i = 0; i < out.nbDims; ++i) {
    if (out.d[i] < 1)
      return core::InvalidArgument(model + " is incompatible: output " + dims_text(out) + " is not fixed");
    e->output_shape.push_back(static_cast<int>(out.d[i]));
    out_count *= static_cast<size_t>(out.d[i]);
  }
  auto head = yolo_head_from_shape(e->output_shape, static_cast<int>(config.class_names.size()));
  if (!head.ok()) return core::InvalidArgument(model + " is incompatible: " + head.status().message());

  e->input_bytes = sizeof(float) * 3 * static_cast<size_t>(s) * static_cast<size_t>(s);
  e->output_bytes = sizeof(float) * out_count;
  HWR_RETURN_IF_ERROR(cuda_status(cudaStreamCreate(&e->stream), "stream"));
  HWR_RETURN_IF_ERROR(cuda_status(cudaMalloc(&e->input_device, e->input_bytes), "input buffer"));
  HWR_RETURN_IF_ERROR(cuda_status(cudaMalloc(&e->output_device, e->output_bytes), "output buffer"));
  if (!e->context->setTensorAddress(e->input_name.c_str(), e->input_device) ||
      !e->context->setTensorAddress(e->output_name.c_str(), e->output_device)) {
    return core::Internal(model + ": binding the tensors failed: " + e->logger.last_error());
  }

  auto post = ModelPostprocess::create(config, head.value(), K);
  if (!post.ok()) return post.status();
  // One forward pass on a grey keyframe, as the ONNX backend's create().
  const cv::Mat grey(K.height, K.width, CV_8UC3, cv::Scalar::all(kLetterboxPadValue));
  cv::Mat letterboxed, blob, output;
  HWR_RETURN_IF_ERROR(letterbox_blob(grey, post->letterbox(), &letterboxed, &blob));
  const core::Status ran = e->forward(blob, &output);
  if (!ran.ok()) return core::Status(ran.code(), model + ": the first forward pass failed: " + ran.message());
  return std::unique_ptr<TensorRtDetector>(new TensorRtDetector(std::move(e), std::move(post.value())));
}

core::Status TensorRtDetector::detect(const KeyframeView& view, DetectionList* out) {
  if (out == nullptr) return core::InvalidArgument("tensorrt detector: no output list");
  out->clear();
  stats_ = ModelDetectorStats{};
  HWR_RETURN_IF_ERROR(post_.check_view(view, "tensorrt detector"));
  HWR_RETURN_IF_ERROR(letterbox_blob(*view.bgr, post_.letterbox(), &letterboxed_bgr_, &blob_));
  HWR_RETURN_IF_ERROR(engine_->forward(blob_, &output_));
  return post_.run(output_, view, out, &stats_);
}

}  // namespace hwr::detect
