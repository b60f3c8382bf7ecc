#pragma once
// The ZED 2i's video as frames with depth: V4L2 (v4l2_capture.hpp) → the side-by-side YUYV frame
// split into left and right gray and the left colour (hardware.md: left eye in the left half;
// side_by_side.hpp) → hal::StereoDepth (the factory calibration's rectification, OpenCV SGBM on the
// gray pair, depth = fx·B/d; the left colour through the same rectification maps into the frame's
// bgr) → a frame from the pipeline's pool, stamped with the V4L2 buffer's CLOCK_MONOTONIC time
// (uvcvideo: start of exposure), pushed into the frame ring. The reader is the pool's only acquirer
// and the ring's only producer; a frame it could not hand over is kept as its spare rather than
// released (the pool has one releaser: the pipeline). SGBM takes longer than a frame period on the
// AGX's CPU at 1280x720: the camera keeps streaming and the frames the reader did not take are
// counted as the driver's sequence gaps.
// An unplugged camera is reopened (found again by USB id when the device is "auto").
// Every dequeued frame's stamp can also go to the ZED sensor thread (set_frame_stamps) for the
// frame sync, whether or not the frame itself is kept.

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "hwr/core/spsc_ring.hpp"
#include "hwr/core/status.hpp"
#include "hwr/hal/hw/camera_frame_stamp.hpp"
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
  uint64_t stamps_dropped = 0;  // frame stamps the sensor thread's ring had no room for
};

class ZedCameraReader {
 public:
  // Loads the calibration, prepares the rectification and opens the camera. Errors name the file or
  // device and say what to do.
  static core::Expected<std::unique_ptr<ZedCameraReader>> open(const HwConfig& config,
                                                               PosixIo& io = real_posix_io());

  // Where every complete dequeued frame's stamp {t_ns, sequence} goes, for the ZED sensor thread's
  // frame sync (camera_clock_sync.hpp): also the frames then dropped for an empty pool, a full frame
  // ring or a depth error. A full stamp ring drops the stamp (counters().stamps_dropped). null:
  // nowhere (the default). Call it before the reader's thread starts calling step(): the pointer is
  // not synchronised, and this reader becomes the ring's only producer.
  void set_frame_stamps(core::SpscRing<CameraFrameStamp>* out) { stamps_out_ = out; }

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
  cv::Mat left_gray_, right_gray_;  // CV_8UC1 eye_width x eye_height, allocated at open
  cv::Mat left_bgr_;                // CV_8UC3, the same
  RgbdFrame* spare_ = nullptr;
  core::SpscRing<CameraFrameStamp>* stamps_out_ = nullptr;
  std::atomic<uint64_t> frames_{0}, pool_empty_{0}, ring_full_{0}, depth_errors_{0}, disconnects_{0},
      reconnects_{0}, incomplete_{0}, driver_dropped_{0}, bad_timestamps_{0}, stamps_dropped_{0};
};

}  // namespace hwr::hal::hw
