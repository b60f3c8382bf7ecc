#pragma once
// What every learned-detector backend (ONNX through OpenCV DNN, TensorRT) shares around its forward
// pass (issue #7 item 3): the config, the keyframe checks, the letterbox, and the model's output turned
// into detections in the world: decoded (yolo_decode.hpp), each box lifted to 3D with the depth
// (box_lift.hpp), placed with the keyframe's pose (place_in_world). Class ids are the paper's welding
// region classes: 0 fillet (SeamKind::kFillet), 1 butt (kButt); a model with more classes may name
// them, but their boxes are not seams and are skipped (counted).

#include <string>
#include <vector>

#include "hwr/detect/box_lift.hpp"
#include "hwr/detect/detector.hpp"
#include "hwr/detect/letterbox.hpp"
#include "hwr/detect/yolo_decode.hpp"

namespace hwr::detect {

struct ModelDetectorConfig {
  std::string model_path;   // the .onnx file (OnnxDetector) or a serialized engine (TensorRtDetector)
  int input_size_px = 640;  // the model's square input (YOLOv10's training size)
  float score_threshold = 0.25f;
  float nms_iou = 0.45f;  // raw heads only (the end-to-end head needs no NMS)
  int max_detections = 16;
  std::vector<std::string> class_names{"fillet", "butt"};  // by class id: their count is the head's C
  BoxLiftConfig lift;
};

// Errors (kInvalidArgument) naming the value: input size < 1, thresholds outside [0, 1] / (0, 1], no
// class names, max_detections < 1.
core::Status validate_model_config(const ModelDetectorConfig& config);

struct ModelDetectorStats {
  YoloDecodeStats decode;
  int boxes = 0;          // after decoding (score, NMS)
  int lifted = 0;         // became detections
  int too_few_depth = 0;  // too few valid depth pixels in the box's depth band
  int no_plane = 0;       // no plane among them
  int not_a_seam = 0;     // a class id other than fillet (0) or butt (1)
};

class ModelPostprocess {
 public:
  // Errors (kInvalidArgument): the config (validate_model_config), K, a head whose class count is not
  // the config's.
  static core::Expected<ModelPostprocess> create(const ModelDetectorConfig& config, const YoloHead& head,
                                                 const hal::PinholeIntrinsics& K);

  // The view has what a model needs: a CV_8UC3 colour image and a CV_32FC1 depth image, both of K's
  // size, and the detector's K. Errors (kInvalidArgument) say which is missing or wrong; who names the
  // backend ("onnx detector").
  core::Status check_view(const KeyframeView& view, const char* who) const;

  // output: the forward pass's head blob. Clears *out, then appends the detections best first (at most
  // max_detections and out's capacity). Errors (kInvalidArgument): output not the head's shape.
  core::Status run(const cv::Mat& output, const KeyframeView& view, DetectionList* out,
                   ModelDetectorStats* stats);

  const Letterbox& letterbox() const { return letterbox_; }
  const YoloHead& head() const { return head_; }

 private:
  ModelPostprocess(const ModelDetectorConfig& config, const YoloHead& head, const hal::PinholeIntrinsics& K,
                   const Letterbox& letterbox, BoxLifter lifter);
  ModelDetectorConfig config_;
  YoloHead head_;
  hal::PinholeIntrinsics K_;
  Letterbox letterbox_;
  BoxLifter lifter_;
  std::vector<ImageBox> boxes_;
};

}  // namespace hwr::detect
