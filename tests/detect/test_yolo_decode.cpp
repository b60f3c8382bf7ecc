// The letterbox (detect/letterbox.hpp) and the decoding of both YOLO heads (detect/yolo_decode.hpp),
// without any model file: hand-made output blobs. Oracles: the letterbox's closed form (640 x 480 into
// 64 x 64: scale 0.1, 8 grey rows above and below), hand-computed IoUs, and the boxes put in.

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include <opencv2/core.hpp>

#include "hwr/detect/letterbox.hpp"
#include "hwr/detect/yolo_decode.hpp"

namespace hwr::detect {
namespace {

Letterbox vga_into_64() {
  auto lb = make_letterbox(cv::Size(640, 480), cv::Size(64, 64));
  EXPECT_TRUE(lb.ok()) << lb.status().message();
  return lb.value();
}

cv::Mat blob3(int a, int b) {
  const int dims[3] = {1, a, b};
  return cv::Mat(3, dims, CV_32F, cv::Scalar(0.0f));
}

void expect_box(const ImageBox& got, double x0, double y0, double x1, double y1, int class_id, float score) {
  EXPECT_NEAR(got.box_px.x, x0, 1e-3);
  EXPECT_NEAR(got.box_px.y, y0, 1e-3);
  EXPECT_NEAR(got.box_px.x + got.box_px.width, x1, 1e-3);
  EXPECT_NEAR(got.box_px.y + got.box_px.height, y1, 1e-3);
  EXPECT_EQ(got.class_id, class_id);
  EXPECT_FLOAT_EQ(got.score, score);
}

// An end-to-end row: x1 y1 x2 y2 score class.
void set_row(cv::Mat* out, int k, std::vector<float> row) {
  for (int c = 0; c < 6; ++c) out->ptr<float>()[k * 6 + c] = row[static_cast<size_t>(c)];
}

// A raw anchor: cx cy w h and the class scores, channels first ([1, 4 + C, N]) or last ([1, N, 4 + C]).
void set_anchor(cv::Mat* out, bool channels_first, int anchor, std::vector<float> values) {
  const int features = channels_first ? out->size[1] : out->size[2];
  const int n = channels_first ? out->size[2] : out->size[1];
  for (int f = 0; f < features; ++f) {
    const size_t i =
        channels_first ? static_cast<size_t>(f) * n + anchor : static_cast<size_t>(anchor) * features + f;
    out->ptr<float>()[i] = values[static_cast<size_t>(f)];
  }
}

TEST(Letterbox, GivenVgaInto64ThenScaleIsATenthWith8GreyRowsAboveAndBelowAndTheInverseIsExact) {
  const Letterbox lb = vga_into_64();
  EXPECT_EQ(lb.resized_size_px, cv::Size(64, 48));
  EXPECT_DOUBLE_EQ(lb.scale_x, 0.1);
  EXPECT_DOUBLE_EQ(lb.scale_y, 0.1);
  EXPECT_EQ(lb.pad_left_px, 0);
  EXPECT_EQ(lb.pad_top_px, 8);
  // Model (20, 28) is image ((20 - 0) / 0.1, (28 - 8) / 0.1).
  const cv::Point2d p = lb.model_to_image(cv::Point2d(20.0, 28.0));
  EXPECT_NEAR(p.x, 200.0, 1e-9);
  EXPECT_NEAR(p.y, 200.0, 1e-9);
  const cv::Point2d q = lb.model_to_image(lb.image_to_model(cv::Point2d(123.25, 456.5)));
  EXPECT_NEAR(q.x, 123.25, 1e-9);
  EXPECT_NEAR(q.y, 456.5, 1e-9);

  // Portrait: the grey columns are left and right; an odd spare pixel goes right (Ultralytics).
  auto portrait = make_letterbox(cv::Size(480, 640), cv::Size(64, 64));
  ASSERT_TRUE(portrait.ok());
  EXPECT_EQ(portrait->pad_left_px, 8);
  EXPECT_EQ(portrait->pad_top_px, 0);
  auto odd = make_letterbox(cv::Size(100, 51), cv::Size(64, 64));  // 64 x round(32.64) = 33: 31 spare rows
  ASSERT_TRUE(odd.ok());
  EXPECT_EQ(odd->resized_size_px, cv::Size(64, 33));
  EXPECT_EQ(odd->pad_top_px, 15);
  EXPECT_DOUBLE_EQ(odd->scale_y, 33.0 / 51.0);

  EXPECT_FALSE(make_letterbox(cv::Size(0, 480), cv::Size(64, 64)).ok());
  EXPECT_FALSE(make_letterbox(cv::Size(640, 480), cv::Size(64, -1)).ok());
}

TEST(Letterbox, GivenAPureRedImageThenTheBlobIsRgbInZeroToOneWithGreyRowsAt114Over255) {
  const Letterbox lb = vga_into_64();
  const cv::Mat red(480, 640, CV_8UC3, cv::Scalar(0, 0, 255));  // BGR
  cv::Mat letterboxed, blob;
  ASSERT_TRUE(letterbox_blob(red, lb, &letterboxed, &blob).ok());
  ASSERT_EQ(blob.dims, 4);
  EXPECT_EQ(blob.size[0], 1);
  EXPECT_EQ(blob.size[1], 3);
  EXPECT_EQ(blob.size[2], 64);
  EXPECT_EQ(blob.size[3], 64);
  const auto at = [&](int c, int y, int x) { return blob.ptr<float>(0, c)[y * 64 + x]; };
  const float grey = 114.0f / 255.0f;
  for (int x = 0; x < 64; x += 9) {
    for (int y : {0, 7, 56, 63}) {  // the grey rows
      for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(at(c, y, x), grey) << c << " " << y << " " << x;
    }
    for (int y : {8, 30, 55}) {  // the image: R first
      EXPECT_FLOAT_EQ(at(0, y, x), 1.0f);
      EXPECT_FLOAT_EQ(at(1, y, x), 0.0f);
      EXPECT_FLOAT_EQ(at(2, y, x), 0.0f);
    }
  }
  // The buffers are reused: same memory on a second call.
  const float* blob_data = blob.ptr<float>();
  ASSERT_TRUE(letterbox_blob(red, lb, &letterboxed, &blob).ok());
  EXPECT_EQ(blob.ptr<float>(), blob_data);

  const cv::Mat gray(480, 640, CV_8UC1, cv::Scalar(0));
  const cv::Mat small(240, 320, CV_8UC3, cv::Scalar(0));
  EXPECT_EQ(letterbox_blob(gray, lb, &letterboxed, &blob).code(), core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(letterbox_blob(small, lb, &letterboxed, &blob).code(), core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(letterbox_blob(cv::Mat(), lb, &letterboxed, &blob).code(), core::ErrorCode::kInvalidArgument);
}

TEST(YoloHead, GivenEachLayoutsShapeThenItIsRecognisedAndOtherShapesAreRejectedNamingTheShape) {
  struct Case {
    std::vector<int> shape;
    int classes;
    bool ok;
    YoloHeadLayout layout;
    int candidates;
  };
  const std::vector<Case> cases = {
      {{1, 300, 6}, 2, true, YoloHeadLayout::kEndToEnd, 300},
      {{1, 300, 6}, 3, true, YoloHeadLayout::kEndToEnd, 300},
      {{1, 6, 8400}, 2, true, YoloHeadLayout::kRawChannelsFirst, 8400},
      {{1, 7, 8400}, 3, true, YoloHeadLayout::kRawChannelsFirst, 8400},
      {{1, 8400, 7}, 3, true, YoloHeadLayout::kRawChannelsLast, 8400},
      {{1, 5, 100}, 1, true, YoloHeadLayout::kRawChannelsFirst, 100},
      {{1, 6, 6}, 2, false, {}, 0},  // end-to-end with 6 rows or raw with 6 anchors: ambiguous
      {{1, 7, 6}, 3, false, {}, 0},  // end-to-end with 7 rows or raw with 6 anchors: ambiguous
      {{1, 7, 5}, 2, false, {}, 0},
      {{1, 300}, 2, false, {}, 0},
      {{2, 300, 6}, 2, false, {}, 0},
      {{1, 1, 300, 6}, 2, false, {}, 0},
      {{1, 0, 6}, 2, false, {}, 0},
      {{1, 300, 6}, 0, false, {}, 0},
  };
  for (const Case& c : cases) {
    const auto head = yolo_head_from_shape(c.shape, c.classes);
    ASSERT_EQ(head.ok(), c.ok) << shape_text(c.shape) << " " << c.classes;
    if (c.ok) {
      EXPECT_EQ(head->layout, c.layout) << shape_text(c.shape);
      EXPECT_EQ(head->candidates, c.candidates);
      EXPECT_EQ(head->classes, c.classes);
    } else {
      EXPECT_EQ(head.status().code(), core::ErrorCode::kInvalidArgument);
      if (c.classes > 0) {
        EXPECT_NE(head.status().message().find(shape_text(c.shape)), std::string::npos)
            << head.status().message();
      }
    }
  }
  EXPECT_NE(yolo_head_from_shape({1, 6, 6}, 2).status().message().find("ambiguous"), std::string::npos);
  EXPECT_NE(yolo_head_from_shape({1, 7, 5}, 2).status().message().find("expected [1, K, 6]"),
            std::string::npos);
}

TEST(YoloDecode, GivenEndToEndRowsThenEachBoxAboveTheThresholdComesOutInImagePixelsBestFirst) {
  const Letterbox lb = vga_into_64();
  const YoloHead head{YoloHeadLayout::kEndToEnd, 300, 2};
  cv::Mat out = blob3(300, 6);
  set_row(&out, 0, {20, 20, 40, 36, 0.6f, 0});           // image (200, 120) - (400, 280)
  set_row(&out, 1, {4, 12, 14, 22, 0.9f, 1});            // image (40, 40) - (140, 140)
  set_row(&out, 2, {44, 30, 60, 50, 0.1f, 0});           // below 0.25
  set_row(&out, 3, {30, 58, 40, 63, 0.8f, 0});           // in the grey rows: outside the image
  set_row(&out, 4, {-5, 50, 10, 70, 0.7f, 0});           // partly out: clipped to (0, 420) - (100, 480)
  set_row(&out, 5, {10, 10, 20, 20, 0.95f, 2});          // class 2 of 2: bad
  set_row(&out, 6, {10, 10, 20, 20, 0.95f, 0.5f});       // not an integer class: bad
  set_row(&out, 7, {10, 10, 20, 20, std::nanf(""), 0});  // NaN score: never above
  // Rows 8..299 are zero: score 0 < 0.25.
  std::vector<ImageBox> boxes;
  YoloDecodeStats stats;
  ASSERT_TRUE(decode_yolo(out, head, lb, YoloDecodeConfig{}, &boxes, &stats).ok());
  ASSERT_EQ(boxes.size(), 3u);
  expect_box(boxes[0], 40, 40, 140, 140, 1, 0.9f);
  expect_box(boxes[1], 0, 420, 100, 480, 0, 0.7f);
  expect_box(boxes[2], 200, 120, 400, 280, 0, 0.6f);
  EXPECT_EQ(stats.above_threshold, 6);
  EXPECT_EQ(stats.bad_class, 2);
  EXPECT_EQ(stats.outside, 1);
  EXPECT_EQ(stats.suppressed, 0);

  // Overlapping end-to-end rows are kept: the head is NMS-free.
  set_row(&out, 2, {21, 20, 41, 36, 0.5f, 0});
  ASSERT_TRUE(decode_yolo(out, head, lb, YoloDecodeConfig{}, &boxes, &stats).ok());
  EXPECT_EQ(boxes.size(), 4u);

  // A higher threshold and max_boxes.
  YoloDecodeConfig strict;
  strict.score_threshold = 0.65f;
  ASSERT_TRUE(decode_yolo(out, head, lb, strict, &boxes, &stats).ok());
  EXPECT_EQ(boxes.size(), 2u);
  YoloDecodeConfig one;
  one.max_boxes = 1;
  ASSERT_TRUE(decode_yolo(out, head, lb, one, &boxes, &stats).ok());
  ASSERT_EQ(boxes.size(), 1u);
  EXPECT_FLOAT_EQ(boxes[0].score, 0.9f);
}

TEST(YoloDecode, GivenRawAnchorsThenNmsRemovesTheOverlappingBoxOfTheSameClassAndKeepsTheOtherClasses) {
  const Letterbox lb = vga_into_64();
  for (const bool channels_first : {true, false}) {
    // 3 classes: [1, 7, 10] or [1, 10, 7] (with 2 classes [1, N, 6] would read as end-to-end).
    const YoloHead head{channels_first ? YoloHeadLayout::kRawChannelsFirst : YoloHeadLayout::kRawChannelsLast,
                        10, 3};
    cv::Mat out = channels_first ? blob3(7, 10) : blob3(10, 7);
    // A: (20, 20) - (40, 36), class 0. B: shifted 1 px, IoU (19 * 16) / (2 * 320 - 304) = 0.905, class 0,
    // less confident: suppressed. C: as B, class 2: kept. D: (0, 8) - (10, 18), class 1: kept.
    // E: shifted 10 px from A, IoU (10 * 16) / (2 * 320 - 160) = 0.333 < 0.45, class 0: kept.
    set_anchor(&out, channels_first, 0, {30, 28, 20, 16, 0.9f, 0.1f, 0.0f});
    set_anchor(&out, channels_first, 1, {31, 28, 20, 16, 0.8f, 0.0f, 0.1f});
    set_anchor(&out, channels_first, 2, {31, 28, 20, 16, 0.1f, 0.0f, 0.7f});
    set_anchor(&out, channels_first, 3, {5, 13, 10, 10, 0.0f, 0.6f, 0.0f});
    set_anchor(&out, channels_first, 4, {40, 28, 20, 16, 0.5f, 0.0f, 0.0f});
    set_anchor(&out, channels_first, 5, {40, 28, 20, 16, 0.2f, 0.1f, 0.0f});  // below 0.25
    std::vector<ImageBox> boxes;
    YoloDecodeStats stats;
    ASSERT_TRUE(decode_yolo(out, head, lb, YoloDecodeConfig{}, &boxes, &stats).ok());
    ASSERT_EQ(boxes.size(), 4u) << channels_first;
    expect_box(boxes[0], 200, 120, 400, 280, 0, 0.9f);
    expect_box(boxes[1], 210, 120, 410, 280, 2, 0.7f);
    expect_box(boxes[2], 0, 0, 100, 100, 1, 0.6f);
    expect_box(boxes[3], 300, 120, 500, 280, 0, 0.5f);
    EXPECT_EQ(stats.above_threshold, 5);
    EXPECT_EQ(stats.suppressed, 1);

    // A looser IoU threshold (0.3) also removes E (IoU 0.333 with A).
    YoloDecodeConfig loose;
    loose.nms_iou = 0.3f;
    ASSERT_TRUE(decode_yolo(out, head, lb, loose, &boxes, &stats).ok());
    EXPECT_EQ(boxes.size(), 3u);
    EXPECT_EQ(stats.suppressed, 2);
  }
}

TEST(YoloDecode, GivenAnOutputNotOfTheHeadsShapeOrTypeOrABadConfigThenInvalidArgument) {
  const Letterbox lb = vga_into_64();
  const YoloHead head{YoloHeadLayout::kEndToEnd, 300, 2};
  std::vector<ImageBox> boxes;
  const auto code = [&](const cv::Mat& out, const YoloDecodeConfig& c) {
    return decode_yolo(out, head, lb, c, &boxes).code();
  };
  EXPECT_EQ(code(blob3(300, 6), YoloDecodeConfig{}), core::ErrorCode::kOk);
  EXPECT_EQ(code(blob3(200, 6), YoloDecodeConfig{}), core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(code(blob3(6, 300), YoloDecodeConfig{}), core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(code(cv::Mat(300, 6, CV_32F, cv::Scalar(0)), YoloDecodeConfig{}),
            core::ErrorCode::kInvalidArgument);
  cv::Mat doubles;
  blob3(300, 6).convertTo(doubles, CV_64F);
  EXPECT_EQ(code(doubles, YoloDecodeConfig{}), core::ErrorCode::kInvalidArgument);
  YoloDecodeConfig bad;
  bad.nms_iou = 0.0f;
  EXPECT_EQ(code(blob3(300, 6), bad), core::ErrorCode::kInvalidArgument);
  bad = YoloDecodeConfig{};
  bad.max_boxes = 0;
  EXPECT_EQ(code(blob3(300, 6), bad), core::ErrorCode::kInvalidArgument);
  const std::string message = decode_yolo(blob3(200, 6), head, lb, YoloDecodeConfig{}, &boxes).message();
  EXPECT_NE(message.find("[1, 200, 6]"), std::string::npos) << message;
  EXPECT_NE(message.find("[1, 300, 6]"), std::string::npos) << message;
}

}  // namespace
}  // namespace hwr::detect
