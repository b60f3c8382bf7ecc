#include "hwr/hal/stream_health.hpp"

#include <cmath>

namespace hwr::hal {

StreamMonitor::StreamMonitor(double rate_hz, double gap_factor)
    : gap_ns_(rate_hz > 0 ? static_cast<int64_t>(gap_factor * 1e9 / rate_hz) : 0) {}

bool StreamMonitor::check_time(int64_t t_ns) {
  if (health_.samples > 0) {
    const int64_t dt = t_ns - health_.last_t_ns;
    if (dt <= 0) {
      ++health_.non_increasing_t;
      return false;
    }
    if (dt > health_.max_interval_ns) health_.max_interval_ns = dt;
    if (gap_ns_ > 0 && dt > gap_ns_) ++health_.gaps;
  }
  ++health_.samples;
  health_.last_t_ns = t_ns;
  return true;
}

bool StreamMonitor::check(const ImuSample& s) {
  if (!s.gyro_radps.allFinite() || !s.accel_mps2.allFinite()) {
    ++health_.non_finite;
    return false;
  }
  return check_time(s.t_ns);
}

bool StreamMonitor::check(const RgbdFrame& f) {
  if (!check_time(f.t_ns)) return false;
  const double px = static_cast<double>(f.depth_m.total());
  if (px > 0 && f.invalid_depth_px > 0.5 * px) ++frames_low_depth_;
  return true;
}

}  // namespace hwr::hal
