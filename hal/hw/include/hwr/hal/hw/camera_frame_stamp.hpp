#pragma once
// One dequeued V4L2 frame of the ZED 2i as the clock sync needs it (camera_clock_sync.hpp): the
// buffer's CLOCK_MONOTONIC stamp (uvcvideo: start of exposure) and the driver's sequence number. The
// camera thread sends one per dequeued frame (kept or not) to the sensor thread through an SpscRing.

#include <cstdint>

namespace hwr::hal::hw {

struct CameraFrameStamp {
  int64_t t_host_ns = 0;  // CLOCK_MONOTONIC
  uint32_t sequence = 0;  // v4l2_buffer.sequence
};

}  // namespace hwr::hal::hw
