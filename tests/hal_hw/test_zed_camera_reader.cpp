// ZedCameraReader against FakeUvcDevice (uvcvideo played by the test) and an ideal SN.conf at the VGA
// mode (672x376 per eye, hardware.md: fx = 350 px, no distortion worth the name, identical parallel
// eyes 120 mm apart). The scene is a fronto-parallel plane of random colour blocks at Z = 1 m, seen by
// the right eye shifted by d = fx·B/Z = 42 px, written into the side-by-side YUYV buffer with the
// BT.601 studio-range encoding that OpenCV's COLOR_YUV2BGR_YUYV inverts. The oracle: the plane's
// depth (within one pixel of disparity), the input colours (within the YUYV rounding), the V4L2
// buffer's timestamp and sequence. Also: open() errors naming the file or device, every dequeued
// frame's stamp reported (kept or dropped) and the counters, unplug → reopen on the backoff clock.
#include "hwr/hal/hw/zed_camera_reader.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "../temp_dir.hpp"
#include "fake_uvc_device.hpp"

namespace hwr::hal::hw {
namespace {

using test::FakeUvcDevice;
using test::good;

constexpr int kEyeW = 672;  // hardware.md: the VGA mode, 672x376 per eye
constexpr int kEyeH = 376;
constexpr double kF = 350.0;          // px
constexpr double kBaselineM = 0.120;  // SN.conf Baseline = 120 mm
constexpr double kPlaneZ = 1.0;       // m
constexpr int kDisparity = 42;        // fx·B/Z = 350 · 0.12 / 1.0, exactly
constexpr int kBlock = 4;             // colour blocks of 4x4 px: texture for the matcher
constexpr int kNumDisparities = 64;   // StereoSgbmParams default: columns left of it cannot match

// An ideal VGA calibration. k1 = 1e-9 rather than 0: a file with k1 = k2 = 0 for both eyes is
// rejected as the comma-locale bug (hardware.md); 1e-9 moves no pixel by more than 1e-8 px.
std::string ideal_conf() {
  const std::string cam = "fx=350\nfy=350\ncx=336\ncy=188\nk1=1e-9\nk2=0\np1=0\np2=0\nk3=0\n\n";
  return "[LEFT_CAM_VGA]\n" + cam + "[RIGHT_CAM_VGA]\n" + cam +
         "[STEREO]\nBaseline=120\nTY_VGA=0\nTZ_VGA=0\nCV_VGA=0\nRX_VGA=0\nRZ_VGA=0\n";
}

struct Yuv {
  uint8_t y, u, v;
};

uint8_t clamp_round(double x) { return static_cast<uint8_t>(std::clamp(std::lround(x), 0L, 255L)); }

// ITU-R BT.601 studio range (Y 16..235, Cb/Cr 16..240), the inverse of what OpenCV's
// COLOR_YUV2BGR_YUYV computes (R = 1.164(Y−16) + 1.596(V−128), ...).
Yuv to_yuv(const cv::Vec3b& bgr) {
  const double b = bgr[0], g = bgr[1], r = bgr[2];
  return {clamp_round(16 + (65.481 * r + 128.553 * g + 24.966 * b) / 255.0),
          clamp_round(128 + (-37.797 * r - 74.203 * g + 112.0 * b) / 255.0),
          clamp_round(128 + (112.0 * r - 93.786 * g - 18.214 * b) / 255.0)};
}

// Both eyes side by side as a YUYV buffer (stride = 2 bytes x 2·kEyeW, as the fake grants): per pixel
// pair Y0 U Y1 V, the chroma of the pair's average (4:2:2).
std::vector<uint8_t> side_by_side_yuyv(const cv::Mat& left_bgr, const cv::Mat& right_bgr) {
  const size_t stride = size_t{2} * 2 * kEyeW;
  std::vector<uint8_t> buf(stride * kEyeH);
  for (int eye = 0; eye < 2; ++eye) {
    const cv::Mat& img = eye == 0 ? left_bgr : right_bgr;
    for (int y = 0; y < kEyeH; ++y) {
      uint8_t* row =
          buf.data() + stride * static_cast<size_t>(y) + size_t{2} * kEyeW * static_cast<size_t>(eye);
      for (int x = 0; x < kEyeW; x += 2) {
        const Yuv a = to_yuv(img.at<cv::Vec3b>(y, x));
        const Yuv b = to_yuv(img.at<cv::Vec3b>(y, x + 1));
        uint8_t* p = row + 2 * x;
        p[0] = a.y;
        p[1] = static_cast<uint8_t>((a.u + b.u + 1) / 2);
        p[2] = b.y;
        p[3] = static_cast<uint8_t>((a.v + b.v + 1) / 2);
      }
    }
  }
  return buf;
}

// The plane: random colour blocks (each channel 30..225, so no YUV value clips), in the left eye at
// columns 0..W−1 of the texture and in the right eye at columns d..W−1+d (right(x) = left(x + d)). Block
// edges fall on even columns in both eyes (d is even), so no YUYV pixel pair straddles two colours.
struct Scene {
  cv::Mat left_bgr, right_bgr;
  std::vector<uint8_t> yuyv;
};

Scene plane_scene() {
  cv::Mat texture(kEyeH, kEyeW + kDisparity, CV_8UC3);
  cv::RNG rng(2024);
  for (int by = 0; by < texture.rows; by += kBlock) {
    for (int bx = 0; bx < texture.cols; bx += kBlock) {
      const cv::Vec3b c(static_cast<uint8_t>(rng.uniform(30, 226)),
                        static_cast<uint8_t>(rng.uniform(30, 226)),
                        static_cast<uint8_t>(rng.uniform(30, 226)));
      texture(cv::Rect(bx, by, std::min(kBlock, texture.cols - bx), std::min(kBlock, texture.rows - by))) = c;
    }
  }
  Scene s;
  s.left_bgr = texture(cv::Rect(0, 0, kEyeW, kEyeH)).clone();
  s.right_bgr = texture(cv::Rect(kDisparity, 0, kEyeW, kEyeH)).clone();
  s.yuyv = side_by_side_yuyv(s.left_bgr, s.right_bgr);
  return s;
}

const Scene& scene() {
  static const Scene s = plane_scene();
  return s;
}

// A calibration file in a temp dir and a config that reads it, explicit device path.
class ZedCameraReaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::ofstream(dir_.file("SN12345.conf")) << ideal_conf();
    config_.camera.device = FakeUvcDevice::kPath;
    config_.camera.eye_width = kEyeW;
    config_.camera.eye_height = kEyeH;
    config_.camera.fps = 30;
    config_.camera.calibration = dir_.file("SN12345.conf");
    config_.camera.buffers = 4;
    config_.sysfs_root = dir_.file("sys");
    fake_.image = scene().yuyv;
    fake_.stamp_frames = false;  // keep the picture intact
  }

