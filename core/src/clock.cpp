#include <time.h>

#include <cerrno>

#include "hwr/core/time.hpp"

namespace hwr::core {

int64_t MonotonicClock::now_ns() const {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * kNsPerS + ts.tv_nsec;
}

void MonotonicClock::sleep_until_ns(int64_t t_ns) {
  timespec ts{};
  ts.tv_sec = t_ns / kNsPerS;
  ts.tv_nsec = t_ns % kNsPerS;
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

}  // namespace hwr::core
