#include "hwr/hal/hw/zed_camera_reader.hpp"

#include "hwr/core/log.hpp"
#include "hwr/hal/hw/side_by_side.hpp"
#include "hwr/hal/hw/zed_calibration.hpp"

namespace hwr::hal::hw {
namespace {

constexpr uint16_t kZedVendor = 0x2b03;
constexpr uint16_t kZedVideoProduct = 0xf880;  // hardware.md: the UVC interface

bool is_unplug(const core::Status& st) {
  return st.code() == core::ErrorCode::kUnavailable || st.code() == core::ErrorCode::kNotFound ||
         st.code() == core::ErrorCode::kIoError;
}

}  // namespace

core::Expected<std::unique_ptr<ZedCameraReader>> ZedCameraReader::open(const HwConfig& config, PosixIo& io) {
  const ZedCameraConfig& c = config.camera;
  auto rig = load_zed_calibration_file(c.calibration, c.eye_width);
  if (!rig.ok()) return core::Status(rig.status().code(), "camera: " + rig.status().message());
  auto depth = StereoDepth::create(rig.value(), c.sgbm);
  if (!depth.ok()) return core::Status(depth.status().code(), "camera: " + depth.status().message());
  std::unique_ptr<ZedCameraReader> r(new ZedCameraReader(config, io));
  r->depth_.emplace(std::move(depth.value()));
  r->left_gray_.create(c.eye_height, c.eye_width, CV_8UC1);
  r->right_gray_.create(c.eye_height, c.eye_width, CV_8UC1);
  r->left_bgr_.create(c.eye_height, c.eye_width, CV_8UC3);
  if (core::Status st = r->open_capture(); !st.ok()) return st;
  return r;
}

core::Status ZedCameraReader::open_capture() {
  const ZedCameraConfig& c = config_.camera;
  device_ = c.device;
  if (device_ == "auto") {
    auto found = find_video_device(config_.sysfs_root, kZedVendor, kZedVideoProduct);
    if (!found.ok()) return core::Status(found.status().code(), "camera: " + found.status().message());
    device_ = found.value();
  }
  V4l2CaptureConfig vc;
  vc.device = device_;
  vc.width = 2 * c.eye_width;  // both eyes side by side
  vc.height = c.eye_height;
  vc.fps = c.fps;
  vc.buffers = c.buffers;
  auto cap = V4l2Capture::open(vc, io_);
  if (!cap.ok()) return core::Status(cap.status().code(), "camera: " + cap.status().message());
  capture_ = std::move(cap.value());
  return core::Status::Ok();
}

core::Status ZedCameraReader::step(int64_t now_ns, SensorStreams* streams, int timeout_ms) {
  if (!capture_) {
    if (!backoff_.due(now_ns)) {
      backoff_.wait_until_due(now_ns, timeout_ms);
      return core::Status::Ok();
    }
    if (core::Status st = open_capture(); !st.ok()) {
      backoff_.failed(now_ns);
      return is_unplug(st) ? core::Status::Ok() : st;
    }
    backoff_.succeeded();
    reconnects_.fetch_add(1, std::memory_order_relaxed);
    HWR_LOG_INFO("camera", "%s: reconnected", device_.c_str());
  }
  auto got = capture_->dequeue(timeout_ms);
  const V4l2CaptureCounters& vc = capture_->counters();
  incomplete_.store(vc.incomplete, std::memory_order_relaxed);
  driver_dropped_.store(vc.dropped, std::memory_order_relaxed);
  bad_timestamps_.store(vc.bad_timestamps, std::memory_order_relaxed);
  if (!got.ok()) {
    if (got.status().code() == core::ErrorCode::kCorruptData) return core::Status::Ok();  // counted, requeued
    if (!is_unplug(got.status())) return got.status();
    HWR_LOG_WARN("camera", "%s; reconnecting", got.status().message().c_str());
    capture_.reset();
    disconnects_.fetch_add(1, std::memory_order_relaxed);
    backoff_.failed(now_ns);
    return core::Status::Ok();
  }
  if (!got.value()) return core::Status::Ok();  // nothing within the timeout
  const V4l2Frame f = *got.value();
  // Stamped before anything below can drop the frame: the frame sync pairs every exposure the MCU
  // signals with a dequeued buffer (camera_clock_sync.hpp), kept or not.
  if (stamps_out_ != nullptr && !stamps_out_->try_push(CameraFrameStamp{f.t_ns, f.sequence})) {
    stamps_dropped_.fetch_add(1, std::memory_order_relaxed);
  }
  // Both eyes' gray halves and the left colour, converted straight from the kernel buffer
  // (side_by_side.hpp) into the images sized at open.
  YuyvFrameView view;
  view.data = f.data;
  view.size_bytes = f.bytes;
  view.width_px = f.width;
  view.height_px = f.height;
  view.stride_bytes = f.stride_bytes;
  const core::Status split = split_side_by_side_yuyv(view, &left_gray_, &right_gray_, &left_bgr_);
  if (core::Status st = capture_->requeue(f); !st.ok()) return st;  // the halves are copied out
  if (!split.ok()) return split;                                    // sized at open: a bug or a mode change

  RgbdFrame* out = spare_ != nullptr ? spare_ : streams->frame_pool.acquire();
  spare_ = nullptr;
  if (out == nullptr) {
    pool_empty_.fetch_add(1, std::memory_order_relaxed);
    return core::Status::Ok();
  }
  if (core::Status st = depth_->compute(left_gray_, right_gray_, left_bgr_, f.t_ns, f.sequence, out);
      !st.ok()) {
    depth_errors_.fetch_add(1, std::memory_order_relaxed);
    spare_ = out;
    return core::Status::Ok();
  }
  if (!streams->frames.try_push(out)) {
    ring_full_.fetch_add(1, std::memory_order_relaxed);
    spare_ = out;
    return core::Status::Ok();
  }
  frames_.fetch_add(1, std::memory_order_relaxed);
  return core::Status::Ok();
}

ZedCameraCounters ZedCameraReader::counters() const {
  ZedCameraCounters c;
  c.frames = frames_.load(std::memory_order_relaxed);
  c.pool_empty = pool_empty_.load(std::memory_order_relaxed);
  c.ring_full = ring_full_.load(std::memory_order_relaxed);
  c.depth_errors = depth_errors_.load(std::memory_order_relaxed);
  c.disconnects = disconnects_.load(std::memory_order_relaxed);
  c.reconnects = reconnects_.load(std::memory_order_relaxed);
  c.incomplete = incomplete_.load(std::memory_order_relaxed);
  c.driver_dropped = driver_dropped_.load(std::memory_order_relaxed);
  c.bad_timestamps = bad_timestamps_.load(std::memory_order_relaxed);
  c.stamps_dropped = stamps_dropped_.load(std::memory_order_relaxed);
  return c;
}

}  // namespace hwr::hal::hw