  std::unique_ptr<ZedCameraReader> open_reader() {
    auto r = ZedCameraReader::open(config_, fake_);
    EXPECT_TRUE(r.ok()) << r.status().to_string();
    return r.ok() ? std::move(r).value() : nullptr;
  }

  static SensorStreamsConfig streams_config(size_t pool, size_t ring) {
    SensorStreamsConfig c;
    c.width = kEyeW;  // the rectified size is the eye size
    c.height = kEyeH;
    c.stereo = true;
    c.frame_pool_size = pool;
    c.frame_capacity = ring;
    return c;
  }

  // The frame step() pushed, or a failure.
  static RgbdFrame* pop_frame(SensorStreams& s) {
    RgbdFrame* f = nullptr;
    EXPECT_TRUE(s.frames.try_pop(f)) << "no frame in the ring";
    return f;
  }

  testing::TempDir dir_{"hwr_zed_cam"};
  HwConfig config_;
  FakeUvcDevice fake_;
};

int64_t timeval_ns(int64_t sec, int64_t usec) { return sec * 1'000'000'000LL + usec * 1'000LL; }

TEST_F(ZedCameraReaderTest, GivenNoCalibrationFileThenOpenNamesItAndWhereToGetItWithoutTouchingTheCamera) {
  config_.camera.calibration = dir_.file("SN999.conf");
  auto r = ZedCameraReader::open(config_, fake_);
  ASSERT_FALSE(r.ok());
  const std::string m = r.status().message();
  EXPECT_NE(m.find("camera: "), std::string::npos) << m;
  EXPECT_NE(m.find(dir_.file("SN999.conf")), std::string::npos) << m;
  EXPECT_NE(m.find("calib.stereolabs.com"), std::string::npos) << m;
  EXPECT_TRUE(fake_.log.empty());
}

