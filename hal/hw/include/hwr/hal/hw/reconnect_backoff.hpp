#pragma once
// When to try reopening a device that went away: 0.1 s after it failed, then doubling up to 2 s, so
// an unplugged sensor costs a few open() calls per second at most and a replugged one is back within
// 2 s. Driven by the caller's clock (tests pass their own times).

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <thread>

namespace hwr::hal::hw {

class ReconnectBackoff {
 public:
  static constexpr int64_t kFirstNs = 100'000'000;
  static constexpr int64_t kMaxNs = 2'000'000'000;

  bool due(int64_t now_ns) const { return now_ns >= retry_at_ns_; }
  // A reopen failed (or the device just went away) at now_ns.
  void failed(int64_t now_ns) {
    retry_at_ns_ = now_ns + delay_ns_;
    delay_ns_ = std::min(delay_ns_ * 2, kMaxNs);
  }
  void succeeded() {
    delay_ns_ = kFirstNs;
    retry_at_ns_ = 0;
  }
  int64_t next_delay_ns() const { return delay_ns_; }
  // A reader's step() while the device is away and the retry not yet due: sleeps until it is due,
  // at most max_ms (what one read would have waited), so the reader's loop does not spin.
  void wait_until_due(int64_t now_ns, int max_ms) const {
    const int64_t wait_ns = std::min<int64_t>(retry_at_ns_ - now_ns, int64_t{max_ms} * 1'000'000);
    if (wait_ns > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(wait_ns));
  }

 private:
  int64_t delay_ns_ = kFirstNs;
  int64_t retry_at_ns_ = 0;
};

}  // namespace hwr::hal::hw
