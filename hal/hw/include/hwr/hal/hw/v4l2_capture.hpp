#pragma once
// Video from the ZED 2i's UVC interface without the vendor SDK (hardware.md "ZED 2i without the
// vendor SDK"): find its /dev/videoN by USB id in sysfs, then capture YUYV frames (both eyes side by
// side, left eye in the left half) through V4L2 mmap streaming. Each frame carries the driver's
// CLOCK_MONOTONIC timestamp (uvcvideo stamps start of exposure) and points into a kernel buffer that
// the caller hands back with requeue() when done. Incomplete or corrupt buffers are dropped and
// counted, never delivered. An unplugged camera is core::Unavailable: the caller destroys this object
// and open()s again later (ReconnectBackoff).
//
// All system calls go through PosixIo, so the tests replace the kernel with a fake uvcvideo.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/hal/hw/posix_io.hpp"

namespace hwr::hal::hw {

// "/dev/videoN" of the V4L2 node whose <sysfs_root>/class/video4linux/videoN/device/modalias starts
// with usb:v<VVVV>p<PPPP> (hex, any case), e.g. usb:v2B03pF880 for the ZED 2i's video interface.
// uvcvideo also registers a metadata node for the same interface (same modalias, sysfs `index` 1):
// among matches, nodes whose `index` is 0 (or absent) win, then the lowest N. NotFound lists every
// node it saw with its USB id.
core::Expected<std::string> find_video_device(const std::string& sysfs_root, uint16_t vendor,
                                              uint16_t product);

struct V4l2CaptureConfig {
  std::string device;  // e.g. "/dev/video0" (find_video_device)
  int width = 0;       // whole frame, both eyes: 2560 for 1280 per eye
  int height = 0;
  int fps = 0;
  int buffers = 4;  // mmap buffers asked for (2..32); the driver may grant more
};

// One captured frame, valid until requeue(). YUYV: 2 bytes per pixel, rows stride_bytes apart.
struct V4l2Frame {
  const uint8_t* data = nullptr;  // into the mmap'd kernel buffer
  size_t bytes = 0;               // bytesused == stride_bytes * height
  int width = 0;
  int height = 0;
  size_t stride_bytes = 0;
  int64_t t_ns = 0;       // CLOCK_MONOTONIC, start of exposure
  uint32_t sequence = 0;  // the driver's frame counter
  uint32_t index = 0;     // buffer index, for requeue()
};

struct V4l2CaptureCounters {
  uint64_t frames = 0;          // delivered by dequeue()
  uint64_t incomplete = 0;      // short (bytesused != frame size) or V4L2_BUF_FLAG_ERROR: requeued
  uint64_t dropped = 0;         // frames the driver skipped: sum of sequence gaps
  uint64_t bad_timestamps = 0;  // buffers whose timestamp was not CLOCK_MONOTONIC: requeued
};

class V4l2Capture {
 public:
  // Opens config.device, sets YUYV width x height at fps, maps the buffers and starts streaming.
  // Errors say what was asked and what the driver granted.
  static core::Expected<std::unique_ptr<V4l2Capture>> open(const V4l2CaptureConfig& config,
                                                           PosixIo& io = real_posix_io());
  ~V4l2Capture();  // STREAMOFF, munmap, close
  V4l2Capture(const V4l2Capture&) = delete;
  V4l2Capture& operator=(const V4l2Capture&) = delete;

  // The next complete frame, or nullopt when none arrives within timeout_ms. Skipped buffers are
  // requeued and counted; ready buffers are examined without waiting again, at most buffer_count()
  // of them per call (nullopt when all of those were bad: call again).
  // Unavailable: the camera is gone (unplugged?), reopen. CorruptData: a buffer without a
  // CLOCK_MONOTONIC timestamp (requeued; the next call continues). InvalidArgument: every buffer is
  // held by the caller (requeue() frames first).
  core::Expected<std::optional<V4l2Frame>> dequeue(int timeout_ms);
  // Hands frame's buffer back to the driver. InvalidArgument when it is not held by the caller.
  core::Status requeue(const V4l2Frame& frame);

  const V4l2CaptureCounters& counters() const { return counters_; }
  // Frame rate the driver granted with VIDIOC_S_PARM (it may round the request); 0 when it does not
  // say (no V4L2_CAP_TIMEPERFRAME).
  double granted_fps() const { return granted_fps_; }
  size_t buffer_count() const { return buffers_.size(); }
  const V4l2CaptureConfig& config() const { return config_; }

 private:
  struct Buffer {
    uint8_t* data = nullptr;
    size_t length = 0;
    bool queued = false;  // owned by the driver; otherwise held by the caller
  };

  V4l2Capture(const V4l2CaptureConfig& config, PosixIo& io) : config_(config), io_(io) {}
  core::Status start();
  core::Status queue(uint32_t index);
  void stop();

  V4l2CaptureConfig config_;
  PosixIo& io_;
  int fd_ = -1;
  bool streaming_ = false;
  size_t stride_bytes_ = 0;
  size_t frame_bytes_ = 0;
  double granted_fps_ = 0.0;
  std::vector<Buffer> buffers_;
  bool have_sequence_ = false;
  uint32_t last_sequence_ = 0;
  V4l2CaptureCounters counters_;
};

}  // namespace hwr::hal::hw
