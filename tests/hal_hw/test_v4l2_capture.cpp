// V4l2Capture against FakeUvcDevice, a PosixIo that plays uvcvideo for a ZED 2i at 2560x720@30: the
// ioctl sequence at open and close, frames in order with their exact timestamps in the mmap'd
// buffers, incomplete / error-flagged / wrongly stamped buffers skipped, counted and handed back,
// sequence gaps counted as dropped, an unplug mid-stream as Unavailable, and what the driver refused
// spelled out. find_video_device on a fake sysfs tree.
#include "hwr/hal/hw/v4l2_capture.hpp"

#include <gtest/gtest.h>

#include <cerrno>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/mman.h>

#include "../temp_dir.hpp"
#include "fake_uvc_device.hpp"

namespace hwr::hal::hw {
namespace {

constexpr int kWidth = 2560;  // 1280 per eye, side by side
constexpr int kHeight = 720;
constexpr size_t kFrameBytes = size_t{kWidth} * kHeight * 2;  // YUYV: 2 bytes per pixel

using test::FakeUvcDevice;
using test::good;
using test::ScriptFrame;

V4l2CaptureConfig zed_config() {
  V4l2CaptureConfig c;
  c.device = FakeUvcDevice::kPath;
  c.width = kWidth;
  c.height = kHeight;
  c.fps = 30;
  c.buffers = 4;
  return c;
}

std::unique_ptr<V4l2Capture> open_zed(FakeUvcDevice& fake) {
  auto cap = V4l2Capture::open(zed_config(), fake);
  EXPECT_TRUE(cap.ok()) << cap.status().to_string();
  return cap.ok() ? std::move(cap).value() : nullptr;
}

// The log from index `from` on.
std::vector<std::string> log_from(const FakeUvcDevice& fake, size_t from) {
  return std::vector<std::string>(fake.log.begin() + static_cast<std::ptrdiff_t>(from), fake.log.end());
}

// Buffers the driver holds (queued, waiting to be filled).
size_t queued(const FakeUvcDevice& fake) {
  size_t n = 0;
  for (const auto& b : fake.bufs) n += b.state == FakeUvcDevice::State::kQueued ? 1 : 0;
  return n;
}

// The frame dequeue() must give, or a failure.
V4l2Frame expect_frame(V4l2Capture& cap) {
  auto f = cap.dequeue(100);
  EXPECT_TRUE(f.ok()) << f.status().to_string();
  if (!f.ok() || !f->has_value()) {
    ADD_FAILURE() << "no frame";
    return V4l2Frame{};
  }
  return **f;
}

TEST(V4l2Capture, GivenAZedThenOpenQueriesSetsFormatAndRateMapsQueuesAndStreamsInOrder) {
  FakeUvcDevice fake;
  auto cap = open_zed(fake);
  ASSERT_NE(cap, nullptr);
  const std::vector<std::string> expected = {"open", "QUERYCAP", "S_FMT", "S_PARM",   "REQBUFS", "QUERYBUF",
                                             "mmap", "QUERYBUF", "mmap",  "QUERYBUF", "mmap",    "QUERYBUF",
                                             "mmap", "QBUF",     "QBUF",  "QBUF",     "QBUF",    "STREAMON"};
  EXPECT_EQ(fake.log, expected);
  EXPECT_EQ(fake.open_flags & O_ACCMODE, O_RDWR);
  EXPECT_NE(fake.open_flags & O_NONBLOCK, 0);
  EXPECT_EQ(fake.asked_format.width, 2560u);
  EXPECT_EQ(fake.asked_format.height, 720u);
  EXPECT_EQ(fake.asked_format.pixelformat, static_cast<uint32_t>(V4L2_PIX_FMT_YUYV));
  EXPECT_EQ(fake.asked_format.field, static_cast<uint32_t>(V4L2_FIELD_ANY));
  EXPECT_EQ(fake.asked_timeperframe.numerator, 1u);
  EXPECT_EQ(fake.asked_timeperframe.denominator, 30u);
  EXPECT_EQ(fake.asked_buffers, 4u);
  EXPECT_EQ(fake.asked_memory, static_cast<uint32_t>(V4L2_MEMORY_MMAP));
  EXPECT_EQ(fake.mapped_count(), 4u);
  EXPECT_EQ(queued(fake), 4u);
  EXPECT_TRUE(fake.streaming);
  EXPECT_EQ(cap->granted_fps(), 30.0);
  EXPECT_EQ(cap->buffer_count(), 4u);

  const size_t before_close = fake.log.size();
  cap.reset();
  EXPECT_EQ(log_from(fake, before_close),
            (std::vector<std::string>{"STREAMOFF", "munmap", "munmap", "munmap", "munmap", "close"}));
  EXPECT_EQ(fake.mapped_count(), 0u);
  EXPECT_FALSE(fake.is_open);
  EXPECT_FALSE(fake.streaming);
}

TEST(V4l2Capture, GivenScriptedFramesThenTheyArriveInOrderWithExactTimesInTheMappedBuffers) {
  FakeUvcDevice fake;
  // 10 frames at 30 Hz through 4 buffers: every buffer is reused, in the driver's FIFO order.
  for (uint32_t s = 0; s < 10; ++s) fake.script.push_back(good(s, 1234, 567'890 + 33'333 * s));
  auto cap = open_zed(fake);
  ASSERT_NE(cap, nullptr);
  for (uint32_t s = 0; s < 10; ++s) {
    const V4l2Frame f = expect_frame(*cap);
    ASSERT_NE(f.data, nullptr);
    EXPECT_EQ(f.sequence, s);
    EXPECT_EQ(f.index, s % 4) << "uvcvideo fills queued buffers in QBUF order";
    // timeval → ns: 1234 s + (567890 + 33333 s) µs.
    EXPECT_EQ(f.t_ns, 1234'000'000'000LL + (567'890LL + 33'333LL * s) * 1'000LL);
    EXPECT_EQ(f.data, fake.bufs[f.index].storage.data()) << "the frame must point into its mmap'd buffer";
    uint32_t stamped = 0;
    std::memcpy(&stamped, f.data, sizeof stamped);
    EXPECT_EQ(stamped, s);
    EXPECT_EQ(f.data[kFrameBytes - 1], static_cast<uint8_t>(s * 7 + 1));
    EXPECT_EQ(f.bytes, kFrameBytes);
    EXPECT_EQ(f.width, kWidth);
    EXPECT_EQ(f.height, kHeight);
    EXPECT_EQ(f.stride_bytes, size_t{kWidth} * 2);
    EXPECT_EQ(queued(fake), 3u) << "the caller holds exactly this frame's buffer";
    ASSERT_TRUE(cap->requeue(f).ok());
    EXPECT_EQ(queued(fake), 4u);
  }
  EXPECT_EQ(cap->counters().frames, 10u);
  EXPECT_EQ(cap->counters().dropped, 0u);
  EXPECT_EQ(cap->counters().incomplete, 0u);
  EXPECT_EQ(cap->counters().bad_timestamps, 0u);
}

TEST(V4l2Capture, GivenTimevalWithLargeSecondsThenNanosecondsDoNotOverflow) {
  FakeUvcDevice fake;
  fake.script.push_back(good(0, 4'000'000'000LL, 999'999));  // > 2^31 s: 64-bit arithmetic needed
  auto cap = open_zed(fake);
  ASSERT_NE(cap, nullptr);
  EXPECT_EQ(expect_frame(*cap).t_ns, 4'000'000'000'999'999'000LL);
}

TEST(V4l2Capture, GivenAShortAndAnErrorFlaggedBufferThenTheyAreSkippedCountedAndRequeued) {
  FakeUvcDevice fake;
  fake.script.push_back(good(0, 10, 0));
  ScriptFrame short_frame = good(1, 10, 33'333);
  short_frame.bytesused = kFrameBytes - 1;
  ScriptFrame error_frame = good(2, 10, 66'666);
  error_frame.error = true;  // full length, but uvcvideo saw a lost packet
  ScriptFrame empty_frame = good(3, 10, 99'999);
  empty_frame.bytesused = 0;
  ScriptFrame long_frame = good(5, 10, 166'665);
  long_frame.bytesused = kFrameBytes + 2;  // a driver that lies about length
  fake.script.insert(fake.script.end(), {short_frame, error_frame, empty_frame, good(4, 10, 133'332),
                                         long_frame, good(6, 10, 199'998)});
  auto cap = open_zed(fake);
  ASSERT_NE(cap, nullptr);

  const V4l2Frame first = expect_frame(*cap);
  EXPECT_EQ(first.sequence, 0u);
  ASSERT_TRUE(cap->requeue(first).ok());
  // One dequeue() walks past the three bad buffers (each requeued at once) to the good one.
  const V4l2Frame next = expect_frame(*cap);
  EXPECT_EQ(next.sequence, 4u);
  EXPECT_EQ(next.t_ns, 10'133'332'000LL);
  EXPECT_EQ(cap->counters().incomplete, 3u);
  EXPECT_EQ(queued(fake), 3u) << "all skipped buffers went back to the driver";
  ASSERT_TRUE(cap->requeue(next).ok());
  EXPECT_EQ(queued(fake), 4u);
  const V4l2Frame last = expect_frame(*cap);
  EXPECT_EQ(last.sequence, 6u);
  EXPECT_EQ(cap->counters().incomplete, 4u);
  EXPECT_EQ(cap->counters().frames, 3u);
  EXPECT_EQ(cap->counters().dropped, 0u) << "skipped buffers are incomplete, not dropped";
}

TEST(V4l2Capture, GivenOnlyBadBuffersReadyThenDequeueReturnsNothingAndKeepsAllQueued) {
  FakeUvcDevice fake;
  for (uint32_t s = 0; s < 6; ++s) {
    ScriptFrame f = good(s, 1, s);
    f.error = true;
    fake.script.push_back(f);
  }
  auto cap = open_zed(fake);
  ASSERT_NE(cap, nullptr);
  auto f = cap->dequeue(100);
  ASSERT_TRUE(f.ok()) << f.status().to_string();
  EXPECT_FALSE(f->has_value());
  // Bounded to one pass over the buffers per call; the rest on the next call.
  EXPECT_EQ(cap->counters().incomplete, 4u);
  EXPECT_EQ(queued(fake), 4u);
  f = cap->dequeue(100);
  ASSERT_TRUE(f.ok());
  EXPECT_FALSE(f->has_value());
  EXPECT_EQ(cap->counters().incomplete, 6u);
  EXPECT_EQ(cap->counters().frames, 0u);
}

TEST(V4l2Capture, GivenASequenceGapThenTheMissingFramesCountAsDropped) {
  FakeUvcDevice fake;
  ScriptFrame bad = good(6, 1, 0);
  bad.bytesused = 100;
  fake.script.insert(fake.script.end(), {good(0, 1, 0), good(1, 1, 0), good(5, 1, 0), bad, good(7, 1, 0)});
  auto cap = open_zed(fake);
  ASSERT_NE(cap, nullptr);
  std::vector<uint32_t> seen;
  for (int i = 0; i < 4; ++i) {
    const V4l2Frame f = expect_frame(*cap);
    seen.push_back(f.sequence);
    ASSERT_TRUE(cap->requeue(f).ok());
  }
  EXPECT_EQ(seen, (std::vector<uint32_t>{0, 1, 5, 7}));
  EXPECT_EQ(cap->counters().dropped, 3u) << "2, 3 and 4 never arrived; 6 arrived incomplete";
  EXPECT_EQ(cap->counters().incomplete, 1u);
  EXPECT_EQ(cap->counters().frames, 4u);
}

TEST(V4l2Capture, GivenTheSequenceRestartingThenNothingCountsAsDropped) {
  FakeUvcDevice fake;
  fake.script.insert(fake.script.end(), {good(100, 1, 0), good(101, 1, 0), good(0, 1, 0), good(1, 1, 0)});
  auto cap = open_zed(fake);
  ASSERT_NE(cap, nullptr);
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(cap->requeue(expect_frame(*cap)).ok());
  EXPECT_EQ(cap->counters().dropped, 0u);
}

TEST(V4l2Capture, GivenTimestampsNotMonotonicThenTheBufferIsRejectedWithAClearErrorAndRequeued) {
  for (const uint32_t ts_flags :
       {uint32_t{V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN}, uint32_t{V4L2_BUF_FLAG_TIMESTAMP_COPY}}) {
    SCOPED_TRACE(ts_flags);
    FakeUvcDevice fake;
    ScriptFrame wall = good(0, 1'700'000'000, 0);
    wall.timestamp_flags = ts_flags;
    fake.script.insert(fake.script.end(), {wall, good(1, 50, 0)});
    auto cap = open_zed(fake);
    ASSERT_NE(cap, nullptr);
    auto f = cap->dequeue(100);
    ASSERT_FALSE(f.ok());
    EXPECT_EQ(f.status().code(), core::ErrorCode::kCorruptData);
    EXPECT_NE(f.status().message().find("timestamps are not CLOCK_MONOTONIC"), std::string::npos)
        << f.status().message();
    EXPECT_NE(f.status().message().find("/dev/video2"), std::string::npos);
    EXPECT_EQ(cap->counters().bad_timestamps, 1u);
    EXPECT_EQ(cap->counters().frames, 0u);
    EXPECT_EQ(queued(fake), 4u) << "the rejected buffer went back to the driver";
    const V4l2Frame next = expect_frame(*cap);
    EXPECT_EQ(next.sequence, 1u);
    EXPECT_EQ(next.t_ns, 50'000'000'000LL);
  }
}

TEST(V4l2Capture, GivenNoFrameWithinTheTimeoutThenDequeueGivesNothing) {
  FakeUvcDevice fake;
  auto cap = open_zed(fake);
  ASSERT_NE(cap, nullptr);
  auto f = cap->dequeue(5);
  ASSERT_TRUE(f.ok()) << f.status().to_string();
  EXPECT_FALSE(f->has_value());
  EXPECT_EQ(cap->counters().frames, 0u);
  EXPECT_EQ(fake.log.back(), "poll") << "no DQBUF after a poll timeout";
}

TEST(V4l2Capture, GivenTheCameraUnpluggedMidStreamThenUnavailableSaysUnplugged) {
  for (const auto style : {FakeUvcDevice::Unplug::kPollHangUp, FakeUvcDevice::Unplug::kPollEnodev,
                           FakeUvcDevice::Unplug::kDqbufEnodev}) {
    SCOPED_TRACE(static_cast<int>(style));
    FakeUvcDevice fake;
    fake.unplug_style = style;
    fake.script.insert(fake.script.end(), {good(0, 1, 0), good(1, 1, 0)});
    auto cap = open_zed(fake);
    ASSERT_NE(cap, nullptr);
    const V4l2Frame held = expect_frame(*cap);
    fake.unplugged = true;
    auto f = cap->dequeue(100);
    ASSERT_FALSE(f.ok());
    EXPECT_EQ(f.status().code(), core::ErrorCode::kUnavailable) << f.status().to_string();
    EXPECT_NE(f.status().message().find("unplugged?"), std::string::npos) << f.status().message();
    EXPECT_NE(f.status().message().find("/dev/video2"), std::string::npos);
    // Handing a buffer back to a vanished device is Unavailable too, and teardown still releases all.
    const core::Status rq = cap->requeue(held);
    EXPECT_EQ(rq.code(), core::ErrorCode::kUnavailable) << rq.to_string();
    cap.reset();
    EXPECT_EQ(fake.mapped_count(), 0u);
    EXPECT_FALSE(fake.is_open);
  }
}

TEST(V4l2Capture, GivenTheCallerHoldsEveryBufferThenDequeueSaysRequeueFirstNotUnplugged) {
  FakeUvcDevice fake;
  for (uint32_t s = 0; s < 5; ++s) fake.script.push_back(good(s, 1, s));
  auto cap = open_zed(fake);
  ASSERT_NE(cap, nullptr);
  std::vector<V4l2Frame> held;
  for (int i = 0; i < 4; ++i) held.push_back(expect_frame(*cap));
  auto f = cap->dequeue(100);
  ASSERT_FALSE(f.ok());
  EXPECT_EQ(f.status().code(), core::ErrorCode::kInvalidArgument);
  EXPECT_NE(f.status().message().find("requeue()"), std::string::npos) << f.status().message();
  ASSERT_TRUE(cap->requeue(held[2]).ok());
  EXPECT_EQ(expect_frame(*cap).sequence, 4u);
}

TEST(V4l2Capture, GivenAFrameRequeuedTwiceThenTheSecondIsRefusedAndTheDriverNeverSeesIt) {
  FakeUvcDevice fake;
  fake.script.push_back(good(0, 1, 0));
  auto cap = open_zed(fake);
  ASSERT_NE(cap, nullptr);
  const V4l2Frame f = expect_frame(*cap);
  ASSERT_TRUE(cap->requeue(f).ok());
  const size_t before = fake.log.size();
  const core::Status again = cap->requeue(f);
  EXPECT_EQ(again.code(), core::ErrorCode::kInvalidArgument);
  EXPECT_NE(again.message().find("buffer 0"), std::string::npos) << again.message();
  V4l2Frame bogus = f;
  bogus.index = 99;
  EXPECT_EQ(cap->requeue(bogus).code(), core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(fake.log.size(), before) << "no QBUF for a buffer the caller does not hold";
}

// Open failures: the error names the device and says what was asked and granted, and everything
// acquired so far is released.
void expect_open_fails(FakeUvcDevice& fake, const V4l2CaptureConfig& config, core::ErrorCode code,
                       const std::vector<std::string>& mentions) {
  auto cap = V4l2Capture::open(config, fake);
  ASSERT_FALSE(cap.ok());
  EXPECT_EQ(cap.status().code(), code) << cap.status().to_string();
  for (const std::string& m : mentions) {
    EXPECT_NE(cap.status().message().find(m), std::string::npos)
        << "'" << m << "' not in: " << cap.status().message();
  }
  EXPECT_EQ(fake.mapped_count(), 0u);
  EXPECT_FALSE(fake.is_open);
  EXPECT_FALSE(fake.streaming);
}

TEST(V4l2Capture, GivenTheDriverRefusesYuyvThenOpenSaysWhatWasAskedAndGranted) {
  FakeUvcDevice fake;
  fake.granted_pixelformat = V4L2_PIX_FMT_MJPEG;
  expect_open_fails(fake, zed_config(), core::ErrorCode::kInvalidArgument,
                    {"/dev/video2", "asked for YUYV 2560x720", "granted MJPG 2560x720"});
}

TEST(V4l2Capture, GivenTheDriverChangesTheSizeThenOpenSaysWhatWasAskedAndGranted) {
  FakeUvcDevice fake;  // a ZED on USB 2 offers only VGA
  fake.granted_width = 1344;
  fake.granted_height = 376;
  expect_open_fails(fake, zed_config(), core::ErrorCode::kInvalidArgument,
                    {"asked for YUYV 2560x720", "granted YUYV 1344x376", "USB 2"});
}

TEST(V4l2Capture, GivenANodeThatCannotStreamVideoThenOpenNamesDeviceDriverAndCard) {
  FakeUvcDevice no_streaming;
  no_streaming.device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_READWRITE;
  expect_open_fails(no_streaming, zed_config(), core::ErrorCode::kInvalidArgument,
                    {"/dev/video2", "uvcvideo", "ZED 2i: ZED 2i", "STREAMING"});
  EXPECT_EQ(no_streaming.log, (std::vector<std::string>{"open", "QUERYCAP", "close"}));

  FakeUvcDevice metadata_node;  // uvcvideo's second node: metadata, not video
  metadata_node.device_caps = V4L2_CAP_META_CAPTURE | V4L2_CAP_STREAMING;
  expect_open_fails(metadata_node, zed_config(), core::ErrorCode::kInvalidArgument,
                    {"uvcvideo", "VIDEO_CAPTURE", "metadata"});

  // Without V4L2_CAP_DEVICE_CAPS, `capabilities` describes the node (old drivers).
  FakeUvcDevice old_driver;
  old_driver.capabilities = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
  old_driver.device_caps = 0;
  EXPECT_NE(open_zed(old_driver), nullptr);
  FakeUvcDevice old_without_streaming;
  old_without_streaming.capabilities = V4L2_CAP_VIDEO_CAPTURE;
  old_without_streaming.device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;  // ignored: no DEVICE_CAPS
  expect_open_fails(old_without_streaming, zed_config(), core::ErrorCode::kInvalidArgument, {"STREAMING"});
}

TEST(V4l2Capture, GivenFewerThanTwoBuffersGrantedThenOpenFailsSayingSo) {
  FakeUvcDevice fake;
  fake.max_buffers = 1;
  expect_open_fails(fake, zed_config(), core::ErrorCode::kUnavailable,
                    {"asked for 4 mmap buffers", "granted 1"});
}

TEST(V4l2Capture, GivenAnotherProcessStreamingThenOpenIsUnavailableSayingSo) {
  FakeUvcDevice fake;
  fake.busy = true;
  expect_open_fails(fake, zed_config(), core::ErrorCode::kUnavailable,
                    {"/dev/video2: VIDIOC_S_FMT YUYV width 2560", "another process"});
}

TEST(V4l2Capture, GivenNoPermissionThenOpenSaysWhichGroup) {
  FakeUvcDevice fake;
  fake.open_errno = EACCES;
  expect_open_fails(fake, zed_config(), core::ErrorCode::kIoError, {"/dev/video2: open", "video group"});
}

TEST(V4l2Capture, GivenAnMmapFailingHalfwayThenOpenFailsAndUnmapsWhatItMapped) {
  FakeUvcDevice fake;
  fake.fail_mmap_index = 2;
  expect_open_fails(fake, zed_config(), core::ErrorCode::kIoError, {"mmap buffer 2"});
  EXPECT_EQ(fake.log,
            (std::vector<std::string>{"open", "QUERYCAP", "S_FMT", "S_PARM", "REQBUFS", "QUERYBUF", "mmap",
                                      "QUERYBUF", "mmap", "QUERYBUF", "mmap", "munmap", "munmap", "close"}));
}

TEST(V4l2Capture, GivenMoreBuffersGrantedThenAllAreMappedAndQueued) {
  FakeUvcDevice fake;
  fake.max_buffers = 3;
  auto cap = open_zed(fake);
  ASSERT_NE(cap, nullptr);
  EXPECT_EQ(cap->buffer_count(), 3u);
  EXPECT_EQ(fake.mapped_count(), 3u);
  EXPECT_EQ(queued(fake), 3u);
}

TEST(V4l2Capture, GivenTheDriverRoundsTheRateThenGrantedFpsSaysSo) {
  FakeUvcDevice fake;
  fake.granted_fps = 15;
  auto cap = open_zed(fake);
  ASSERT_NE(cap, nullptr);
  EXPECT_EQ(fake.asked_timeperframe.denominator, 30u);
  EXPECT_EQ(cap->granted_fps(), 15.0);
}

TEST(V4l2Capture, GivenNoSuchDeviceThenNotFoundNamesIt) {
  FakeUvcDevice fake;
  V4l2CaptureConfig c = zed_config();
  c.device = "/dev/video9";
  expect_open_fails(fake, c, core::ErrorCode::kNotFound, {"/dev/video9", "plugged in"});
}

TEST(V4l2Capture, GivenABadConfigThenInvalidArgumentWithoutTouchingTheDevice) {
  const auto bad = [](auto edit) {
    V4l2CaptureConfig c = zed_config();
    edit(c);
    return c;
  };
  for (const V4l2CaptureConfig& c :
       {bad([](V4l2CaptureConfig& c) { c.device.clear(); }), bad([](V4l2CaptureConfig& c) { c.width = 0; }),
        bad([](V4l2CaptureConfig& c) { c.width = 2561; }), bad([](V4l2CaptureConfig& c) { c.height = -1; }),
        bad([](V4l2CaptureConfig& c) { c.fps = 0; }), bad([](V4l2CaptureConfig& c) { c.buffers = 1; }),
        bad([](V4l2CaptureConfig& c) { c.buffers = 33; })}) {
    FakeUvcDevice fake;
    auto cap = V4l2Capture::open(c, fake);
    ASSERT_FALSE(cap.ok());
    EXPECT_EQ(cap.status().code(), core::ErrorCode::kInvalidArgument) << cap.status().to_string();
    EXPECT_TRUE(fake.log.empty());
  }
}

// --- find_video_device on a fake /sys -------------------------------------------------------------

// <root>/class/video4linux/videoN/{device/modalias,index}; empty modalias/index: file left out.
void add_node(const std::string& root, int n, const std::string& modalias, const std::string& index) {
  namespace fs = std::filesystem;
  const fs::path node = fs::path(root) / "class" / "video4linux" / ("video" + std::to_string(n));
  fs::create_directories(node / "device");
  if (!modalias.empty()) std::ofstream(node / "device" / "modalias") << modalias << "\n";
  if (!index.empty()) std::ofstream(node / "index") << index << "\n";
}

const char* const kZedModalias = "usb:v2B03pF880d0100dcEFdsc02dp01ic0Eisc01ip00in00";
const char* const kWebcamModalias = "usb:v046Dp0825d0012dcEFdsc02dp01ic0Eisc01ip00in00";

TEST(FindVideoDevice, GivenAWebcamAndAZedThenTheZedsCaptureNodeIsFound) {
  testing::TempDir sys("hwr_sysfs");
  add_node(sys.path(), 0, kWebcamModalias, "0");
  add_node(sys.path(), 1, kWebcamModalias, "1");
  add_node(sys.path(), 2, kZedModalias, "0");
  add_node(sys.path(), 3, kZedModalias, "1");  // uvcvideo's metadata node for the same interface
  auto dev = find_video_device(sys.path(), 0x2b03, 0xf880);
  ASSERT_TRUE(dev.ok()) << dev.status().to_string();
  EXPECT_EQ(*dev, "/dev/video2");
  auto webcam = find_video_device(sys.path(), 0x046d, 0x0825);
  ASSERT_TRUE(webcam.ok());
  EXPECT_EQ(*webcam, "/dev/video0");
}

TEST(FindVideoDevice, GivenLowercaseHexInModaliasThenItStillMatches) {
  testing::TempDir sys("hwr_sysfs");
  add_node(sys.path(), 4, "usb:v2b03pf880d0100", "");
  auto dev = find_video_device(sys.path(), 0x2B03, 0xF880);
  ASSERT_TRUE(dev.ok()) << dev.status().to_string();
  EXPECT_EQ(*dev, "/dev/video4");
}

TEST(FindVideoDevice, GivenTwoZedsThenTheLowestNumberWinsNumerically) {
  testing::TempDir sys("hwr_sysfs");
  add_node(sys.path(), 10, kZedModalias, "0");  // "video10" sorts before "video2" as text
  add_node(sys.path(), 2, kZedModalias, "0");
  auto dev = find_video_device(sys.path(), 0x2b03, 0xf880);
  ASSERT_TRUE(dev.ok());
  EXPECT_EQ(*dev, "/dev/video2");
}

TEST(FindVideoDevice, GivenTheMetadataNodeNumberedLowerThenTheCaptureNodeWins) {
  testing::TempDir sys("hwr_sysfs");
  add_node(sys.path(), 1, kZedModalias, "1");
  add_node(sys.path(), 4, kZedModalias, "0");
  auto dev = find_video_device(sys.path(), 0x2b03, 0xf880);
  ASSERT_TRUE(dev.ok());
  EXPECT_EQ(*dev, "/dev/video4");
}

TEST(FindVideoDevice, GivenNoZedThenNotFoundListsWhatItSaw) {
  testing::TempDir sys("hwr_sysfs");
  add_node(sys.path(), 0, kWebcamModalias, "0");
  add_node(sys.path(), 5, "", "0");  // a node without a USB parent (e.g. a CSI camera)
  std::filesystem::create_directories(sys.path() + "/class/video4linux/v4l-subdev0");  // not videoN
  auto dev = find_video_device(sys.path(), 0x2b03, 0xf880);
  ASSERT_FALSE(dev.ok());
  EXPECT_EQ(dev.status().code(), core::ErrorCode::kNotFound);
  const std::string want = "no video device with USB id 2b03:f880 under " + sys.path() +
                           "/class/video4linux (found: video0 usb:v046Dp0825, video5 (no modalias)): "
                           "is the ZED 2i plugged in, on USB 3?";
  EXPECT_EQ(dev.status().message(), want);
}

TEST(FindVideoDevice, GivenNoVideo4linuxDirectoryThenNotFoundSaysNoDriver) {
  testing::TempDir sys("hwr_sysfs");
  auto dev = find_video_device(sys.path(), 0x2b03, 0xf880);
  ASSERT_FALSE(dev.ok());
  EXPECT_EQ(dev.status().code(), core::ErrorCode::kNotFound);
  EXPECT_NE(dev.status().message().find("found: none"), std::string::npos) << dev.status().message();
  EXPECT_NE(dev.status().message().find("no V4L2 driver"), std::string::npos) << dev.status().message();
}

}  // namespace
}  // namespace hwr::hal::hw
