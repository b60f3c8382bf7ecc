#pragma once
// Records what the pipeline consumes (hwr-robot --record FILE) to an LCM log file (lcm::LogFile,
// the format lcm-logplayer and lcm-spy read), so a live run can be replayed exactly as the pipeline
// saw it (`--source lcmlog:FILE`, recording_log.hpp). Events, their LCM time stamp being the
// sample's t_ns in µs:
//   HWR_RECORDING_INFO recording_info_t  once, first: intrinsics, extrinsics, which streams exist
//   HWR_IMU imu_t, HWR_MAG mag_t, HWR_GNSS gnss_t    every sample
//   HWR_CAM_LEFT  image_t bgr8                       the (rectified) left image
//   HWR_CAM_DEPTH image_t depth uint16 mm (0 = none) the frame's depth, rounded to the millimetre
//                                                    (beyond 65.535 m: none)
//   HWR_CAM_RIGHT image_t mono8                      the rectified right image (stereo sources)
// The three images of a frame share its t_ns; image_t.size is the pixel bytes (rows packed).
// Data rate: 1280x720 at 30 fps is 5.5 MB per frame, ~166 MB/s: record to the AGX's NVMe, not eMMC.
//
// Threads: the record_* calls come from one thread (the scheduler's) and only copy into buffers
// preallocated at open() (the depth converted to mm on the way); a writer thread encodes and writes.
// When the writer falls behind, new samples and frames are dropped and counted, never the
// pipeline slowed (unless config.wait_when_full, for replays). A write error (disk full) stops the
// recording and is reported by close().

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "hwr/core/object_pool.hpp"
#include "hwr/core/spsc_ring.hpp"
#include "hwr/core/status.hpp"
#include "hwr/hal/gnss_fix.hpp"
#include "hwr/hal/imu_sample.hpp"
#include "hwr/hal/mag_sample.hpp"
#include "hwr/hal/rgbd_frame.hpp"
#include "hwr/hal/sensor_source.hpp"

namespace lcm {
class LogFile;
}
namespace hwr_lcm {
class image_t;
}

namespace hwr::mapio {

struct SensorRecorderConfig {
  size_t imu_capacity = 4096;  // samples waiting for the writer (10 s at 400 Hz)
  size_t mag_capacity = 1024;
  size_t gnss_capacity = 128;
  size_t frame_slots = 8;  // frames waiting for the writer (copies)
  // Recording a replay (a dataset, a simulator run, another recording): the pipeline is not paced by
  // the sensors, so record_* wait for the writer rather than drop, and the recording is complete.
  // Live sensors (false): drop and count, never slow the pipeline.
  bool wait_when_full = false;
};

struct SensorRecorderCounters {
  uint64_t imu = 0, mag = 0, gnss = 0, frames = 0;  // written
  uint64_t dropped = 0;                             // samples and frames the writer had no room for
  uint64_t bytes = 0;                               // event payload bytes written
};

class SensorRecorder {
 public:
  // Creates (truncates) path and writes the recording_info_t event. Frames must then be of
  // info.intrinsics' size (stereo: with right_gray). Errors: the file cannot be created (kIoError
  // naming it), intrinsics without a size.
  static core::Expected<std::unique_ptr<SensorRecorder>> open(const std::string& path,
                                                              const hal::SourceInfo& info,
                                                              const SensorRecorderConfig& config = {});
  ~SensorRecorder();  // close()
  SensorRecorder(const SensorRecorder&) = delete;
  SensorRecorder& operator=(const SensorRecorder&) = delete;

  // From one thread. No allocation; false when the sample was dropped (writer behind or stopped).
  bool record_imu(const hal::ImuSample& s);
  bool record_mag(const hal::MagSample& s);
  bool record_gnss(const hal::GnssFix& s);
  // A frame of another size or type is refused (counted as dropped).
  bool record_frame(const hal::RgbdFrame& f);

  // Writes what is queued, stops the writer and closes the file. The first write error, if any.
  core::Status close();

  SensorRecorderCounters counters() const;
  const std::string& path() const { return path_; }

 private:
  struct FrameSlot {
    int64_t t_ns = 0;
    cv::Mat bgr, depth_mm, right;
    cv::Mat beyond;  // CV_8UC1 scratch: depths past the uint16 range (become 0, not 65.535 m)
  };
  SensorRecorder(const std::string& path, const hal::SourceInfo& info, const SensorRecorderConfig& config);
  void writer_loop();
  bool drain_once();
  template <class T>
  bool push(core::SpscRing<T>* ring, const T& v);
  FrameSlot* acquire_slot();
  bool write_event(const char* channel, int64_t t_ns, const void* data, size_t size);
  template <class Msg>
  bool write_message(const char* channel, int64_t t_ns, const Msg& msg);
  bool write_image(const char* channel, int64_t t_ns, const cv::Mat& image, int8_t encoding);

  std::string path_;
  hal::SourceInfo info_;
  bool wait_when_full_ = false;
  std::unique_ptr<lcm::LogFile> log_;
  core::SpscRing<hal::ImuSample> imu_;
  core::SpscRing<hal::MagSample> mag_;
  core::SpscRing<hal::GnssFix> gnss_;
  core::SpscRing<FrameSlot*> frames_;
  core::ObjectPool<FrameSlot> slots_;
  std::vector<uint8_t> buf_;                 // the writer's encode buffer (reused)
  std::unique_ptr<hwr_lcm::image_t> image_;  // the writer's image message (its pixel vector reused)
  std::thread writer_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> failed_{false};
  std::atomic<uint64_t> written_imu_{0}, written_mag_{0}, written_gnss_{0}, written_frames_{0}, dropped_{0},
      bytes_{0};
  std::mutex error_mutex_;
  core::Status error_;
  bool closed_ = false;
};

}  // namespace hwr::mapio