TEST_F(ZedCameraReaderTest, GivenACalibrationWithoutTheVgaModeThenOpenNamesTheMissingSection) {
  std::ofstream(dir_.file("SN12345.conf")) << "[LEFT_CAM_HD]\nfx=700\n";
  auto r = ZedCameraReader::open(config_, fake_);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), core::ErrorCode::kNotFound) << r.status().to_string();
  EXPECT_NE(r.status().message().find("LEFT_CAM_VGA"), std::string::npos) << r.status().message();
}

TEST_F(ZedCameraReaderTest, GivenNoSuchDeviceThenOpenNamesIt) {
  config_.camera.device = "/dev/video9";
  auto r = ZedCameraReader::open(config_, fake_);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), core::ErrorCode::kNotFound) << r.status().to_string();
  EXPECT_NE(r.status().message().find("camera: "), std::string::npos) << r.status().message();
  EXPECT_NE(r.status().message().find("/dev/video9"), std::string::npos) << r.status().message();
  EXPECT_FALSE(fake_.is_open);
}

TEST_F(ZedCameraReaderTest, GivenAutoAndNoZedInSysfsThenOpenSaysWhichUsbIdItLookedFor) {
  config_.camera.device = "auto";
  std::filesystem::create_directories(config_.sysfs_root + "/class/video4linux");
  auto r = ZedCameraReader::open(config_, fake_);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), core::ErrorCode::kNotFound) << r.status().to_string();
  EXPECT_NE(r.status().message().find("2b03:f880"), std::string::npos) << r.status().message();
  EXPECT_TRUE(fake_.log.empty());
}

TEST_F(ZedCameraReaderTest, GivenAutoThenTheZedsVideoNodeIsFoundInSysfsAndOpenedAtTheModesSize) {
  config_.camera.device = "auto";
  const std::filesystem::path node = std::filesystem::path(config_.sysfs_root) / "class/video4linux/video2";
  std::filesystem::create_directories(node / "device");
  std::ofstream(node / "device" / "modalias") << "usb:v2B03pF880d0100dcEFdsc02dp01ic0Eisc01ip00in00\n";
  std::ofstream(node / "index") << "0\n";
  auto reader = open_reader();
  ASSERT_NE(reader, nullptr);
  EXPECT_EQ(reader->device(), "/dev/video2");
  EXPECT_TRUE(fake_.streaming);
  EXPECT_EQ(fake_.asked_format.width, 2u * kEyeW) << "both eyes side by side";
  EXPECT_EQ(fake_.asked_format.height, static_cast<uint32_t>(kEyeH));
  EXPECT_EQ(fake_.asked_timeperframe.denominator, 30u);
}

