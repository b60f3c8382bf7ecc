#include "hwr/hal/hw/receipt_clock_map.hpp"

#include <algorithm>

namespace hwr::hal::hw {

ReceiptClockMap::ReceiptClockMap(int window_s) : window_s_(std::clamp(window_s, 1, kMaxWindowS)) {}

void ReceiptClockMap::reset() {
  buckets_.fill(Bucket{});
  started_ = false;
}

int64_t ReceiptClockMap::map(int64_t t_device_ns, int64_t t_receipt_ns) {
  const int64_t delay = t_receipt_ns - t_device_ns;
  const int64_t second = t_receipt_ns / 1'000'000'000;
  Bucket& b = buckets_[static_cast<size_t>(((second % window_s_) + window_s_) % window_s_)];
  if (b.second != second) {
    b.second = second;  // a new second reuses the slot of the one window_s seconds ago
    b.min_delay_ns = delay;
  } else {
    b.min_delay_ns = std::min(b.min_delay_ns, delay);
  }
  started_ = true;
  return t_device_ns + *offset_ns();
}

std::optional<int64_t> ReceiptClockMap::offset_ns() const {
  if (!started_) return std::nullopt;
  int64_t newest = INT64_MIN;
  for (int i = 0; i < window_s_; ++i) newest = std::max(newest, buckets_[static_cast<size_t>(i)].second);
  std::optional<int64_t> best;
  for (int i = 0; i < window_s_; ++i) {
    const Bucket& b = buckets_[static_cast<size_t>(i)];
    if (b.second == INT64_MIN || b.second <= newest - window_s_) continue;  // empty or too old
    if (!best || b.min_delay_ns < *best) best = b.min_delay_ns;
  }
  return best;
}

}  // namespace hwr::hal::hw
