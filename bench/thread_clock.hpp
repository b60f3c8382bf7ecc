#pragma once
// Per-thread CPU clocks for the peer benches: both sides of a comparison are timed on the thread
// that runs them, so other threads (ours or the peer's) do not count.

#include <sys/resource.h>
#include <time.h>

namespace hwr::bench {

// CPU time of this thread (user + system), seconds.
inline double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// Kernel time of this thread (RUSAGE_THREAD, Linux), seconds.
inline double thread_sys_s() {
  rusage ru{};
  getrusage(RUSAGE_THREAD, &ru);
  return static_cast<double>(ru.ru_stime.tv_sec) + 1e-6 * static_cast<double>(ru.ru_stime.tv_usec);
}

}  // namespace hwr::bench