TEST_F(ZedCameraReaderTest,
       GivenAPlaneAtOneMetreThenStepPushesItsDepthAndRectifiedColourWithTheBuffersStamp) {
  fake_.script.push_back(good(5, 100, 250'000));
  auto reader = open_reader();
  ASSERT_NE(reader, nullptr);
  // The ideal rig rectifies to itself: the pixel grids of input and output agree (to well under a
  // pixel), which is what lets the colours below be compared pixel for pixel.
  const PinholeIntrinsics& k = reader->rectified_intrinsics();
  EXPECT_EQ(k.width, kEyeW);
  EXPECT_EQ(k.height, kEyeH);
  EXPECT_NEAR(k.fx, kF, 0.005 * kF);
  EXPECT_NEAR(k.cx, 336.0, 1.0);
  EXPECT_NEAR(k.cy, 188.0, 1.0);
  EXPECT_TRUE(reader->T_cam_rect().isApprox(Eigen::Isometry3d::Identity(), 1e-9));

  SensorStreams streams(streams_config(2, 2));
  ASSERT_TRUE(reader->step(0, &streams, 0).ok());
  RgbdFrame* f = pop_frame(streams);
  ASSERT_NE(f, nullptr);
  EXPECT_FALSE(streams.frames.try_pop(f)) << "exactly one frame";

  // The stamp of the V4L2 buffer.
  EXPECT_EQ(f->t_ns, timeval_ns(100, 250'000));
  EXPECT_EQ(f->seq, 5u);
  EXPECT_EQ(f->intrinsics.fx, k.fx);
  ASSERT_EQ(f->bgr.type(), CV_8UC3);
  ASSERT_EQ(f->bgr.size(), cv::Size(kEyeW, kEyeH));
  ASSERT_EQ(f->depth_m.size(), cv::Size(kEyeW, kEyeH));
  ASSERT_EQ(f->right_gray.size(), cv::Size(kEyeW, kEyeH));

  // Depth: the plane at Z = fx·B/d. In the rectified frame d = fx'·B/Z, so one pixel of disparity
  // error is the band [fx'·B/(d'+1), fx'·B/(d'−1)]; SGBM's 1/16 px steps sit well inside it.
  const double d_rect = k.fx * kBaselineM / kPlaneZ;
  const double z_near = k.fx * kBaselineM / (d_rect + 1);
  const double z_far = k.fx * kBaselineM / (d_rect - 1);
  size_t valid = 0, in_band = 0, matchable = 0;
  std::vector<float> zs;
  for (int y = 0; y < kEyeH; ++y) {
    for (int x = 0; x < kEyeW; ++x) {
      const float z = f->depth_m.at<float>(y, x);
      if (x >= kNumDisparities) ++matchable;
      if (z == 0) continue;
      ++valid;
      zs.push_back(z);
      if (z >= z_near && z <= z_far) ++in_band;
    }
  }
  EXPECT_EQ(f->invalid_depth_px, static_cast<uint32_t>(f->depth_m.total() - valid));
  EXPECT_GT(valid, matchable * 9 / 10) << "most pixels right of the disparity range must match";
  EXPECT_GT(in_band, valid * 99 / 100) << "valid depth within one pixel of disparity of " << kPlaneZ << " m";
  ASSERT_FALSE(zs.empty());
  std::nth_element(zs.begin(), zs.begin() + static_cast<long>(zs.size() / 2), zs.end());
  EXPECT_NEAR(zs[zs.size() / 2], kPlaneZ, 0.005 * kPlaneZ);

  // Colour: every pixel of the central half whose 3x3 neighbourhood is one colour block must show
  // that colour again. YUYV rounding moves a channel by at most ~2 levels (Y to an integer: ±0.6,
  // U or V: up to ±1.0 through B = … + 2.018(U−128), OpenCV's fixed point: ±0.5), so 3 is the
  // tolerance. A gray image would miss by tens of levels.
  const cv::Rect centre(kEyeW / 4, kEyeH / 4, kEyeW / 2, kEyeH / 2);
  size_t compared = 0, chromatic = 0, lost_colour = 0;
  int worst = 0;
  for (int y = centre.y; y < centre.y + centre.height; ++y) {
    for (int x = centre.x; x < centre.x + centre.width; ++x) {
      const cv::Vec3b want = scene().left_bgr.at<cv::Vec3b>(y, x);
      bool uniform = true;
      for (int dy = -1; dy <= 1 && uniform; ++dy) {
        for (int dx = -1; dx <= 1 && uniform; ++dx)
          uniform = scene().left_bgr.at<cv::Vec3b>(y + dy, x + dx) == want;
      }
      if (!uniform) continue;
      ++compared;
      const cv::Vec3b got = f->bgr.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(int{got[c]} - int{want[c]}));
      // Where the input's channels differ strongly, the output's must differ the same way.
      if (std::abs(int{want[2]} - int{want[0]}) > 60) {
        ++chromatic;
        const bool same_way = (got[2] > got[0]) == (want[2] > want[0]);
        if (!same_way || std::abs(int{got[2]} - int{got[0]}) <= 50) ++lost_colour;
      }
    }
  }
  EXPECT_GT(compared, centre.area() / 10u);
  EXPECT_GT(chromatic, compared / 5);
  EXPECT_EQ(lost_colour, 0u) << "of " << chromatic << " pixels whose red and blue differ by > 60";
  EXPECT_LE(worst, 3);
  RecordProperty("valid_fraction_of_matchable",
                 std::to_string(static_cast<double>(valid) / static_cast<double>(matchable)));
  RecordProperty("in_band_fraction",
                 std::to_string(static_cast<double>(in_band) / static_cast<double>(valid)));
  RecordProperty("median_depth_m", std::to_string(zs[zs.size() / 2]));
  RecordProperty("rect_fx", std::to_string(k.fx));
  RecordProperty("colour_worst_error", worst);
  RecordProperty("colour_compared_px", std::to_string(compared));
  // The very centre.
  const cv::Point c(kEyeW / 2, kEyeH / 2);
  for (int ch = 0; ch < 3; ++ch) {
    EXPECT_NEAR(f->bgr.at<cv::Vec3b>(c)[ch], scene().left_bgr.at<cv::Vec3b>(c)[ch], 3) << "channel " << ch;
  }

  const ZedCameraCounters n = reader->counters();
  EXPECT_EQ(n.frames, 1u);
  EXPECT_EQ(n.pool_empty + n.ring_full + n.depth_errors + n.disconnects + n.reconnects + n.incomplete +
                n.driver_dropped + n.bad_timestamps + n.stamps_dropped,
            0u);
  streams.frame_pool.release(f);
}

TEST_F(ZedCameraReaderTest, GivenPooledFramesThenTheImagesAreWrittenInPlaceWithoutReallocating) {
  for (uint32_t s = 0; s < 3; ++s) fake_.script.push_back(good(s, 1, 33'333 * s));
  auto reader = open_reader();
  ASSERT_NE(reader, nullptr);
  SensorStreams streams(streams_config(1, 1));
  RgbdFrame* only = streams.frame_pool.acquire();
  const uint8_t* bgr = only->bgr.data;
  const uint8_t* depth = only->depth_m.data;
  const uint8_t* right = only->right_gray.data;
  streams.frame_pool.release(only);
  for (uint32_t s = 0; s < 3; ++s) {
    ASSERT_TRUE(reader->step(0, &streams, 0).ok());
    RgbdFrame* f = pop_frame(streams);
    ASSERT_EQ(f, only);
    EXPECT_EQ(f->seq, s);
    EXPECT_EQ(f->bgr.data, bgr);
    EXPECT_EQ(f->depth_m.data, depth);
    EXPECT_EQ(f->right_gray.data, right);
    streams.frame_pool.release(f);
  }
  EXPECT_EQ(reader->counters().frames, 3u);
}

TEST_F(ZedCameraReaderTest, GivenFrameStampsThenEveryDequeuedFrameIsReportedKeptOrDroppedAndCounted) {
  // Frames 10..15, 33.333 ms apart.
  for (uint32_t s = 10; s < 16; ++s) fake_.script.push_back(good(s, 7, 33'333 * (s - 10)));
  auto reader = open_reader();
  ASSERT_NE(reader, nullptr);
  core::SpscRing<CameraFrameStamp> stamps(5);
  reader->set_frame_stamps(&stamps);
  SensorStreams streams(streams_config(2, 1));  // two frames, one waiting at most

  // 10: pushed. 11: the ring is full (10 waits): dropped, its frame kept as the spare.
  ASSERT_TRUE(reader->step(0, &streams, 0).ok());
  ASSERT_TRUE(reader->step(0, &streams, 0).ok());
  EXPECT_EQ(reader->counters().frames, 1u);
  EXPECT_EQ(reader->counters().ring_full, 1u);
  // The pipeline takes 10 and holds it; 12 goes into the spare and is pushed.
  RgbdFrame* held10 = pop_frame(streams);
  ASSERT_NE(held10, nullptr);
  EXPECT_EQ(held10->seq, 10u);
  ASSERT_TRUE(reader->step(0, &streams, 0).ok());
  EXPECT_EQ(reader->counters().frames, 2u);
  // Now every frame is out (10 held, 12 waiting): 13 and 14 find the pool empty.
  ASSERT_TRUE(reader->step(0, &streams, 0).ok());
  ASSERT_TRUE(reader->step(0, &streams, 0).ok());
  EXPECT_EQ(reader->counters().pool_empty, 2u);
  // 15: the stamp ring (5) is full: its stamp is dropped and counted; the frame is dropped too.
  ASSERT_TRUE(reader->step(0, &streams, 0).ok());
  // Nothing more: a step without a frame reports nothing.
  ASSERT_TRUE(reader->step(0, &streams, 0).ok());

  const ZedCameraCounters n = reader->counters();
  EXPECT_EQ(n.frames, 2u);
  EXPECT_EQ(n.ring_full, 1u);
  EXPECT_EQ(n.pool_empty, 3u);
  EXPECT_EQ(n.stamps_dropped, 1u);
  EXPECT_EQ(n.depth_errors, 0u);
  EXPECT_EQ(n.driver_dropped, 0u);

  CameraFrameStamp st;
  for (uint32_t s = 10; s < 15; ++s) {
    ASSERT_TRUE(stamps.try_pop(st)) << "stamp of frame " << s;
    EXPECT_EQ(st.sequence, s);
    EXPECT_EQ(st.t_host_ns, timeval_ns(7, 33'333 * (s - 10)));
  }
  EXPECT_FALSE(stamps.try_pop(st)) << "15's stamp had no room";
  RgbdFrame* waiting12 = pop_frame(streams);
  ASSERT_NE(waiting12, nullptr);
  EXPECT_EQ(waiting12->seq, 12u);
  EXPECT_EQ(waiting12->t_ns, timeval_ns(7, 66'666));
  streams.frame_pool.release(held10);
  streams.frame_pool.release(waiting12);
}

TEST_F(ZedCameraReaderTest, GivenTheCameraUnpluggedThenStepIsOkCountsItAndReopensWhenTheBackoffIsDue) {
  fake_.script.push_back(good(0, 1, 0));
  auto reader = open_reader();
  ASSERT_NE(reader, nullptr);
  SensorStreams streams(streams_config(2, 2));
  core::SpscRing<CameraFrameStamp> stamps(8);
  reader->set_frame_stamps(&stamps);
  const int64_t t0 = 5'000'000'000;
  ASSERT_TRUE(reader->step(t0, &streams, 0).ok());
  RgbdFrame* f = pop_frame(streams);
  ASSERT_NE(f, nullptr);
  streams.frame_pool.release(f);

  // Unplugged: poll hangs up. Not an error; the device is closed and released.
  fake_.unplugged = true;
  fake_.open_errno = ENOENT;  // the node is gone until it is plugged in again
  ASSERT_TRUE(reader->step(t0, &streams, 0).ok());
  EXPECT_EQ(reader->counters().disconnects, 1u);
  EXPECT_FALSE(fake_.is_open);
  EXPECT_EQ(fake_.mapped_count(), 0u);

  // ReconnectBackoff: first retry 100 ms after the unplug, then 200 ms after that failure.
  const auto opens = [&] { return std::count(fake_.log.begin(), fake_.log.end(), "open"); };
  const auto opens_before = opens();
  ASSERT_TRUE(reader->step(t0 + 50'000'000, &streams, 0).ok());
  EXPECT_EQ(opens(), opens_before) << "not due yet";
  ASSERT_TRUE(reader->step(t0 + 100'000'000, &streams, 0).ok());
  EXPECT_EQ(opens(), opens_before + 1) << "due: one attempt, which fails (still unplugged)";
  ASSERT_TRUE(reader->step(t0 + 250'000'000, &streams, 0).ok());
  EXPECT_EQ(opens(), opens_before + 1) << "the next retry is at +300 ms";
  EXPECT_EQ(reader->counters().reconnects, 0u);
  EXPECT_EQ(reader->counters().disconnects, 1u);

  // Plugged in again, streaming restarts at sequence 0.
  fake_.unplugged = false;
  fake_.open_errno = 0;
  fake_.script.push_back(good(0, 9, 500'000));
  fake_.script.push_back(good(1, 9, 533'333));
  ASSERT_TRUE(reader->step(t0 + 300'000'000, &streams, 0).ok());
  EXPECT_EQ(opens(), opens_before + 2);
  EXPECT_EQ(reader->counters().reconnects, 1u);
  EXPECT_TRUE(fake_.streaming);
  ASSERT_TRUE(reader->step(t0 + 333'000'000, &streams, 0).ok());
  std::vector<int64_t> times;
  while (streams.frames.try_pop(f)) {
    times.push_back(f->t_ns);
    streams.frame_pool.release(f);
  }
  EXPECT_EQ(times, (std::vector<int64_t>{timeval_ns(9, 500'000), timeval_ns(9, 533'333)}));
  const ZedCameraCounters n = reader->counters();
  EXPECT_EQ(n.frames, 3u);
  EXPECT_EQ(n.disconnects, 1u);
  EXPECT_EQ(n.reconnects, 1u);
  // Stamps: before the unplug and after the reopen, none for the attempts in between.
  std::vector<uint32_t> seqs;
  CameraFrameStamp st;
  while (stamps.try_pop(st)) seqs.push_back(st.sequence);
  EXPECT_EQ(seqs, (std::vector<uint32_t>{0, 0, 1}));
}

TEST_F(ZedCameraReaderTest, GivenAnUnplugFoundAtDequeueByEnodevThenItIsCountedTheSame) {
  fake_.unplug_style = FakeUvcDevice::Unplug::kDqbufEnodev;
  fake_.script.push_back(good(0, 1, 0));
  auto reader = open_reader();
  ASSERT_NE(reader, nullptr);
  SensorStreams streams(streams_config(2, 2));
  fake_.unplugged = true;
  ASSERT_TRUE(reader->step(0, &streams, 0).ok());
  EXPECT_EQ(reader->counters().disconnects, 1u);
  EXPECT_EQ(reader->counters().frames, 0u);
  EXPECT_FALSE(fake_.is_open);
}

}  // namespace
}  // namespace hwr::hal::hw
