// Scheduler on a SimClock: every expectation is a closed-form count derived from the release rule
// start + llround(k * 1e9 / rate_hz). No test asserts on wall-clock timing.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <thread>

#include "hwr/core/alloc_counter.hpp"
#include "hwr/core/scheduler.hpp"

namespace hwr::core {
namespace {

constexpr TaskSpec kTasks[] = {
    {"imu", 200, 500'000, 0},
    {"camera", 30, 20'000'000, 1},
    {"keyframe", 10, 50'000'000, 2},
    {"map", 1, 10'000'000, 3},
};
static_assert(kTasks[0].rate_hz == 200, "the task table is a constant expression");
constexpr size_t kNumTasks = sizeof(kTasks) / sizeof(kTasks[0]);

// A task that models work_ns of computation on the clock it is given and checks that it is only
// ever started at or after its own releases.
struct Worker {
  SimClock* clock = nullptr;
  int64_t work_ns = 0;
  uint64_t runs = 0;
  int64_t last_now_ns = INT64_MIN;
  bool monotonic = true;
  static void run(void* ctx, int64_t now_ns) {
    auto* w = static_cast<Worker*>(ctx);
    if (now_ns < w->last_now_ns) w->monotonic = false;
    w->last_now_ns = now_ns;
    ++w->runs;
    if (w->work_ns > 0) w->clock->advance_ns(w->work_ns);
  }
};

TaskTelemetry telemetry_of(const Scheduler& s, size_t i) {
  TaskTelemetry t[Scheduler::kMaxTasks];
  s.snapshot(t, Scheduler::kMaxTasks);
  return t[i];
}

TEST(Scheduler, GivenFourRateTableWhenRunForASimulatedMinuteThenExactRunCounts) {
  // GIVEN the 200/30/10/1 Hz table on a simulated clock, tasks taking no time
  SimClock clock(1'000'000'000);
  Scheduler sched(kTasks, kNumTasks, clock);
  Worker w[kNumTasks];
  for (size_t i = 0; i < kNumTasks; ++i) {
    w[i].clock = &clock;
    sched.bind(i, &Worker::run, &w[i]);
  }
  ASSERT_TRUE(sched.status().ok()) << sched.status().to_string();
  // WHEN it runs for 60 s
  sched.start(clock.now_ns());
  ASSERT_TRUE(sched.run_until(clock.now_ns() + 60 * kNsPerS).ok());
  // THEN each task ran rate * 60 times (release 60 s itself is excluded), on time
  const uint64_t expected[] = {12000, 1800, 600, 60};
  for (size_t i = 0; i < kNumTasks; ++i) {
    const TaskTelemetry t = telemetry_of(sched, i);
    EXPECT_EQ(w[i].runs, expected[i]) << kTasks[i].name;
    EXPECT_EQ(t.runs, expected[i]) << kTasks[i].name;
    EXPECT_EQ(t.overruns, 0u);
    EXPECT_EQ(t.slips, 0u);
    EXPECT_EQ(t.skipped_releases, 0u);
    EXPECT_EQ(t.max_slip_ns, 0);
    EXPECT_EQ(t.total_exec_ns, 0);
    EXPECT_TRUE(w[i].monotonic);
    // The last run started exactly at the last release before 60 s.
    EXPECT_EQ(w[i].last_now_ns, sched.release_ns(i, expected[i] - 1));
  }
  EXPECT_EQ(clock.now_ns(), sched.release_ns(0, 11999));  // never slept past the last release
}

TEST(Scheduler, GivenNonIntegerPeriodsWhenReleasesComputedThenNoDriftAccumulates) {
  // 3 Hz and 7 Hz periods are not whole nanoseconds; adding rounded periods would drift.
  constexpr TaskSpec table[] = {{"three", 3, 1'000'000, 0}, {"seven", 7, 1'000'000, 1}};
  SimClock clock(0);
  Scheduler sched(table, 2, clock);
  sched.start(5);
  for (uint64_t n : {1ull, 10ull, 1000ull, 1'000'000ull}) {
    EXPECT_EQ(sched.release_ns(0, 3 * n), 5 + static_cast<int64_t>(n) * kNsPerS);
    EXPECT_EQ(sched.release_ns(1, 7 * n), 5 + static_cast<int64_t>(n) * kNsPerS);
  }
  EXPECT_EQ(sched.release_ns(0, 1), 5 + 333'333'333);
  EXPECT_EQ(sched.release_ns(0, 2), 5 + 666'666'667);
  Worker w[2];
  for (size_t i = 0; i < 2; ++i) {
    w[i].clock = &clock;
    sched.bind(i, &Worker::run, &w[i]);
  }
  ASSERT_TRUE(sched.run_until(5 + 3600 * kNsPerS).ok());
  EXPECT_EQ(w[0].runs, 3u * 3600u);
  EXPECT_EQ(w[1].runs, 7u * 3600u);
}

// A slow 1 Hz task (work_ns, budget 10 ms) delays the 5 ms-period imu task once per second.
struct SlowCase {
  int64_t work_ms;
  uint64_t imu_runs;
  uint64_t imu_skipped;
  uint64_t imu_slips;
  int64_t imu_max_slip_ms;
};

class SchedulerSlowTask : public ::testing::TestWithParam<SlowCase> {};

TEST_P(SchedulerSlowTask, GivenSlowLowPriorityTaskWhenRunThenOverrunsCountedAndHigherTasksKeepTheirCounts) {
  const SlowCase c = GetParam();
  // GIVEN the table with the 1 Hz task doing work_ms of work per run
  SimClock clock(0);
  Scheduler sched(kTasks, kNumTasks, clock);
  Worker w[kNumTasks];
  for (size_t i = 0; i < kNumTasks; ++i) {
    w[i].clock = &clock;
    sched.bind(i, &Worker::run, &w[i]);
  }
  w[3].work_ns = c.work_ms * kNsPerMs;
  // WHEN it runs for a simulated minute
  sched.start(0);
  ASSERT_TRUE(sched.run_until(60 * kNsPerS).ok());
  // THEN the slow task overran on every run
  const TaskTelemetry slow = telemetry_of(sched, 3);
  EXPECT_EQ(slow.runs, 60u);
  EXPECT_EQ(slow.overruns, 60u);
  EXPECT_EQ(slow.max_exec_ns, c.work_ms * kNsPerMs);
  EXPECT_EQ(slow.total_exec_ns, 60 * c.work_ms * kNsPerMs);
  // AND the imu task caught up (or skipped, beyond max_catchup = 2 periods) with bounded slip:
  // the slow task ends at s + work; imu releases s + 5k ms inside it are late by (work - 5k) ms.
  const TaskTelemetry imu = telemetry_of(sched, 0);
  EXPECT_EQ(imu.runs, c.imu_runs);
  EXPECT_EQ(imu.skipped_releases, c.imu_skipped);
  EXPECT_EQ(imu.runs + imu.skipped_releases, 12000u);
  EXPECT_EQ(imu.slips, c.imu_slips);
  EXPECT_EQ(imu.max_slip_ns, c.imu_max_slip_ms * kNsPerMs);
  EXPECT_LE(imu.max_slip_ns, c.work_ms * kNsPerMs);
  EXPECT_EQ(imu.overruns, 0u);
  // AND the 30 Hz and 10 Hz tasks, whose releases never fall inside the slow run, are untouched
  for (size_t i : {size_t{1}, size_t{2}}) {
    const TaskTelemetry t = telemetry_of(sched, i);
    EXPECT_EQ(t.runs, i == 1 ? 1800u : 600u);
    EXPECT_EQ(t.slips, 0u);
    EXPECT_EQ(t.overruns, 0u);
    EXPECT_EQ(t.skipped_releases, 0u);
  }
}

INSTANTIATE_TEST_SUITE_P(WorkDurations, SchedulerSlowTask,
                         ::testing::Values(
                             // 12 ms: releases at 5, 10 ms run late by 7, 2 ms (both > 0.5 ms tolerance).
                             SlowCase{12, 12000, 0, 2 * 60, 7},
                             // 15 ms: 2 periods behind is still caught up: late by 10, 5, 0 ms.
                             SlowCase{15, 12000, 0, 2 * 60, 10},
                             // 16 ms: releases 5, 10, 15 ms late by 11, 6, 1 ms.
                             SlowCase{16, 12000, 0, 3 * 60, 11},
                             // 30 ms: 5 periods behind > 2: releases 5..25 ms skipped, 30 ms runs on time.
                             SlowCase{30, 12000 - 5 * 60, 5 * 60, 0, 0}));

TEST(Scheduler, GivenTasksDueTogetherWhenACycleRunsThenTheyRunInPriorityOrder) {
  // GIVEN four tasks at the same rate, listed out of priority order (two share priority 1)
  constexpr TaskSpec table[] = {{"low", 10, 1'000'000, 3},
                                {"high", 10, 1'000'000, 0},
                                {"mid_a", 10, 1'000'000, 1},
                                {"mid_b", 10, 1'000'000, 1}};
  struct Recorder {
    int order[64];
    int n = 0;
  } rec;
  struct Tag {
    Recorder* rec;
    int id;
    static void run(void* ctx, int64_t) {
      auto* t = static_cast<Tag*>(ctx);
      if (t->rec->n < 64) t->rec->order[t->rec->n++] = t->id;
    }
  };
  Tag tags[4] = {{&rec, 0}, {&rec, 1}, {&rec, 2}, {&rec, 3}};
  SimClock clock(0);
  Scheduler sched(table, 4, clock);
  for (size_t i = 0; i < 4; ++i) sched.bind(i, &Tag::run, &tags[i]);
  // WHEN three cycles run
  sched.start(0);
  EXPECT_EQ(sched.step(), 4);
  EXPECT_EQ(sched.step(), 4);
  EXPECT_EQ(sched.step(), 4);
  // THEN each cycle ran high, mid_a, mid_b (table order breaks the tie), low
  ASSERT_EQ(rec.n, 12);
  for (int c = 0; c < 3; ++c) {
    EXPECT_EQ(rec.order[4 * c + 0], 1);
    EXPECT_EQ(rec.order[4 * c + 1], 2);
    EXPECT_EQ(rec.order[4 * c + 2], 3);
    EXPECT_EQ(rec.order[4 * c + 3], 0);
  }
  EXPECT_EQ(clock.now_ns(), 200'000'000);  // the third cycle slept to the third release
}

TEST(Scheduler, GivenPreallocatedSchedulerWhenTenThousandCyclesRunThenZeroAllocations) {
  SimClock clock(0);
  Scheduler sched(kTasks, kNumTasks, clock);
  Worker w[kNumTasks];
  for (size_t i = 0; i < kNumTasks; ++i) {
    w[i].clock = &clock;
    w[i].work_ns = 10'000;
    sched.bind(i, &Worker::run, &w[i]);
  }
  sched.start(0);
  AllocationScope scope;
  int runs = 0;
  for (int i = 0; i < 10'000; ++i) runs += sched.step();
  ASSERT_TRUE(sched.run_until(clock.now_ns() + kNsPerS).ok());
  TaskTelemetry t[Scheduler::kMaxTasks];
  sched.snapshot(t, Scheduler::kMaxTasks);
  EXPECT_EQ(scope.allocations(), 0u);
  EXPECT_GE(runs, 10'000);
}

TEST(Scheduler, GivenSeparateExecutionClockWhenTaskWorksThenDurationComesFromIt) {
  // GIVEN a replay timeline and a separate clock on which the task's work is measured
  constexpr TaskSpec table[] = {{"vo", 10, 1'000'000, 0}};
  SimClock timeline(0);
  SimClock exec(0);
  Scheduler sched(table, 1, timeline);
  sched.set_execution_clock(exec);
  Worker w;
  w.clock = &exec;
  w.work_ns = 2'000'000;  // 2 ms of work against a 1 ms budget, invisible to the timeline
  sched.bind(0, &Worker::run, &w);
  // WHEN it runs for one simulated second
  sched.start(0);
  ASSERT_TRUE(sched.run_until(kNsPerS).ok());
  // THEN every run is an overrun of exactly 2 ms, and none is late on the timeline
  const TaskTelemetry t = telemetry_of(sched, 0);
  EXPECT_EQ(t.runs, 10u);
  EXPECT_EQ(t.overruns, 10u);
  EXPECT_EQ(t.max_exec_ns, 2'000'000);
  EXPECT_EQ(t.slips, 0u);
  EXPECT_EQ(t.max_slip_ns, 0);
  EXPECT_EQ(timeline.now_ns(), 900'000'000);
}

TEST(Scheduler, GivenTaskRequestingStopWhenRunningThenRunUntilReturnsAndTheRequestIsConsumed) {
  constexpr TaskSpec table[] = {{"t", 100, 1'000'000, 0}};
  SimClock clock(0);
  Scheduler sched(table, 1, clock);
  struct Stopper {
    Scheduler* s;
    int runs = 0;
    int stop_at;
    static void run(void* ctx, int64_t) {
      auto* st = static_cast<Stopper*>(ctx);
      if (++st->runs == st->stop_at) st->s->request_stop();
    }
  } stopper{&sched, 0, 25};
  sched.bind(0, &Stopper::run, &stopper);
  sched.start(0);
  ASSERT_TRUE(sched.run_until(INT64_MAX).ok());
  EXPECT_EQ(stopper.runs, 25);
  // The request was consumed: the next run continues until its end time.
  ASSERT_TRUE(sched.run_until(sched.release_ns(0, 35)).ok());
  EXPECT_EQ(stopper.runs, 35);
}

TEST(Scheduler, GivenBadTablesWhenCheckedThenStatusNamesTheProblemAndNothingRuns) {
  SimClock clock(0);
  {
    Scheduler sched(kTasks, kNumTasks, clock);
    Worker w;
    sched.bind(0, &Worker::run, &w);
    const Status st = sched.status();
    EXPECT_EQ(st.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(st.message().find("'camera'"), std::string::npos) << st.message();
    EXPECT_NE(st.message().find("bind"), std::string::npos) << st.message();
    EXPECT_FALSE(sched.run_until(kNsPerS).ok());
    EXPECT_EQ(w.runs, 0u);
  }
  {
    constexpr TaskSpec bad_rate[] = {{"gnss", 0, 1000, 0}};
    Scheduler sched(bad_rate, 1, clock);
    EXPECT_NE(sched.status().message().find("rate_hz"), std::string::npos);
  }
  {
    constexpr TaskSpec bad_budget[] = {{"gnss", 5, 0, 0}};
    Scheduler sched(bad_budget, 1, clock);
    EXPECT_NE(sched.status().message().find("budget_ns"), std::string::npos);
  }
  {
    TaskSpec many[Scheduler::kMaxTasks + 1];
    for (auto& t : many) t = {"t", 1, 1, 0};
    Scheduler sched(many, Scheduler::kMaxTasks + 1, clock);
    EXPECT_EQ(sched.num_tasks(), Scheduler::kMaxTasks);
    EXPECT_NE(sched.status().message().find("more than 32"), std::string::npos);
  }
  {
    Scheduler sched(kTasks, kNumTasks, clock);
    EXPECT_EQ(sched.step(), 0);  // nothing bound: returns instead of sleeping forever
  }
}

TEST(SchedulerTelemetry, GivenSnapshotWhenFormattedThenOneLinePerTaskAndTruncationIsReported) {
  SimClock clock(0);
  Scheduler sched(kTasks, kNumTasks, clock);
  Worker w[kNumTasks];
  for (size_t i = 0; i < kNumTasks; ++i) {
    w[i].clock = &clock;
    sched.bind(i, &Worker::run, &w[i]);
  }
  w[3].work_ns = 12 * kNsPerMs;
  sched.start(0);
  ASSERT_TRUE(sched.run_until(2 * kNsPerS).ok());

  char buf[2048];
  const size_t n = sched.format_telemetry(buf, sizeof(buf));
  ASSERT_LT(n, sizeof(buf));
  EXPECT_EQ(std::strlen(buf), n);
  int lines = 0;
  for (const char* p = buf; *p; ++p) lines += *p == '\n';
  EXPECT_EQ(lines, 1 + static_cast<int>(kNumTasks));
  for (const TaskSpec& t : kTasks) EXPECT_NE(std::strstr(buf, t.name), nullptr);
  EXPECT_NE(std::strstr(buf, "400"), nullptr);  // imu runs in 2 s

  char small[40];
  const size_t needed = sched.format_telemetry(small, sizeof(small));
  EXPECT_EQ(needed, n);
  EXPECT_EQ(std::strlen(small), sizeof(small) - 1);
  EXPECT_EQ(std::strncmp(small, buf, sizeof(small) - 1), 0);
}

TEST(SchedulerRealTime,
     GivenMonotonicClockWhenRunForAboutFiftyMillisecondsThenTasksRanAndTelemetryIsReadable) {
  // Smoke test only: counts > 0, no timing assertion.
  constexpr TaskSpec table[] = {{"fast", 1000, 1'000'000, 0}, {"slow", 100, 5'000'000, 1}};
  MonotonicClock clock;
  Scheduler sched(table, 2, clock);
  struct Count {
    std::atomic<uint64_t> n{0};
    static void run(void* ctx, int64_t) {
      static_cast<Count*>(ctx)->n.fetch_add(1, std::memory_order_relaxed);
    }
  } fast, slow;
  sched.bind(0, &Count::run, &fast);
  sched.bind(1, &Count::run, &slow);
  std::atomic<bool> done{false};
  uint64_t seen_runs = 0;
  std::thread reader([&] {
    TaskTelemetry t[2];
    while (!done.load(std::memory_order_acquire)) {
      sched.snapshot(t, 2);
      // A consistent snapshot: the mean cannot exceed the max.
      if (t[0].runs > 0 && t[0].total_exec_ns > static_cast<int64_t>(t[0].runs) * t[0].max_exec_ns)
        seen_runs = ~0ull;
      std::this_thread::yield();
    }
  });
  const int64_t start = clock.now_ns();
  sched.start(start);
  const Status st = sched.run_until(start + 50 * kNsPerMs);
  done.store(true, std::memory_order_release);
  reader.join();
  ASSERT_TRUE(st.ok());
  EXPECT_GT(fast.n.load(), 0u);
  EXPECT_GT(slow.n.load(), 0u);
  EXPECT_NE(seen_runs, ~0ull);
  TaskTelemetry t[2];
  ASSERT_EQ(sched.snapshot(t, 2), 2u);
  EXPECT_EQ(t[0].runs, fast.n.load());
  EXPECT_EQ(t[1].runs, slow.n.load());
  EXPECT_EQ(t[0].runs + t[0].skipped_releases, 50u);  // releases 0..49 ms, each run or skipped
}

}  // namespace
}  // namespace hwr::core
