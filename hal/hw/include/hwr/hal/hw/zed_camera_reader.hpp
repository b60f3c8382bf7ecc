#pragma once
// The ZED 2i's video as frames with depth: V4L2 (v4l2_capture.hpp) → the side-by-side YUYV frame
// split into left and right gray (hardware.md: left eye in the left half) → hal::StereoDepth (the
// factory calibration's rectification, OpenCV SGBM, depth = fx·B/d) → a frame from the pipeline's
// pool, stamped with the V4L2 buffer's CLOCK_MONOTONIC time (uvcvideo: start of exposure), pushed
// into the frame ring. The reader is the pool's only acquirer and the ring's only producer; a frame
// it could not hand over is kept as its spare rather than released (the pool has one releaser: the
// pipeline). SGBM takes longer than a frame period on the AGX's CPU at 1280x720: the camera keeps
// streaming and the frames the reader did not take are counted as the driver's sequence gaps.
// An unplugged camera is reopened (found again by USB id when the device is "auto").

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "hwr/core/status.hpp"
#include "hwr/hal/hw/hw_config.hpp"
#include "hwr/hal/hw/reconnect_backoff.hpp"
#include "hwr/hal/hw/v4l2_capture.hpp"
#include "hwr/hal/sensor_streams.hpp"
#include "hwr/hal/stereo_depth.hpp"

namespace hwr::hal::hw {

struct ZedCameraCounters {
  uint64_t frames = 0;      // pushed into the ring
  uint64_t pool_empty = 0;  // no free frame: the pipeline holds them all
  uint64_t ring_full = 0;   // the pipeline is behind: the new frame is dropped
  uint64_t depth_errors = 0;
  uint64_t disconnects = 0, reconnects = 0;
  uint64_t incomplete = 0, driver_dropped = 0, bad_timestamps = 0;  // from V4l2Capture
};

class ZedCameraReader {
 public:
  // Loads the calibration, prepares the rectification and opens the camera. Errors name the file or
  // device and say what to do.
  static core::Expected<std::unique_ptr<ZedCameraReader>> open(const HwConfig& config,
                                                               PosixIo& io = real_posix_io());

  // One frame (waits up to timeout_ms). An error only for what a reconnect cannot fix.
  core::Status step(int64_t now_ns, SensorStreams* streams, int timeout_ms = 100);

  const PinholeIntrinsics& rectified_intrinsics() const { return depth_->rectified_intrinsics(); }
  // The rectified left camera in the original left camera's frame (rotation only).
  const Eigen::Isometry3d& T_cam_rect() const { return depth_->T_cam0_rect(); }
  const std::string& device() const { return device_; }
  ZedCameraCounters counters() const;

 private:
  ZedCameraReader(const HwConfig& config, PosixIo& io) : config_(config), io_(io) {}
  core::Status open_capture();

  HwConfig config_;
  PosixIo& io_;
  std::string device_;
  std::optional<StereoDepth> depth_;
  std::unique_ptr<V4l2Capture> capture_;
  ReconnectBackoff backoff_;
  cv::Mat left_gray_, right_gray_;
  RgbdFrame* spare_ = nullptr;
  std::atomic<uint64_t> frames_{0}, pool_empty_{0}, ring_full_{0}, depth_errors_{0}, disconnects_{0},
      reconnects_{0}, incomplete_{0}, driver_dropped_{0}, bad_timestamps_{0};
};

}  // namespace hwr::hal::hw
