#pragma once
// Fixed-rate cooperative scheduler over a constexpr task table (rate, time budget, priority), in
// the manner of ArduPilot's AP_Scheduler: one thread, no preemption, every task's release times
// fixed in advance, overruns and slips counted per task and exposed as telemetry.
//
//   constexpr TaskSpec kTasks[] = {{"imu", 200, 500'000, 0}, {"camera", 30, 20'000'000, 1}};
//   Scheduler sched(kTasks, 2, clock);
//   sched.bind(0, &imu_task, &imu_state);
//   sched.run_until(clock.now_ns() + 60 * kNsPerS);
//
// Timing model:
//  - Release k of a task is at start_ns + llround(k * 1e9 / rate_hz): computed from k, never by
//    adding periods, so rounding does not accumulate into drift.
//  - A cycle sleeps on the timeline clock until the earliest pending release, then runs every task
//    that is due at that instant, in priority order (0 = highest; ties by table order). A task
//    never interrupts another; a long task delays the rest of its cycle.
//  - A task behind by at most max_catchup periods runs its missed releases back to back (one per
//    cycle); one behind by more skips to its latest release and counts the skipped ones.
//  - Duration is measured on the execution clock (the timeline clock unless set otherwise, e.g. a
//    MonotonicClock to measure real work while replaying on a SimClock). With a SimClock timeline,
//    a run is deterministic; a task models work by calling SimClock::advance_ns.
//
// Threads: construct, bind and run on one thread. request_stop(), snapshot() and
// format_telemetry() may be called from any thread. Nothing allocates: storage for kMaxTasks tasks
// is inside the object.

#include <atomic>
#include <cstddef>
#include <cstdint>

#include "hwr/core/status.hpp"
#include "hwr/core/time.hpp"

namespace hwr::core {

struct TaskSpec {
  const char* name;
  double rate_hz;     // > 0
  int64_t budget_ns;  // a run longer than this is an overrun
  int priority;       // 0 = highest
};

// A task: ctx is the pointer given to bind(), now_ns the timeline time at which it starts.
using TaskFn = void (*)(void* ctx, int64_t now_ns);

struct SchedulerOptions {
  // A start later than release + slip_tolerance * period counts as a slip.
  double slip_tolerance = 0.1;
  // A task more than this many periods behind skips its missed releases.
  uint64_t max_catchup = 2;
};

struct TaskTelemetry {
  const char* name = nullptr;
  double rate_hz = 0.0;
  int64_t budget_ns = 0;
  int priority = 0;
  uint64_t runs = 0;
  uint64_t overruns = 0;          // duration > budget_ns
  uint64_t slips = 0;             // start - release > slip tolerance
  uint64_t skipped_releases = 0;  // releases dropped by the catch-up rule
  int64_t max_exec_ns = 0;
  int64_t total_exec_ns = 0;
  int64_t max_slip_ns = 0;
};

// One line per task with a header line, into buf (always NUL-terminated when buf_len > 0). Returns
// the length the full text needs, like snprintf: a result >= buf_len means it was truncated.
size_t format_telemetry(const TaskTelemetry* tasks, size_t n, char* buf, size_t buf_len);

class Scheduler {
 public:
  static constexpr size_t kMaxTasks = 32;

  // The table is copied. A bad table (too many tasks, rate <= 0, budget <= 0, no name) is reported
  // by status(); tasks past kMaxTasks are ignored.
  Scheduler(const TaskSpec* table, size_t n, Clock& timeline_clock, const SchedulerOptions& options = {});
  Scheduler(const Scheduler&) = delete;
  Scheduler& operator=(const Scheduler&) = delete;

  // OK when the table is valid and every task is bound.
  Status status() const;

  void bind(size_t index, TaskFn fn, void* ctx);
  void set_execution_clock(Clock& clock) { exec_clock_ = &clock; }
  // Release 0 of every task is at start_ns. If never called, the first cycle starts at the
  // timeline clock's now.
  void start(int64_t start_ns);

  // One cycle (see the timing model). Returns the number of task runs in it; 0 when no task is
  // bound. Unbound tasks are skipped.
  int step();
  // Cycles until the next release is at or after end_ns (releases at t < end_ns run), or until
  // request_stop(), which this call then consumes. Fails without running if status() is not OK.
  Status run_until(int64_t end_ns);
  void request_stop() { stop_.store(true, std::memory_order_release); }

  size_t num_tasks() const { return n_; }
  int64_t start_ns() const { return start_ns_; }
  // Release k of task i.
  int64_t release_ns(size_t i, uint64_t k) const;
  int64_t next_release_ns(size_t i) const { return tasks_[i].next_release_ns; }

  // Copies up to n tasks' telemetry in table order; returns how many. Each task's counters are
  // mutually consistent (per-task seqlock).
  size_t snapshot(TaskTelemetry* out, size_t n) const;
  size_t format_telemetry(char* buf, size_t buf_len) const;

 private:
  // Counters readable from other threads: single writer (the scheduler thread), seqlock readers.
  struct alignas(64) SharedCounters {
    std::atomic<uint32_t> seq{0};
    std::atomic<uint64_t> runs{0}, overruns{0}, slips{0}, skipped{0};
    std::atomic<int64_t> max_exec_ns{0}, total_exec_ns{0}, max_slip_ns{0};
  };
  struct Task {
    TaskSpec spec{};
    TaskFn fn = nullptr;
    void* ctx = nullptr;
    int64_t slip_tolerance_ns = 0;
    uint64_t k = 0;  // index of the next release to run
    int64_t next_release_ns = 0;
    TaskTelemetry stats;  // the scheduler thread's own copy, published into shared
  };

  int cycle(int64_t limit_ns);
  int64_t earliest_release() const;
  // Largest m >= task.k with release m <= t_ns (t_ns >= the release of task.k).
  uint64_t last_release_at_or_before(size_t i, int64_t t_ns) const;
  void publish(size_t i);

  Task tasks_[kMaxTasks];
  SharedCounters shared_[kMaxTasks];
  uint8_t order_[kMaxTasks] = {};  // task indices by priority
  size_t n_ = 0;
  bool table_too_long_ = false;
  Clock* timeline_;
  Clock* exec_clock_;
  SchedulerOptions options_;
  bool started_ = false;
  int64_t start_ns_ = 0;
  std::atomic<bool> stop_{false};
};

}  // namespace hwr::core
