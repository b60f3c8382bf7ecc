#include "hwr/hal/sensor_streams.hpp"

#include <vector>

#include <opencv2/core.hpp>

namespace hwr::hal {

SensorStreams::SensorStreams(const SensorStreamsConfig& config)
    : imu(config.imu_capacity),
      mag(config.mag_capacity),
      gnss(config.gnss_capacity),
      frames(config.frame_capacity),
      frame_pool(config.frame_pool_size),
      config_(config) {
  // Size every pooled frame now so decoding into it later reuses the buffers.
  std::vector<RgbdFrame*> all(config.frame_pool_size);
  for (size_t i = 0; i < config.frame_pool_size; ++i) {
    RgbdFrame* f = frame_pool.acquire();
    f->bgr.create(config.height, config.width, CV_8UC3);
    f->depth_m.create(config.height, config.width, CV_32FC1);
    if (config.stereo) f->right_gray.create(config.height, config.width, CV_8UC1);
    all[i] = f;
  }
  for (size_t i = 0; i < config.frame_pool_size; ++i) frame_pool.release(all[i]);
}

}  // namespace hwr::hal
