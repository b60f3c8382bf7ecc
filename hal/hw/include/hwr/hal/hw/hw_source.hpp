#pragma once
// The live sensors as a hal::SensorSource (`hwr-robot --source hw:CONFIG`). One thread per device
// fills the pipeline's rings directly as samples arrive (each ring has exactly one producer):
//   camera: ZED 2i over V4L2 → both eyes' gray and the left colour split from the side-by-side YUYV
//           frame → hal::StereoDepth (rectify + SGBM on the gray pair, the colour rectified alike)
//           → a pooled RgbdFrame stamped with the buffer's CLOCK_MONOTONIC time
//   zed sensors: the ZED 2i's MCU over USB HID (ZedSensorReader) → the IMU ring (imu: zed) and the
//           magnetometer ring, its clock put on the frames' timeline by the frame-sync events (the
//           camera thread sends every frame's stamp to it), by the receipt times until then
//   a9:     A9Reader → the IMU ring (imu: a9; device clock placed on CLOCK_MONOTONIC,
//           receipt_clock_map.hpp)
//   gnss:   GnssReader → the GNSS ring
// so the pipeline's timeline is the host's CLOCK_MONOTONIC and poll() only reports: a device error
// that a reconnect cannot fix stops the source (finished()), unplugging is counted and retried.
// open() checks every configured device and fails naming the first one that is missing; start()
// then launches the threads into the caller's SensorStreams (sized from info()).
// The magnetometer is passed on only with imu: zed (it is in the ZED's sensor axes, not the A9's).

#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "hwr/core/spsc_ring.hpp"
#include "hwr/core/status.hpp"
#include "hwr/hal/hw/camera_frame_stamp.hpp"
#include "hwr/hal/hw/hw_config.hpp"
#include "hwr/hal/sensor_source.hpp"

namespace hwr::hal::hw {

class A9Reader;
class GnssReader;
class ByteStream;
class ZedCameraReader;
class ZedSensorReader;
class UsbHidOps;

struct HwSourceCounters {
  uint64_t camera_disconnects = 0, camera_reconnects = 0, camera_incomplete = 0, camera_driver_dropped = 0;
  uint64_t a9_disconnects = 0, a9_crc_errors = 0;
  uint64_t gnss_disconnects = 0, gnss_fixes_from_gga = 0;
  uint64_t zed_sensor_disconnects = 0, zed_sensor_reports_dropped = 0;  // repeated, invalid, unparsable
  bool zed_clock_synced = false;  // the ZED IMU's samples are timed by the frame sync
  double zed_clock_drift_ppm = 0;
};

class HwSource final : public SensorSource {
 public:
  // now_ns: the host's CLOCK_MONOTONIC (the timeline's origin, info().first_t_ns).
  static core::Expected<std::unique_ptr<HwSource>> open(const HwConfig& config, const std::string& name,
                                                        int64_t now_ns);
  // The same with the ZED sensor MCU's USB device given (tests: a fake; null: libusb).
  static core::Expected<std::unique_ptr<HwSource>> open(const HwConfig& config, const std::string& name,
                                                        int64_t now_ns, std::unique_ptr<UsbHidOps> zed_usb);
  ~HwSource() override;
  HwSource(const HwSource&) = delete;
  HwSource& operator=(const HwSource&) = delete;

  // Launches the device threads into *streams (which must outlive the source or stop()).
  core::Status start(SensorStreams* streams);
  // Stops and joins the threads (also done by the destructor).
  void stop();

  const SourceInfo& info() const override { return info_; }
  core::Status poll(int64_t until_ns, SensorStreams* streams) override;
  bool finished() const override { return failed_.load(std::memory_order_acquire); }
  SourceCounters counters() const override;
  HwSourceCounters hw_counters() const;

 private:
  HwSource() = default;
  void fail(const core::Status& st);
  template <class Step>
  void run_thread(const char* what, Step step);

  HwConfig config_;
  SourceInfo info_;
  std::unique_ptr<ZedCameraReader> camera_;
  std::unique_ptr<ZedSensorReader> zed_sensors_;
  // Camera thread → sensor thread: every dequeued frame's stamp, for the frame sync.
  std::unique_ptr<core::SpscRing<CameraFrameStamp>> frame_stamps_;
  std::unique_ptr<ByteStream> a9_port_, gnss_port_;
  std::unique_ptr<A9Reader> a9_;
  std::unique_ptr<GnssReader> gnss_;
  std::vector<std::thread> threads_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> failed_{false};
  mutable std::mutex error_mutex_;
  core::Status error_;
};

}  // namespace hwr::hal::hw
