#pragma once
// Decoding a YOLO detection head's output into boxes in image pixels (issue #7 item 3). Two heads:
//   end-to-end [1, K, 6]: x1 y1 x2 y2 score class per row, already free of duplicates (YOLOv10's
//     NMS-free one-to-one head, Wang et al. 2024; the paper retrains YOLOv10 on welding regions);
//   raw [1, 4 + C, N] (YOLOv8-style, Ultralytics' export): per anchor cx cy w h and C class scores;
//     each anchor's best class above the threshold, then class-wise NMS (cv::dnn::NMSBoxes with the
//     batched-NMS offset: OpenCV 4.6 has no NMSBoxesBatched). The transposed [1, N, 4 + C] is read too
//     where the shape says so unambiguously: with 2 classes [1, N, 6] is the end-to-end head's shape,
//     so a transposed raw head of 2 classes cannot be told from it and is read as end-to-end (export
//     raw heads channels-first, Ultralytics' default).
// Coordinates are model input pixels (not normalised); the letterbox is undone and the boxes clipped
// to the image. Pure functions over plain data: tested without any model file.

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "hwr/core/status.hpp"
#include "hwr/detect/letterbox.hpp"

namespace hwr::detect {

enum class YoloHeadLayout : uint8_t {
  kEndToEnd = 0,      // [1, K, 6]
  kRawChannelsFirst,  // [1, 4 + C, N]
  kRawChannelsLast,   // [1, N, 4 + C]
};
const char* yolo_head_layout_name(YoloHeadLayout layout);  // "end-to-end [1, K, 6]", ...

struct YoloHead {
  YoloHeadLayout layout = YoloHeadLayout::kEndToEnd;
  int candidates = 0;  // K rows or N anchors
  int classes = 0;     // C: the class names the detector knows
};

// The head an output shape is, for num_classes classes. A shape that fits exactly one of the three
// layouts is that layout. Errors (kInvalidArgument), naming the shape: not rank 3 with batch 1, none
// of the layouts, more than one ([1, 6, 6] with 2 classes), num_classes < 1, no candidates.
core::Expected<YoloHead> yolo_head_from_shape(const std::vector<int>& shape, int num_classes);
std::string shape_text(const std::vector<int>& shape);  // "[1, 300, 6]"
std::vector<int> mat_shape(const cv::Mat& m);           // m.size[0 .. dims)

struct YoloDecodeConfig {
  float score_threshold = 0.25f;  // a box needs score >= this
  float nms_iou = 0.45f;          // raw heads: a box overlapping a better one of its class more is dropped
  int max_boxes = 100;            // the best this many are kept
};

// One box the model found, image pixels (continuous), clipped to the image.
struct ImageBox {
  cv::Rect2f box_px;
  int class_id = 0;
  float score = 0.0f;
};

struct YoloDecodeStats {
  int above_threshold = 0;  // candidates with a score >= the threshold
  int suppressed = 0;       // removed by NMS or by max_boxes
  int bad_class = 0;        // end-to-end rows whose class is not an integer in [0, C)
  int outside = 0;          // empty once clipped to the image (e.g. within the letterbox's grey band)
};

// output: the head's blob (CV_32F, the head's shape). *boxes is cleared, then filled best first.
// Errors (kInvalidArgument): output's type or shape not the head's, a bad config value.
core::Status decode_yolo(const cv::Mat& output, const YoloHead& head, const Letterbox& letterbox,
                         const YoloDecodeConfig& config, std::vector<ImageBox>* boxes,
                         YoloDecodeStats* stats = nullptr);

}  // namespace hwr::detect
