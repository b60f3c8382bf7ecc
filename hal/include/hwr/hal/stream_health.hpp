#pragma once
// Health of one sensor stream as the pipeline receives it: samples, timestamps that do not
// increase, gaps longer than gap_factor nominal periods (a dropout), and samples with non-finite
// values. Hardware faults degrade the estimate and are reported; they never stop the process
// (ARCHITECTURE.md firmware rules) — these counters are how they are reported.

#include <cstdint>

#include "hwr/hal/imu_sample.hpp"
#include "hwr/hal/rgbd_frame.hpp"

namespace hwr::hal {

struct StreamHealth {
  uint64_t samples = 0;
  uint64_t non_increasing_t = 0;  // rejected: t_ns <= previous
  uint64_t gaps = 0;              // interval > gap_factor / rate
  uint64_t non_finite = 0;        // rejected: NaN/inf values
  int64_t max_interval_ns = 0;
  int64_t last_t_ns = 0;
};

class StreamMonitor {
 public:
  // rate_hz <= 0 disables gap detection.
  explicit StreamMonitor(double rate_hz, double gap_factor = 2.5);

  // Returns true when the sample is usable (finite, newer than the last one).
  bool check(const ImuSample& s);
  bool check(const RgbdFrame& f);
  const StreamHealth& health() const { return health_; }
  // Frames whose valid-depth fraction was below 50 %.
  uint64_t frames_low_depth() const { return frames_low_depth_; }

 private:
  bool check_time(int64_t t_ns);

  int64_t gap_ns_ = 0;
  StreamHealth health_;
  uint64_t frames_low_depth_ = 0;
};

}  // namespace hwr::hal
