// The model backends' shared post-processing (detect/model_postprocess.hpp) on hand-made head outputs:
// class ids map to seam kinds (0 fillet, 1 butt, others skipped), max_detections and the list's
// capacity bound the output. Oracles: the rows put in, a wall at a known depth.

#include <gtest/gtest.h>

#include "depth_render.hpp"
#include "hwr/detect/model_postprocess.hpp"

namespace hwr::detect {
namespace {

struct Fixture {
  hal::PinholeIntrinsics K = testing::vga_intrinsics();
  cv::Mat depth_m, bgr;
  KeyframeView view;
  Fixture() {
    depth_m = cv::Mat(K.height, K.width, CV_32FC1, cv::Scalar(1.5f));  // a wall at 1.5 m
    bgr = cv::Mat(K.height, K.width, CV_8UC3, cv::Scalar(0));
    view.K = K;
    view.bgr = &bgr;
    view.depth_m = &depth_m;
  }
};

cv::Mat end_to_end(const std::vector<std::vector<float>>& rows) {
  const int dims[3] = {1, 300, 6};
  cv::Mat out(3, dims, CV_32F, cv::Scalar(0.0f));
  for (size_t k = 0; k < rows.size(); ++k) {
    for (int c = 0; c < 6; ++c)
      out.ptr<float>()[k * 6 + static_cast<size_t>(c)] = rows[k][static_cast<size_t>(c)];
  }
  return out;
}

ModelPostprocess make_post(const ModelDetectorConfig& c, int classes) {
  auto p = ModelPostprocess::create(c, YoloHead{YoloHeadLayout::kEndToEnd, 300, classes},
                                    testing::vga_intrinsics());
  EXPECT_TRUE(p.ok()) << p.status().message();
  return std::move(p.value());
}

TEST(ModelPostprocess, GivenClassIdsZeroOneAndTwoThenFilletButtAndTheThirdSkippedAsNotASeam) {
  Fixture f;
  ModelDetectorConfig c;
  c.input_size_px = 64;
  c.class_names = {"fillet", "butt", "bead"};
  ModelPostprocess post = make_post(c, 3);
  const cv::Mat out =
      end_to_end({{20, 20, 40, 36, 0.9f, 2}, {20, 20, 40, 36, 0.8f, 1}, {4, 12, 14, 22, 0.7f, 0}});
  DetectionList list(8);
  ModelDetectorStats stats;
  ASSERT_TRUE(post.run(out, f.view, &list, &stats).ok());
  ASSERT_EQ(list.size(), 2);
  EXPECT_EQ(list[0].kind, SeamKind::kButt);
  EXPECT_FLOAT_EQ(list[0].confidence, 0.8f);
  EXPECT_EQ(list[1].kind, SeamKind::kFillet);
  EXPECT_NEAR(list[1].T_cam_box.translation().z(), 1.5, 1e-6);
  EXPECT_EQ(stats.boxes, 3);
  EXPECT_EQ(stats.not_a_seam, 1);
  EXPECT_EQ(stats.lifted, 2);
}

TEST(ModelPostprocess, GivenMoreBoxesThanWantedThenMaxDetectionsAndTheListsCapacityBoundTheOutput) {
  Fixture f;
  ModelDetectorConfig c;
  c.input_size_px = 64;
  c.max_detections = 2;
  ModelPostprocess post = make_post(c, 2);
  const cv::Mat out = end_to_end({{20, 20, 40, 36, 0.9f, 0},
                                  {4, 12, 14, 22, 0.8f, 1},
                                  {44, 30, 60, 50, 0.7f, 0},
                                  {4, 30, 14, 40, 0.6f, 1}});
  DetectionList list(8);
  ModelDetectorStats stats;
  ASSERT_TRUE(post.run(out, f.view, &list, &stats).ok());
  ASSERT_EQ(list.size(), 2);
  EXPECT_FLOAT_EQ(list[0].confidence, 0.9f);
  EXPECT_FLOAT_EQ(list[1].confidence, 0.8f);
  DetectionList one(1);
  c.max_detections = 16;
  ModelPostprocess roomy = make_post(c, 2);
  ASSERT_TRUE(roomy.run(out, f.view, &one, &stats).ok());
  ASSERT_EQ(one.size(), 1);
  EXPECT_FLOAT_EQ(one[0].confidence, 0.9f);
}

TEST(ModelPostprocess, GivenAHeadWhoseClassCountIsNotTheConfigsThenCreateFails) {
  ModelDetectorConfig c;  // two class names
  const auto p =
      ModelPostprocess::create(c, YoloHead{YoloHeadLayout::kEndToEnd, 300, 3}, testing::vga_intrinsics());
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(p.status().code(), core::ErrorCode::kInvalidArgument);
}

}  // namespace
}  // namespace hwr::detect
