#pragma once
// Time is int64_t nanoseconds named t_ns (ARCHITECTURE.md "Frames and names"). A Clock gives the
// scheduler its timeline: MonotonicClock on the robot, SimClock for replay and simulation, where
// sleeping advances time instantly so a run is deterministic and faster than real time.

#include <cstdint>

namespace hwr::core {

constexpr int64_t kNsPerUs = 1'000;
constexpr int64_t kNsPerMs = 1'000'000;
constexpr int64_t kNsPerS = 1'000'000'000;

constexpr double ns_to_s(int64_t t_ns) { return static_cast<double>(t_ns) * 1e-9; }
// Rounds to the nearest nanosecond.
constexpr int64_t s_to_ns(double t_s) { return static_cast<int64_t>(t_s * 1e9 + (t_s >= 0 ? 0.5 : -0.5)); }

class Clock {
 public:
  virtual ~Clock() = default;
  virtual int64_t now_ns() const = 0;
  // Returns when now_ns() >= t_ns (immediately if already past).
  virtual void sleep_until_ns(int64_t t_ns) = 0;
};

// CLOCK_MONOTONIC, the clock uvcvideo stamps V4L2 buffers with.
class MonotonicClock final : public Clock {
 public:
  int64_t now_ns() const override;
  void sleep_until_ns(int64_t t_ns) override;
};

// Simulated time: starts at start_ns, moves only through sleep_until_ns() and advance_ns().
// Not thread-safe; one scheduler thread owns it.
class SimClock final : public Clock {
 public:
  explicit SimClock(int64_t start_ns = 0) : now_ns_(start_ns) {}
  int64_t now_ns() const override { return now_ns_; }
  void sleep_until_ns(int64_t t_ns) override {
    if (t_ns > now_ns_) now_ns_ = t_ns;
  }
  // Models work that takes dt_ns (tests inject slow tasks this way).
  void advance_ns(int64_t dt_ns) { now_ns_ += dt_ns; }

 private:
  int64_t now_ns_;
};

}  // namespace hwr::core
