#include "hwr/detect/model_postprocess.hpp"

#include <algorithm>
#include <string>

namespace hwr::detect {

namespace {

// Decoded boxes kept per wanted detection: some find no depth or plane.
constexpr int kBoxesPerDetection = 4;

}  // namespace

core::Status validate_model_config(const ModelDetectorConfig& c) {
  if (c.input_size_px < 1) {
    return core::InvalidArgument("model detector: input_size_px must be >= 1, got " +
                                 std::to_string(c.input_size_px));
  }
  if (!(c.score_threshold >= 0.0f && c.score_threshold <= 1.0f)) {
    return core::InvalidArgument("model detector: score_threshold must be in [0, 1], got " +
                                 std::to_string(c.score_threshold));
  }
  if (!(c.nms_iou > 0.0f && c.nms_iou <= 1.0f)) {
    return core::InvalidArgument("model detector: nms_iou must be in (0, 1], got " +
                                 std::to_string(c.nms_iou));
  }
  if (c.max_detections < 1) {
    return core::InvalidArgument("model detector: max_detections must be >= 1, got " +
                                 std::to_string(c.max_detections));
  }
  if (c.class_names.empty()) return core::InvalidArgument("model detector: class_names is empty");
  return core::Status();
}

ModelPostprocess::ModelPostprocess(const ModelDetectorConfig& config, const YoloHead& head,
                                   const hal::PinholeIntrinsics& K, const Letterbox& letterbox,
                                   BoxLifter lifter)
    : config_(config), head_(head), K_(K), letterbox_(letterbox), lifter_(std::move(lifter)) {
  boxes_.reserve(static_cast<size_t>(config.max_detections * kBoxesPerDetection));
}

core::Expected<ModelPostprocess> ModelPostprocess::create(const ModelDetectorConfig& config,
                                                          const YoloHead& head,
                                                          const hal::PinholeIntrinsics& K) {
  HWR_RETURN_IF_ERROR(validate_model_config(config));
  if (head.classes != static_cast<int>(config.class_names.size())) {
    return core::InvalidArgument("model detector: the head has " + std::to_string(head.classes) +
                                 " classes, the config names " + std::to_string(config.class_names.size()));
  }
  auto lifter = BoxLifter::create(config.lift, K);
  if (!lifter.ok()) return lifter.status();
  auto letterbox =
      make_letterbox(cv::Size(K.width, K.height), cv::Size(config.input_size_px, config.input_size_px));
  if (!letterbox.ok()) return letterbox.status();
  return ModelPostprocess(config, head, K, letterbox.value(), std::move(lifter.value()));
}

core::Status ModelPostprocess::check_view(const KeyframeView& view, const char* who) const {
  const std::string kf = std::string(who) + ": keyframe " + std::to_string(view.keyframe_id);
  if (view.K.width != K_.width || view.K.height != K_.height || view.K.fx != K_.fx || view.K.fy != K_.fy ||
      view.K.cx != K_.cx || view.K.cy != K_.cy) {
    return core::InvalidArgument(kf + ": the keyframe's intrinsics are not the detector's");
  }
  if (view.bgr == nullptr || view.bgr->empty()) return core::InvalidArgument(kf + " has no colour image");
  if (view.bgr->type() != CV_8UC3 || view.bgr->cols != K_.width || view.bgr->rows != K_.height) {
    return core::InvalidArgument(kf + ": the colour image must be CV_8UC3 of " + std::to_string(K_.width) +
                                 "x" + std::to_string(K_.height));
  }
  if (view.depth_m == nullptr || view.depth_m->empty())
    return core::InvalidArgument(kf + " has no depth image");
  if (view.depth_m->type() != CV_32FC1 || view.depth_m->cols != K_.width || view.depth_m->rows != K_.height) {
    return core::InvalidArgument(kf + ": the depth image must be CV_32FC1 of " + std::to_string(K_.width) +
                                 "x" + std::to_string(K_.height));
  }
  return core::Status();
}

core::Status ModelPostprocess::run(const cv::Mat& output, const KeyframeView& view, DetectionList* out,
                                   ModelDetectorStats* stats) {
  out->clear();
  *stats = ModelDetectorStats{};
  YoloDecodeConfig decode;
  decode.score_threshold = config_.score_threshold;
  decode.nms_iou = config_.nms_iou;
  decode.max_boxes = config_.max_detections * kBoxesPerDetection;
  HWR_RETURN_IF_ERROR(decode_yolo(output, head_, letterbox_, decode, &boxes_, &stats->decode));
  stats->boxes = static_cast<int>(boxes_.size());
  for (const ImageBox& box : boxes_) {
    if (out->size() >= std::min(config_.max_detections, out->capacity())) break;
    if (box.class_id != static_cast<int>(SeamKind::kFillet) &&
        box.class_id != static_cast<int>(SeamKind::kButt)) {
      ++stats->not_a_seam;
      continue;
    }
    Detection d;
    d.source = DetectionSource::kModel;
    d.kind = static_cast<SeamKind>(box.class_id);
    d.confidence = std::clamp(box.score, 0.0f, 1.0f);
    d.keyframe_id = view.keyframe_id;
    d.t_ns = view.t_ns;
    auto lifted = lifter_.lift(*view.depth_m, box.box_px, &d);
    if (!lifted.ok()) return lifted.status();
    if (lifted.value() == LiftOutcome::kTooFewDepth) {
      ++stats->too_few_depth;
      continue;
    }
    if (lifted.value() == LiftOutcome::kNoPlane) {
      ++stats->no_plane;
      continue;
    }
    place_in_world(view.T_world_cam, &d);
    out->push(d);
    ++stats->lifted;
  }
  return core::Status();
}

}  // namespace hwr::detect
