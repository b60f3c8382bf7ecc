#pragma once
// The bounded queues between the HAL and the pipeline (ARCHITECTURE.md data flow: hal →
// core::Scheduler). Everything is allocated here, at start-up, from the configured capacities:
// the sample rings and a pool of camera frames whose image buffers are sized for the camera, so
// the steady-state loop only refills them. A full ring drops the oldest sample and counts it;
// an empty frame pool drops the new frame and counts it.
//
// Threads: the HAL side (a source's poll()) produces and the pipeline side consumes; frames are
// acquired from the pool by the HAL side and released by the pipeline side (core::ObjectPool's
// single-acquirer/single-releaser contract).

#include <cstddef>

#include "hwr/core/object_pool.hpp"
#include "hwr/core/spsc_ring.hpp"
#include "hwr/hal/gnss_fix.hpp"
#include "hwr/hal/imu_sample.hpp"
#include "hwr/hal/mag_sample.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/hal/rgbd_frame.hpp"

namespace hwr::hal {

struct SensorStreamsConfig {
  size_t imu_capacity = 512;  // 2.5 s at 200 Hz
  size_t mag_capacity = 128;
  size_t gnss_capacity = 32;
  size_t frame_capacity = 4;   // frames waiting for the pipeline
  size_t frame_pool_size = 8;  // frames in flight: waiting + being processed + being loaded
  int width = 640;             // frame buffers are preallocated at this size
  int height = 480;
  bool stereo = false;  // also preallocate right_gray
};

class SensorStreams {
 public:
  explicit SensorStreams(const SensorStreamsConfig& config);
  SensorStreams(const SensorStreams&) = delete;
  SensorStreams& operator=(const SensorStreams&) = delete;

  const SensorStreamsConfig& config() const { return config_; }

  core::SpscRing<ImuSample> imu;
  core::SpscRing<MagSample> mag;
  core::SpscRing<GnssFix> gnss;
  core::SpscRing<RgbdFrame*> frames;  // owned by frame_pool; release after use
  core::ObjectPool<RgbdFrame> frame_pool;

 private:
  SensorStreamsConfig config_;
};

}  // namespace hwr::hal
