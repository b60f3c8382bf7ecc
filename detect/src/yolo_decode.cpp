#include "hwr/detect/yolo_decode.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/dnn/dnn.hpp>

namespace hwr::detect {

namespace {

constexpr int kEndToEndColumns = 6;  // x1 y1 x2 y2 score class

struct Candidate {
  cv::Rect2d box_model_px;
  int class_id = 0;
  float score = 0.0f;
};

cv::Rect2d clip(const cv::Rect2d& r, const cv::Size& size) {
  return r & cv::Rect2d(0.0, 0.0, size.width, size.height);
}

// The letterbox undone, clipped to the image; empty when nothing of it is in the image.
cv::Rect2f to_image(const cv::Rect2d& box_model_px, const Letterbox& lb) {
  const cv::Point2d tl = lb.model_to_image(box_model_px.tl());
  const cv::Point2d br = lb.model_to_image(box_model_px.br());
  const cv::Rect2d r = clip(cv::Rect2d(tl, br), lb.image_size_px);
  return cv::Rect2f(static_cast<float>(r.x), static_cast<float>(r.y), static_cast<float>(r.width),
                    static_cast<float>(r.height));
}

void end_to_end_candidates(const float* out, const YoloHead& head, const Letterbox& lb, float threshold,
                           std::vector<Candidate>* cands, YoloDecodeStats* stats) {
  for (int k = 0; k < head.candidates; ++k) {
    const float* row = out + static_cast<size_t>(k) * kEndToEndColumns;
    const float score = row[4];
    if (!(score >= threshold)) continue;  // NaN too
    ++stats->above_threshold;
    const float cls = row[5];
    const float cls_rounded = std::round(cls);
    if (!(std::fabs(cls - cls_rounded) <= 1e-3f) || cls_rounded < 0.0f ||
        cls_rounded >= static_cast<float>(head.classes)) {
      ++stats->bad_class;
      continue;
    }
    const cv::Rect2d box =
        clip(cv::Rect2d(cv::Point2d(row[0], row[1]), cv::Point2d(row[2], row[3])), lb.input_size_px);
    cands->push_back({box, static_cast<int>(cls_rounded), score});
  }
}

void raw_candidates(const float* out, const YoloHead& head, const Letterbox& lb, float threshold,
                    std::vector<Candidate>* cands, YoloDecodeStats* stats) {
  const int n = head.candidates, features = 4 + head.classes;
  const bool channels_first = head.layout == YoloHeadLayout::kRawChannelsFirst;
  const auto at = [&](int anchor, int feature) {
    return channels_first ? out[static_cast<size_t>(feature) * n + anchor]
                          : out[static_cast<size_t>(anchor) * features + feature];
  };
  for (int a = 0; a < n; ++a) {
    int best = 0;
    float best_score = at(a, 4);
    for (int c = 1; c < head.classes; ++c) {
      const float s = at(a, 4 + c);
      if (s > best_score) best_score = s, best = c;
    }
    if (!(best_score >= threshold)) continue;
    ++stats->above_threshold;
    const double cx = at(a, 0), cy = at(a, 1), w = at(a, 2), h = at(a, 3);
    const cv::Rect2d box = clip(cv::Rect2d(cx - 0.5 * w, cy - 0.5 * h, w, h), lb.input_size_px);
    cands->push_back({box, best, best_score});
  }
}

}  // namespace

const char* yolo_head_layout_name(YoloHeadLayout layout) {
  switch (layout) {
    case YoloHeadLayout::kEndToEnd:
      return "end-to-end [1, K, 6]";
    case YoloHeadLayout::kRawChannelsFirst:
      return "raw [1, 4 + C, N]";
    case YoloHeadLayout::kRawChannelsLast:
      return "raw transposed [1, N, 4 + C]";
  }
  return "?";
}

std::string shape_text(const std::vector<int>& shape) {
  std::string s = "[";
  for (size_t i = 0; i < shape.size(); ++i) s += (i ? ", " : "") + std::to_string(shape[i]);
  return s + "]";
}

std::vector<int> mat_shape(const cv::Mat& m) {
  std::vector<int> shape(static_cast<size_t>(m.dims));
  for (int i = 0; i < m.dims; ++i) shape[static_cast<size_t>(i)] = m.size[i];
  return shape;
}

core::Expected<YoloHead> yolo_head_from_shape(const std::vector<int>& shape, int num_classes) {
  if (num_classes < 1) {
    return core::InvalidArgument("YOLO head: needs at least one class, got " + std::to_string(num_classes));
  }
  const int features = 4 + num_classes;
  const std::string expected = "expected [1, K, 6] (end-to-end: x1 y1 x2 y2 score class) or [1, " +
                               std::to_string(features) + ", N] (raw: cx cy w h and " +
                               std::to_string(num_classes) + " class scores per anchor)";
  if (shape.size() != 3 || shape[0] != 1) {
    return core::InvalidArgument("YOLO head: output shape " + shape_text(shape) +
                                 " is not a YOLO head: " + expected);
  }
  const int a = shape[1], b = shape[2];
  // Which layouts the shape fits. With 2 classes the transposed raw head is [1, N, 6], the end-to-end
  // head's shape: it is read as end-to-end and never as raw transposed (header).
  const bool end_to_end = b == kEndToEndColumns;
  const bool raw_first = a == features;
  const bool raw_last = b == features && features != kEndToEndColumns;
  const int fits = int{end_to_end} + int{raw_first} + int{raw_last};
  if (fits == 0) {
    return core::InvalidArgument("YOLO head: output shape " + shape_text(shape) + " is not a YOLO head for " +
                                 std::to_string(num_classes) + " classes: " + expected);
  }
  if (fits > 1) {
    return core::InvalidArgument("YOLO head: output shape " + shape_text(shape) + " is ambiguous for " +
                                 std::to_string(num_classes) +
                                 " classes (it fits more than one head layout): " + expected);
  }
  YoloHead head;
  head.classes = num_classes;
  head.layout = end_to_end  ? YoloHeadLayout::kEndToEnd
                : raw_first ? YoloHeadLayout::kRawChannelsFirst
                            : YoloHeadLayout::kRawChannelsLast;
  head.candidates = head.layout == YoloHeadLayout::kRawChannelsFirst ? b : a;
  if (head.candidates < 1) {
    return core::InvalidArgument("YOLO head: output shape " + shape_text(shape) + " has no candidates");
  }
  return head;
}

core::Status decode_yolo(const cv::Mat& output, const YoloHead& head, const Letterbox& letterbox,
                         const YoloDecodeConfig& config, std::vector<ImageBox>* boxes,
                         YoloDecodeStats* stats) {
  boxes->clear();
  YoloDecodeStats local_stats;
  YoloDecodeStats& st = stats != nullptr ? *stats : local_stats;
  st = YoloDecodeStats{};
  if (!(config.score_threshold >= 0.0f) || !(config.nms_iou > 0.0f && config.nms_iou <= 1.0f) ||
      config.max_boxes < 1) {
    return core::InvalidArgument("YOLO decode: needs score_threshold >= 0, 0 < nms_iou <= 1, max_boxes >= 1");
  }
  const int features = head.layout == YoloHeadLayout::kEndToEnd ? kEndToEndColumns : 4 + head.classes;
  const std::vector<int> want = head.layout == YoloHeadLayout::kRawChannelsFirst
                                    ? std::vector<int>{1, features, head.candidates}
                                    : std::vector<int>{1, head.candidates, features};
  if (output.type() != CV_32F || !output.isContinuous() || mat_shape(output) != want) {
    return core::InvalidArgument("YOLO decode: output " + shape_text(mat_shape(output)) + " of type " +
                                 std::to_string(output.type()) + " is not the " +
                                 yolo_head_layout_name(head.layout) + " head's CV_32F " + shape_text(want));
  }

  std::vector<Candidate> cands;
  cands.reserve(static_cast<size_t>(head.candidates));
  const float* out = output.ptr<float>();
  if (head.layout == YoloHeadLayout::kEndToEnd) {
    end_to_end_candidates(out, head, letterbox, config.score_threshold, &cands, &st);
  } else {
    raw_candidates(out, head, letterbox, config.score_threshold, &cands, &st);
  }

  // The end-to-end head's rows are its detections; a raw head's go through class-wise NMS. Boxes of
  // different classes never overlap once each class is shifted by a multiple of an offset larger than
  // the input (torchvision's batched_nms), so one NMSBoxes call suppresses within classes only.
  std::vector<int> keep;
  if (head.layout == YoloHeadLayout::kEndToEnd) {
    keep.resize(cands.size());
    for (size_t i = 0; i < keep.size(); ++i) keep[i] = static_cast<int>(i);
    std::stable_sort(keep.begin(), keep.end(), [&](int i, int j) {
      return cands[static_cast<size_t>(i)].score > cands[static_cast<size_t>(j)].score;
    });
    if (static_cast<int>(keep.size()) > config.max_boxes) keep.resize(static_cast<size_t>(config.max_boxes));
  } else if (!cands.empty()) {
    const double offset = 2.0 * std::max(letterbox.input_size_px.width, letterbox.input_size_px.height);
    std::vector<cv::Rect2d> shifted(cands.size());
    std::vector<float> scores(cands.size());
    for (size_t i = 0; i < cands.size(); ++i) {
      shifted[i] = cands[i].box_model_px + cv::Point2d(offset * cands[i].class_id, 0.0);
      scores[i] = cands[i].score;
    }
    cv::dnn::NMSBoxes(shifted, scores, config.score_threshold, config.nms_iou, keep, 1.0f, config.max_boxes);
  }
  st.suppressed = static_cast<int>(cands.size() - keep.size());

  for (const int i : keep) {
    const Candidate& c = cands[static_cast<size_t>(i)];
    const cv::Rect2f box_px = to_image(c.box_model_px, letterbox);
    if (!(box_px.width > 0.0f && box_px.height > 0.0f)) {
      ++st.outside;
      continue;
    }
    boxes->push_back({box_px, c.class_id, c.score});
  }
  return core::Status();
}

}  // namespace hwr::detect
