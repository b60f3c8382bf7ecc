// Side-by-side YUYV split (hal/hw/side_by_side.hpp). Oracles: cv::cvtColor on each half copied out
// into its own continuous image (pixel-exact, gray and BGR), and the YUYV definition itself (gray =
// the Y bytes). Checked with padded strides, at the ZED's real sizes, in place in preallocated (and
// ROI) outputs without reallocation; every short buffer and every malformed geometry refused.
#include "hwr/hal/hw/side_by_side.hpp"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace hwr::hal::hw {
namespace {

// A random side-by-side frame: width_px × height, stride ≥ 2·width_px bytes (padding filled with
// junk, which must never leak into the eyes).
struct Frame {
  std::vector<uint8_t> bytes;
  YuyvFrameView view;
};

Frame random_frame(int width_px, int height, size_t stride, uint32_t seed) {
  Frame f;
  f.bytes.resize(stride * static_cast<size_t>(height));
  std::mt19937 rng(seed);
  for (auto& b : f.bytes) b = static_cast<uint8_t>(rng());
  f.view = {f.bytes.data(), f.bytes.size(), width_px, height, stride};
  return f;
}

// The oracle: one half copied into its own continuous CV_8UC2 image, row by row from the bytes.
cv::Mat half_copy(const Frame& f, bool right) {
  const int eye_w = f.view.width_px / 2;
  cv::Mat half(f.view.height_px, eye_w, CV_8UC2);
  for (int y = 0; y < f.view.height_px; ++y) {
    const uint8_t* row =
        f.bytes.data() + static_cast<size_t>(y) * f.view.stride_bytes + (right ? eye_w * 2 : 0);
    std::copy(row, row + eye_w * 2, half.ptr<uint8_t>(y));
  }
  return half;
}

bool identical(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

void expect_split_matches_oracle(const Frame& f) {
  cv::Mat left_gray, right_gray, left_bgr;
  ASSERT_TRUE(split_side_by_side_yuyv(f.view, &left_gray, &right_gray, &left_bgr).ok());
  cv::Mat want_left_gray, want_right_gray, want_left_bgr;
  cv::cvtColor(half_copy(f, false), want_left_gray, cv::COLOR_YUV2GRAY_YUYV);
  cv::cvtColor(half_copy(f, true), want_right_gray, cv::COLOR_YUV2GRAY_YUYV);
  cv::cvtColor(half_copy(f, false), want_left_bgr, cv::COLOR_YUV2BGR_YUYV);
  EXPECT_TRUE(identical(left_gray, want_left_gray));
  EXPECT_TRUE(identical(right_gray, want_right_gray));
  EXPECT_TRUE(identical(left_bgr, want_left_bgr));
  // Gray is YUYV's luma: every even byte of the row, left eye from the left half.
  const int eye_w = f.view.width_px / 2;
  for (int y = 0; y < f.view.height_px; y += std::max(1, f.view.height_px / 7)) {
    const uint8_t* row = f.bytes.data() + static_cast<size_t>(y) * f.view.stride_bytes;
    for (int x = 0; x < eye_w; ++x) {
      ASSERT_EQ(left_gray.at<uint8_t>(y, x), row[2 * x]) << y << "," << x;
      ASSERT_EQ(right_gray.at<uint8_t>(y, x), row[2 * (eye_w + x)]) << y << "," << x;
    }
  }
}

TEST(SideBySide, GivenRandomFramesWithPaddedStridesThenEachEyeMatchesCvtColorOnItsOwnHalf) {
  struct Case {
    int width_px, height;
    size_t stride;
  };
  for (const Case& c : {Case{8, 4, 16}, Case{8, 3, 40}, Case{12, 5, 24}, Case{16, 2, 33}, Case{4, 1, 8},
                        Case{64, 17, 256}, Case{1344, 9, 2688}, Case{1344, 9, 2688 + 64}}) {
    SCOPED_TRACE(std::to_string(c.width_px) + "x" + std::to_string(c.height) + " stride " +
                 std::to_string(c.stride));
    expect_split_matches_oracle(
        random_frame(c.width_px, c.height, c.stride, 17u + static_cast<uint32_t>(c.stride)));
  }
}

TEST(SideBySide, GivenTheZedVgaModeThenTheSplitIsPixelExact) {
  // hardware.md: 672x376 per eye, so the frame is 1344x376, 2688 bytes a row.
  expect_split_matches_oracle(random_frame(1344, 376, 2688, 3));
}

TEST(SideBySide, GivenDifferentEyesThenTheLeftEyeComesFromTheLeftHalf) {
  Frame f = random_frame(16, 4, 32, 1);
  for (int y = 0; y < 4; ++y) {
    for (int x = 0; x < 16; ++x) {
      f.bytes[static_cast<size_t>(y) * 32 + 2 * static_cast<size_t>(x)] = x < 8 ? 50 : 200;  // Y
      f.bytes[static_cast<size_t>(y) * 32 + 2 * static_cast<size_t>(x) + 1] = 128;           // U/V: no chroma
    }
  }
  cv::Mat l, r, bgr;
  ASSERT_TRUE(split_side_by_side_yuyv(f.view, &l, &r, &bgr).ok());
  EXPECT_EQ(cv::countNonZero(l != 50), 0);
  EXPECT_EQ(cv::countNonZero(r != 200), 0);
  // Neutral chroma: B = G = R; BT.601 video range maps Y = 50 to about (50 − 16) · 255 / 219 ≈ 40.
  const cv::Vec3b p = bgr.at<cv::Vec3b>(2, 3);
  EXPECT_EQ(p[0], p[1]);
  EXPECT_EQ(p[1], p[2]);
  EXPECT_NEAR(p[0], 40, 2);
}

TEST(SideBySide, GivenPreallocatedOutputsThenTheyAreFilledInPlaceWithoutReallocation) {
  const Frame a = random_frame(64, 8, 128, 1);
  const Frame b = random_frame(64, 8, 128, 2);
  cv::Mat l(8, 32, CV_8UC1), r(8, 32, CV_8UC1), bgr(8, 32, CV_8UC3);
  const uint8_t* const l_data = l.data;
  const uint8_t* const r_data = r.data;
  const uint8_t* const bgr_data = bgr.data;
  for (const Frame* f : {&a, &b, &a}) {
    ASSERT_TRUE(split_side_by_side_yuyv(f->view, &l, &r, &bgr).ok());
    EXPECT_EQ(l.data, l_data);
    EXPECT_EQ(r.data, r_data);
    EXPECT_EQ(bgr.data, bgr_data);
  }
  cv::Mat want;
  cv::cvtColor(half_copy(a, true), want, cv::COLOR_YUV2GRAY_YUYV);
  EXPECT_TRUE(identical(r, want));
}

TEST(SideBySide, GivenOutputsThatAreRoisOfALargerImageThenOnlyTheRoiIsWritten) {
  const Frame f = random_frame(32, 6, 64, 9);
  cv::Mat canvas(10, 40, CV_8UC1, cv::Scalar(7));
  cv::Mat left_roi = canvas(cv::Rect(2, 1, 16, 6));
  cv::Mat right_roi = canvas(cv::Rect(20, 3, 16, 6));
  ASSERT_TRUE(split_side_by_side_yuyv(f.view, &left_roi, &right_roi, nullptr).ok());
  EXPECT_EQ(left_roi.data, canvas.ptr<uint8_t>(1) + 2);  // still a view into the canvas
  cv::Mat want;
  cv::cvtColor(half_copy(f, false), want, cv::COLOR_YUV2GRAY_YUYV);
  EXPECT_TRUE(identical(canvas(cv::Rect(2, 1, 16, 6)), want));
  EXPECT_EQ(canvas.at<uint8_t>(0, 0), 7);
  EXPECT_EQ(canvas.at<uint8_t>(9, 39), 7);
  EXPECT_EQ(canvas.at<uint8_t>(1, 18), 7);  // between the two ROIs
}

TEST(SideBySide, GivenNullOutputsThenTheyAreSkipped) {
  const Frame f = random_frame(16, 4, 32, 4);
  cv::Mat bgr;
  ASSERT_TRUE(split_side_by_side_yuyv(f.view, nullptr, nullptr, &bgr).ok());
  EXPECT_EQ(bgr.size(), cv::Size(8, 4));
  EXPECT_EQ(bgr.type(), CV_8UC3);
  EXPECT_TRUE(split_side_by_side_yuyv(f.view, nullptr, nullptr, nullptr).ok());
}

TEST(SideBySide, GivenAnOddEyeWidthOrAnOddFrameWidthThenInvalidArgument) {
  for (int width : {6, 10, 1342, 7, 9, 1}) {
    const Frame f = random_frame(width, 4, 2 * static_cast<size_t>(width) + 2, 5);
    cv::Mat l, r;
    const core::Status st = split_side_by_side_yuyv(f.view, &l, &r, nullptr);
    ASSERT_FALSE(st.ok()) << width;
    EXPECT_EQ(st.code(), core::ErrorCode::kInvalidArgument);
    EXPECT_NE(st.message().find("eye width must be even"), std::string::npos) << st.message();
    EXPECT_TRUE(l.empty() && r.empty());  // nothing allocated for a refused frame
  }
}

TEST(SideBySide, GivenANonPositiveSizeOrAShortStrideThenInvalidArgument) {
  Frame f = random_frame(16, 4, 32, 6);
  cv::Mat l;
  for (auto [w, h] : {std::pair{0, 4}, std::pair{16, 0}, std::pair{-16, 4}, std::pair{16, -1}}) {
    YuyvFrameView v = f.view;
    v.width_px = w;
    v.height_px = h;
    EXPECT_EQ(split_side_by_side_yuyv(v, &l, nullptr, nullptr).code(), core::ErrorCode::kInvalidArgument);
  }
  YuyvFrameView v = f.view;
  v.stride_bytes = 31;  // one byte less than a 16-pixel YUYV row
  const core::Status st = split_side_by_side_yuyv(v, &l, nullptr, nullptr);
  EXPECT_EQ(st.code(), core::ErrorCode::kInvalidArgument);
  EXPECT_NE(st.message().find("stride 31"), std::string::npos) << st.message();
}

TEST(SideBySide, GivenEveryShortBufferThenCorruptDataAndTheExactSizeWithoutLastRowPaddingIsEnough) {
  // 16x4 frame, stride 40: needs 3·40 + 32 = 152 bytes (the last row's padding is not required).
  const Frame f = random_frame(16, 4, 40, 7);
  cv::Mat l, r, bgr;
  for (size_t n = 0; n < 152; ++n) {
    std::vector<uint8_t> exact(f.bytes.begin(), f.bytes.begin() + static_cast<std::ptrdiff_t>(n));
    YuyvFrameView v = f.view;
    v.data = exact.data();
    v.size_bytes = n;
    const core::Status st = split_side_by_side_yuyv(v, &l, &r, &bgr);
    ASSERT_FALSE(st.ok()) << n;
    EXPECT_EQ(st.code(), core::ErrorCode::kCorruptData);
    EXPECT_NE(st.message().find("needs 152"), std::string::npos) << st.message();
  }
  std::vector<uint8_t> exact(f.bytes.begin(), f.bytes.begin() + 152);  // ASan: nothing read past it
  YuyvFrameView v = f.view;
  v.data = exact.data();
  v.size_bytes = exact.size();
  ASSERT_TRUE(split_side_by_side_yuyv(v, &l, &r, &bgr).ok());
  cv::Mat want;
  cv::cvtColor(half_copy(f, true), want, cv::COLOR_YUV2GRAY_YUYV);
  EXPECT_TRUE(identical(r, want));
  v.data = nullptr;
  EXPECT_EQ(split_side_by_side_yuyv(v, &l, &r, &bgr).code(), core::ErrorCode::kCorruptData);
}

TEST(SideBySide, GivenOutputsSizedForAnotherModeThenInvalidArgumentAndTheyAreLeftAlone) {
  const Frame f = random_frame(32, 6, 64, 8);
  struct Case {
    cv::Mat l, r, bgr;
    const char* says;
  };
  std::vector<Case> cases;
  cases.push_back({cv::Mat(6, 15, CV_8UC1, cv::Scalar(3)), cv::Mat(), cv::Mat(), "left gray image is 15x6"});
  cases.push_back({cv::Mat(), cv::Mat(7, 16, CV_8UC1, cv::Scalar(3)), cv::Mat(), "right gray image is 16x7"});
  cases.push_back(
      {cv::Mat(), cv::Mat(), cv::Mat(6, 16, CV_8UC1, cv::Scalar(3)), "left BGR image is 16x6 type 0"});
  cases.push_back(
      {cv::Mat(6, 16, CV_8UC3, cv::Scalar(3)), cv::Mat(), cv::Mat(), "left gray image is 16x6 type 16"});
  for (Case& c : cases) {
    const cv::Mat l0 = c.l.clone(), r0 = c.r.clone(), b0 = c.bgr.clone();
    const core::Status st = split_side_by_side_yuyv(f.view, &c.l, &c.r, &c.bgr);
    ASSERT_FALSE(st.ok()) << c.says;
    EXPECT_EQ(st.code(), core::ErrorCode::kInvalidArgument);
    EXPECT_NE(st.message().find(c.says), std::string::npos) << st.message();
    // Untouched: the sized ones keep their pixels, the empty ones stay empty.
    EXPECT_TRUE(l0.empty() ? c.l.empty() : identical(c.l, l0));
    EXPECT_TRUE(r0.empty() ? c.r.empty() : identical(c.r, r0));
    EXPECT_TRUE(b0.empty() ? c.bgr.empty() : identical(c.bgr, b0));
  }
}

TEST(SideBySide, GivenTheSameImageForTwoOutputsThenInvalidArgument) {
  const Frame f = random_frame(16, 4, 32, 9);
  cv::Mat m;
  EXPECT_EQ(split_side_by_side_yuyv(f.view, &m, &m, nullptr).code(), core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(split_side_by_side_yuyv(f.view, &m, nullptr, &m).code(), core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(split_side_by_side_yuyv(f.view, nullptr, &m, &m).code(), core::ErrorCode::kInvalidArgument);
}

}  // namespace
}  // namespace hwr::hal::hw
