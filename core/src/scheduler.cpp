#include "hwr/core/scheduler.hpp"

#include <algorithm>
#include <cassert>
#include <cinttypes>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <string>

namespace hwr::core {
namespace {

// snprintf at *pos, keeping *pos as the length the whole text needs.
void appendf(char* buf, size_t buf_len, size_t* pos, const char* fmt, ...)
    __attribute__((format(printf, 4, 5)));
void appendf(char* buf, size_t buf_len, size_t* pos, const char* fmt, ...) {
  va_list args;
  va_start(args, fmt);
  char* dst = *pos < buf_len ? buf + *pos : nullptr;
  const size_t room = *pos < buf_len ? buf_len - *pos : 0;
  const int n = std::vsnprintf(dst, room, fmt, args);
  va_end(args);
  if (n > 0) *pos += static_cast<size_t>(n);
}

constexpr double kMaxRateHz = 1e9;  // one release per nanosecond

}  // namespace

size_t format_telemetry(const TaskTelemetry* tasks, size_t n, char* buf, size_t buf_len) {
  if (buf_len > 0) buf[0] = '\0';
  size_t pos = 0;
  appendf(buf, buf_len, &pos, "%-12s %4s %9s %12s %10s %10s %10s %12s %12s %12s\n", "task", "prio", "rate_hz",
          "runs", "overruns", "slips", "skipped", "max_exec_us", "mean_exec_us", "max_slip_us");
  for (size_t i = 0; i < n; ++i) {
    const TaskTelemetry& t = tasks[i];
    const double mean_us =
        t.runs > 0 ? static_cast<double>(t.total_exec_ns) / static_cast<double>(t.runs) * 1e-3 : 0.0;
    appendf(buf, buf_len, &pos,
            "%-12s %4d %9.2f %12" PRIu64 " %10" PRIu64 " %10" PRIu64 " %10" PRIu64 " %12.1f %12.1f %12.1f\n",
            t.name ? t.name : "?", t.priority, t.rate_hz, t.runs, t.overruns, t.slips, t.skipped_releases,
            static_cast<double>(t.max_exec_ns) * 1e-3, mean_us, static_cast<double>(t.max_slip_ns) * 1e-3);
  }
  return pos;
}

Scheduler::Scheduler(const TaskSpec* table, size_t n, Clock& timeline_clock, const SchedulerOptions& options)
    : timeline_(&timeline_clock), exec_clock_(&timeline_clock), options_(options) {
  table_too_long_ = n > kMaxTasks;
  n_ = std::min(n, kMaxTasks);
  for (size_t i = 0; i < n_; ++i) {
    Task& t = tasks_[i];
    t.spec = table[i];
    t.stats.name = t.spec.name;
    t.stats.rate_hz = t.spec.rate_hz;
    t.stats.budget_ns = t.spec.budget_ns;
    t.stats.priority = t.spec.priority;
    const double period_ns = t.spec.rate_hz > 0.0 ? 1e9 / t.spec.rate_hz : 0.0;
    t.slip_tolerance_ns = static_cast<int64_t>(std::llround(options_.slip_tolerance * period_ns));
    order_[i] = static_cast<uint8_t>(i);
  }
  // Insertion sort by (priority, table index): stable, no allocation, n <= 32.
  for (size_t i = 1; i < n_; ++i) {
    const uint8_t v = order_[i];
    size_t j = i;
    while (j > 0 && tasks_[order_[j - 1]].spec.priority > tasks_[v].spec.priority) {
      order_[j] = order_[j - 1];
      --j;
    }
    order_[j] = v;
  }
}

Status Scheduler::status() const {
  if (table_too_long_) {
    return InvalidArgument("scheduler: task table has more than " + std::to_string(kMaxTasks) + " tasks");
  }
  // Messages are built only on failure: run_until() calls this, and the OK path must not allocate.
  auto fail = [](size_t i, const TaskSpec& s, const std::string& problem) {
    return InvalidArgument("scheduler: task " + std::to_string(i) + " '" + (s.name ? s.name : "") +
                           "': " + problem);
  };
  for (size_t i = 0; i < n_; ++i) {
    const TaskSpec& s = tasks_[i].spec;
    if (s.name == nullptr || s.name[0] == '\0') return fail(i, s, "needs a name");
    if (!(s.rate_hz > 0.0 && s.rate_hz <= kMaxRateHz)) {
      return fail(i, s, "rate_hz must be in (0, 1e9], got " + std::to_string(s.rate_hz));
    }
    if (s.budget_ns <= 0) return fail(i, s, "budget_ns must be > 0, got " + std::to_string(s.budget_ns));
    if (s.priority < 0) return fail(i, s, "priority must be >= 0, got " + std::to_string(s.priority));
    if (tasks_[i].fn == nullptr) return fail(i, s, "no function bound (call bind())");
  }
  return Status::Ok();
}

void Scheduler::bind(size_t index, TaskFn fn, void* ctx) {
  assert(index < n_);
  tasks_[index].fn = fn;
  tasks_[index].ctx = ctx;
}

void Scheduler::start(int64_t start_ns) {
  start_ns_ = start_ns;
  started_ = true;
  for (size_t i = 0; i < n_; ++i) {
    tasks_[i].k = 0;
    tasks_[i].next_release_ns = start_ns;
  }
}

int64_t Scheduler::release_ns(size_t i, uint64_t k) const {
  // From k directly (no running sum), so rounding never accumulates.
  return start_ns_ +
         static_cast<int64_t>(std::llround(static_cast<double>(k) * 1e9 / tasks_[i].spec.rate_hz));
}

uint64_t Scheduler::last_release_at_or_before(size_t i, int64_t t_ns) const {
  const Task& task = tasks_[i];
  const double estimate = static_cast<double>(t_ns - start_ns_) * task.spec.rate_hz * 1e-9;
  uint64_t m = estimate > static_cast<double>(task.k) ? static_cast<uint64_t>(estimate) : task.k;
  // The estimate is off by at most one either way from rounding.
  while (m > task.k && release_ns(i, m) > t_ns) --m;
  while (release_ns(i, m + 1) <= t_ns) ++m;
  return m;
}

int64_t Scheduler::earliest_release() const {
  int64_t earliest = INT64_MAX;
  for (size_t i = 0; i < n_; ++i) {
    if (tasks_[i].fn != nullptr) earliest = std::min(earliest, tasks_[i].next_release_ns);
  }
  return earliest;
}

int Scheduler::step() { return cycle(INT64_MAX); }

Status Scheduler::run_until(int64_t end_ns) {
  HWR_RETURN_IF_ERROR(status());
  if (!started_) start(timeline_->now_ns());
  for (;;) {
    if (stop_.load(std::memory_order_acquire)) {
      stop_.store(false, std::memory_order_relaxed);
      break;
    }
    if (earliest_release() >= end_ns) break;
    cycle(end_ns);
  }
  return Status::Ok();
}

int Scheduler::cycle(int64_t limit_ns) {
  if (!started_) start(timeline_->now_ns());
  const int64_t earliest = earliest_release();
  if (earliest >= limit_ns) return 0;
  timeline_->sleep_until_ns(earliest);
  const int64_t now = timeline_->now_ns();

  int ran = 0;
  for (size_t j = 0; j < n_; ++j) {
    const size_t i = order_[j];
    Task& task = tasks_[i];
    if (task.fn == nullptr || task.next_release_ns > now || task.next_release_ns >= limit_ns) continue;

    const int64_t start = timeline_->now_ns();
    // Catch-up rule: within max_catchup periods run the oldest missed release; beyond, jump to
    // the latest one (before the limit) and count the rest as skipped instead of bursting.
    const int64_t horizon = std::min(start, limit_ns - 1);
    const uint64_t latest = last_release_at_or_before(i, horizon);
    if (latest - task.k > options_.max_catchup) {
      task.stats.skipped_releases += latest - task.k;
      task.k = latest;
    }
    const int64_t release = release_ns(i, task.k);

    const int64_t exec_start = exec_clock_->now_ns();
    task.fn(task.ctx, start);
    const int64_t exec_ns = exec_clock_->now_ns() - exec_start;
    const int64_t slip_ns = start - release;

    TaskTelemetry& s = task.stats;
    ++s.runs;
    if (exec_ns > task.spec.budget_ns) ++s.overruns;
    if (slip_ns > task.slip_tolerance_ns) ++s.slips;
    s.max_exec_ns = std::max(s.max_exec_ns, exec_ns);
    s.total_exec_ns += exec_ns;
    s.max_slip_ns = std::max(s.max_slip_ns, slip_ns);

    ++task.k;
    task.next_release_ns = release_ns(i, task.k);
    publish(i);
    ++ran;
  }
  return ran;
}

void Scheduler::publish(size_t i) {
  // Seqlock writer: odd sequence while the fields change. The fields are release-stored, so a
  // reader that sees any new field value also sees the odd sequence (no fences needed, which keeps
  // it understood by ThreadSanitizer too).
  SharedCounters& c = shared_[i];
  const TaskTelemetry& s = tasks_[i].stats;
  const uint32_t seq = c.seq.load(std::memory_order_relaxed);
  c.seq.store(seq + 1, std::memory_order_relaxed);
  constexpr auto kRel = std::memory_order_release;
  c.runs.store(s.runs, kRel);
  c.overruns.store(s.overruns, kRel);
  c.slips.store(s.slips, kRel);
  c.skipped.store(s.skipped_releases, kRel);
  c.max_exec_ns.store(s.max_exec_ns, kRel);
  c.total_exec_ns.store(s.total_exec_ns, kRel);
  c.max_slip_ns.store(s.max_slip_ns, kRel);
  c.seq.store(seq + 2, std::memory_order_release);
}

size_t Scheduler::snapshot(TaskTelemetry* out, size_t n) const {
  const size_t count = std::min(n, n_);
  for (size_t i = 0; i < count; ++i) {
    const SharedCounters& c = shared_[i];
    TaskTelemetry t;
    const TaskSpec& spec = tasks_[i].spec;
    t.name = spec.name;
    t.rate_hz = spec.rate_hz;
    t.budget_ns = spec.budget_ns;
    t.priority = spec.priority;
    for (;;) {
      const uint32_t before = c.seq.load(std::memory_order_acquire);
      if (before & 1u) continue;  // writer mid-update; it finishes within a few stores
      constexpr auto kAcq = std::memory_order_acquire;
      t.runs = c.runs.load(kAcq);
      t.overruns = c.overruns.load(kAcq);
      t.slips = c.slips.load(kAcq);
      t.skipped_releases = c.skipped.load(kAcq);
      t.max_exec_ns = c.max_exec_ns.load(kAcq);
      t.total_exec_ns = c.total_exec_ns.load(kAcq);
      t.max_slip_ns = c.max_slip_ns.load(kAcq);
      if (c.seq.load(std::memory_order_relaxed) == before) break;
    }
    out[i] = t;
  }
  return count;
}

size_t Scheduler::format_telemetry(char* buf, size_t buf_len) const {
  TaskTelemetry t[kMaxTasks];
  const size_t n = snapshot(t, kMaxTasks);
  return hwr::core::format_telemetry(t, n, buf, buf_len);
}

}  // namespace hwr::core
