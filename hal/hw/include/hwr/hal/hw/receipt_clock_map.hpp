#pragma once
// A device's own sample clock (e.g. the A9's µs stamps) put on the host's CLOCK_MONOTONIC from the
// times its bytes arrived. Every arrival is later than the sample by the transport latency
// (USB/serial buffering, scheduling), which is never negative and often close to its minimum, so
// the offset host − device is estimated by the smallest (t_receipt − t_device) seen over a sliding
// window (a lower envelope, as in the "convex hull" / minimum-delay clock-sync methods of network
// time keeping). The window (default 10 s) bounds how far device drift can pull the estimate: at
// 100 ppm drift, 1 ms over 10 s. Stamps are then t_host = t_device + offset, so the intervals
// between samples keep the device's precision instead of the arrival jitter.
// No allocation after construction (a fixed ring of per-second minima).

#include <array>
#include <cstdint>
#include <optional>

namespace hwr::hal::hw {

class ReceiptClockMap {
 public:
  // window_s: how many 1-second buckets the minimum is taken over (1..kMaxWindowS).
  explicit ReceiptClockMap(int window_s = 10);

  // One sample: its device stamp (ns on the device's clock, monotonic) and when its last byte was
  // read on the host (CLOCK_MONOTONIC ns). Returns the sample's host time.
  int64_t map(int64_t t_device_ns, int64_t t_receipt_ns);

  // The current offset t_host − t_device (none before the first sample).
  std::optional<int64_t> offset_ns() const;
  // Forgets everything (the device was reopened: its clock may have restarted).
  void reset();

  static constexpr int kMaxWindowS = 64;

 private:
  struct Bucket {
    int64_t second = INT64_MIN;  // t_receipt_ns / 1e9 of the bucket's samples
    int64_t min_delay_ns = 0;    // smallest t_receipt − t_device in it
  };
  int window_s_;
  std::array<Bucket, kMaxWindowS> buckets_{};
  bool started_ = false;
};

}  // namespace hwr::hal::hw
