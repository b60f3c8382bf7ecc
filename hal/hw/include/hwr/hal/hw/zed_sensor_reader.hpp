#pragma once
// The ZED 2i's own sensors as a live stream (hardware.md "ZED 2i without the vendor SDK"): input
// reports from the sensor MCU over USB HID (usb_hid.hpp, ~400 Hz) → parse_zed_sensor_report →
// ZedReportMonitor (repeats dropped, gaps and restarts counted) → hal::ImuSample and, when the
// report carries a new reading, hal::MagSample, pushed into the pipeline's rings on the host's
// CLOCK_MONOTONIC. The reader is those rings' only producer.
//
// Time. Every report has the MCU's timestamp (t_imu). It is put on the host clock by
//  - the camera's frame sync, once CameraClockSync is locked: the frame stamps the camera thread
//    sends (camera_frame_stamp.hpp) paired with the reports flagged frame_sync give
//    t_imu = offset + (1 + drift)·t_host (camera_clock_sync.hpp eq. (1)), inverted here, so the IMU
//    samples and the V4L2 frames share one timeline to within the frame stamps' jitter;
//  - until then (or without a camera), the reports' receipt times (ReceiptClockMap: the lower
//    envelope of t_receipt − t_imu, within the USB latency floor, ~1 ms).
// The switch between the two may step the mapped times back by up to that floor; a sample that
// would not come after the previous one pushed is dropped (counted in out_of_order), so the rings
// stay monotonic.
//
// The stream is enabled at open() and kept alive (usb_hid.hpp); an unplugged MCU is reopened with
// ReconnectBackoff, and a reopened or reset MCU (its clock goes back) restarts the clock maps.
// step() does one read; run it in a loop on the reader's own thread, never in the scheduler's loop.
// No allocation after construction.

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>

#include "hwr/core/spsc_ring.hpp"
#include "hwr/core/status.hpp"
#include "hwr/hal/hw/camera_clock_sync.hpp"
#include "hwr/hal/hw/camera_frame_stamp.hpp"
#include "hwr/hal/hw/receipt_clock_map.hpp"
#include "hwr/hal/hw/reconnect_backoff.hpp"
#include "hwr/hal/hw/usb_hid.hpp"
#include "hwr/hal/hw/zed_sensor_report.hpp"
#include "hwr/hal/imu_sample.hpp"
#include "hwr/hal/mag_sample.hpp"

namespace hwr::hal::hw {

// Where the reader's output goes; any may be null (e.g. imu: a9 keeps the ZED's IMU out of the
// estimator's ring but still reads its magnetometer; no camera, no frame stamps).
struct ZedSensorOutputs {
  core::SpscRing<ImuSample>* imu = nullptr;
  core::SpscRing<MagSample>* mag = nullptr;
  // Frame stamps from the camera thread (this reader is the consumer).
  core::SpscRing<CameraFrameStamp>* frame_stamps = nullptr;
};

struct ZedSensorReaderCounters {
  uint64_t imu_samples = 0;     // pushed into the IMU ring (or that would have been: no ring)
  uint64_t mag_samples = 0;     // new magnetometer readings pushed
  uint64_t parse_errors = 0;    // short reports and other report ids
  uint64_t imu_not_valid = 0;   // reports with imu_not_valid set (skipped)
  uint64_t repeated = 0;        // the same timestamp again (dropped)
  uint64_t out_of_order = 0;    // mapped time not after the previous sample's (dropped)
  uint64_t clock_restarts = 0;  // the MCU's clock went back
  uint64_t gaps = 0;            // report gaps over 1.5 periods (ZedReportMonitor)
  uint64_t missed_sync_events = 0;
  uint64_t frame_stamps = 0;    // received from the camera thread
  uint64_t synced_samples = 0;  // samples timed by the frame sync (the rest by receipt times)
  uint64_t disconnects = 0, reconnects = 0, keep_alives = 0;
  bool sync_locked = false;   // CameraClockSync's current state
  double sync_drift_ppm = 0;  // ... its drift estimate and residual RMS when locked
  double sync_residual_rms_ns = 0;
};

class ZedSensorReader {
 public:
  // The host's CLOCK_MONOTONIC in ns, read right after each report arrives (its receipt time).
  using Clock = std::function<int64_t()>;
  static int64_t monotonic_ns();

  // Takes the USB device (make_libusb_hid_ops() on the robot, a fake in the tests) and the clock
  // (the tests' fake device advances its own).
  ZedSensorReader(std::unique_ptr<UsbHidOps> usb, const ZedSensorOutputs& outputs,
                  const ZedHidConfig& hid = {}, const CameraClockSyncConfig& sync = {},
                  Clock clock = &ZedSensorReader::monotonic_ns);

  // Opens the MCU and enables its stream. Errors (the robot refuses to start): NotFound (not
  // attached), IoError (permissions: names toolchain/deploy/99-hwr.rules; busy), Unavailable.
  core::Status open(int64_t now_ns);
  // Where the samples go (replacing the constructor's); only before step() runs on the reader's
  // thread (HwSource opens the device first and learns the rings at start()).
  void set_outputs(const ZedSensorOutputs& outputs) { out_ = outputs; }

  // One read of up to read_timeout_ms, keep-alive when due, the report's samples pushed. now_ns: the
  // host's CLOCK_MONOTONIC when called. An error only for what a reconnect cannot fix; unplugging
  // is counted and retried.
  core::Status step(int64_t now_ns, int read_timeout_ms = 20);

  ZedSensorReaderCounters counters() const;
  bool connected() const { return connected_.load(std::memory_order_relaxed); }

 private:
  void restart_clocks();
  void drain_frame_stamps();
  void handle_report(const uint8_t* bytes, size_t n, int64_t t_receipt_ns);

  std::unique_ptr<UsbHidOps> usb_;
  Clock clock_;
  ZedHidStream hid_;
  ZedSensorOutputs out_;
  ZedReportMonitor monitor_;
  ReceiptClockMap receipt_map_;
  CameraClockSync sync_;
  ReconnectBackoff backoff_;
  std::array<uint8_t, ZedHidStream::kReportBytes> buf_{};
  int64_t last_pushed_ns_ = INT64_MIN;
  std::atomic<bool> connected_{false};
  // Written by the reader thread, read by counters() from any thread.
  std::atomic<uint64_t> imu_samples_{0}, mag_samples_{0}, parse_errors_{0}, imu_not_valid_{0}, repeated_{0},
      out_of_order_{0}, clock_restarts_{0}, gaps_{0}, missed_sync_events_{0}, frame_stamps_{0},
      synced_samples_{0}, disconnects_{0}, reconnects_{0}, keep_alives_{0};
  std::atomic<bool> sync_locked_{false};
  std::atomic<double> sync_drift_ppm_{0}, sync_residual_rms_ns_{0};
};

}  // namespace hwr::hal::hw
