#pragma once
// A source of sensor data for the pipeline: dataset replay, the simulator's runs, and (later) the
// hardware drivers all implement this one narrow interface. The scheduler's HAL task calls poll()
// at a fixed rate; poll moves every sample stamped at or before until_ns into the streams and
// returns at once (it never blocks the control loop on I/O: file reading happens on the
// source's own thread).

#include <cstdint>
#include <string>

#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/hal/sensor_streams.hpp"

namespace hwr::hal {

struct SourceInfo {
  std::string name;  // e.g. "tum:/data/rgbd_dataset_freiburg3_teddy"
  PinholeIntrinsics intrinsics;
  Eigen::Isometry3d T_imu_cam = Eigen::Isometry3d::Identity();
  Eigen::Vector3d gnss_antenna_imu_m = Eigen::Vector3d::Zero();  // the GNSS antenna in the IMU frame
  Eigen::Vector3d mag_hard_iron_uT = Eigen::Vector3d::Zero();    // magnetometer offset, sensor frame
  bool has_imu = false;  // gyro + accelerometer (TUM has accelerometer only: has_imu false)
  bool has_mag = false;
  bool has_gnss = false;
  bool stereo = false;
  double camera_rate_hz = 0;
  double imu_rate_hz = 0;
  int64_t first_t_ns = 0;  // earliest sample of any stream
  int64_t last_t_ns = 0;   // latest sample of any stream
};

// Counters a source keeps for telemetry.
struct SourceCounters {
  uint64_t frames = 0;  // delivered into streams.frames
  uint64_t imu = 0;
  uint64_t mag = 0;
  uint64_t gnss = 0;
  uint64_t frames_dropped = 0;  // frame pool empty or frame ring full
  uint64_t frame_errors = 0;    // a frame that could not be read/decoded (skipped)
  // Replay only: polls that waited for the prefetch thread to decode a frame, and the total wait
  // (the replay is I/O-bound when these grow; the wait is part of the calling task's run time).
  uint64_t decode_waits = 0;
  int64_t decode_wait_ns = 0;
};

class SensorSource {
 public:
  virtual ~SensorSource() = default;
  virtual const SourceInfo& info() const = 0;
  // Moves the samples with t_ns <= until_ns into *streams. A bad frame is skipped, counted and
  // logged, not returned as an error; an error Status means the source cannot go on.
  virtual core::Status poll(int64_t until_ns, SensorStreams* streams) = 0;
  // True when every sample has been delivered (replay) or the device is gone for good.
  virtual bool finished() const = 0;
  virtual SourceCounters counters() const = 0;
};

}  // namespace hwr::hal
