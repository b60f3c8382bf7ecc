// hwr-robot: the robot process. Today it runs the HAL into the fixed-rate scheduler: a source
// (dataset replay or a simulator run) is polled by the "hal" task into bounded rings, and the
// pipeline tasks drain them through stream-health monitors, where pose estimation plugs in next
// (docs/architecture.md). Replay runs on a simulated clock: deterministic, faster than real time;
// --realtime paces it at sensor rate on the monotonic clock.
#include <unistd.h>

#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>

#include "hwr/core/log.hpp"
#include "hwr/core/scheduler.hpp"
#include "hwr/core/time.hpp"
#include "hwr/hal/replay_source.hpp"
#include "hwr/hal/stream_health.hpp"
#if HWR_WITH_SIM
#include "hwr/sim/sim_run_replay.hpp"
#endif

namespace {

using hwr::core::kNsPerS;

// Scheduler task table: rate, time budget, priority (0 = highest).
constexpr hwr::core::TaskSpec kTasks[] = {
    {"hal", 200.0, 1'000'000, 0},      // poll the source into the rings
    {"inertial", 200.0, 500'000, 1},   // IMU, magnetometer, GNSS rings
    {"camera", 30.0, 25'000'000, 2},   // frames
    {"telemetry", 1.0, 1'000'000, 9},  // status line
};
enum TaskIndex : size_t { kHal = 0, kInertial, kCamera, kTelemetry };

struct Args {
  std::string source;
  double duration_s = 0;  // 0: the whole source
  bool realtime = false;
  bool quiet = false;
};

void usage() {
  std::fprintf(
      stderr,
      "usage: hwr-robot --source KIND:PATH [--duration S] [--realtime] [--quiet]\n"
      "  KIND: sim (a folder written by hwr-sim), tum (TUM RGB-D folder), euroc (EuRoC folder or mav0)\n");
}

// Replay paced at sensor rate: the timeline is the source's time, advancing with CLOCK_MONOTONIC.
class PacedClock final : public hwr::core::Clock {
 public:
  explicit PacedClock(int64_t source_t0_ns) : t0_(source_t0_ns), mono0_(mono_.now_ns()) {}
  int64_t now_ns() const override { return t0_ + (mono_.now_ns() - mono0_); }
  void sleep_until_ns(int64_t t_ns) override { mono_.sleep_until_ns(mono0_ + (t_ns - t0_)); }

 private:
  hwr::core::MonotonicClock mono_;
  int64_t t0_, mono0_;
};

struct Robot {
  hwr::hal::SensorStreams* streams = nullptr;
  hwr::hal::SensorSource* source = nullptr;
  hwr::core::Scheduler* scheduler = nullptr;
  hwr::hal::StreamMonitor imu{200.0};
  hwr::hal::StreamMonitor camera{30.0};
  uint64_t mag = 0, gnss = 0, gnss_3d = 0;
  hwr::core::Status error;
  bool quiet = false;
};

void hal_task(void* ctx, int64_t now_ns) {
  auto* r = static_cast<Robot*>(ctx);
  if (!r->error.ok()) return;
  r->error = r->source->poll(now_ns, r->streams);
  if (!r->error.ok() || r->source->finished()) r->scheduler->request_stop();
}

void inertial_task(void* ctx, int64_t) {
  auto* r = static_cast<Robot*>(ctx);
  hwr::hal::ImuSample s;
  while (r->streams->imu.try_pop(s)) r->imu.check(s);
  hwr::hal::MagSample m;
  while (r->streams->mag.try_pop(m)) ++r->mag;
  hwr::hal::GnssFix g;
  while (r->streams->gnss.try_pop(g)) {
    ++r->gnss;
    if (g.has_3d_fix()) ++r->gnss_3d;
  }
}

void camera_task(void* ctx, int64_t) {
  auto* r = static_cast<Robot*>(ctx);
  hwr::hal::RgbdFrame* f = nullptr;
  while (r->streams->frames.try_pop(f)) {
    r->camera.check(*f);
    r->streams->frame_pool.release(f);
  }
}

void telemetry_task(void* ctx, int64_t now_ns) {
  auto* r = static_cast<Robot*>(ctx);
  if (r->quiet) return;
  const hwr::hal::SourceCounters c = r->source->counters();
  hwr::core::TaskTelemetry t[4];
  r->scheduler->snapshot(t, 4);
  uint64_t overruns = 0;
  for (const auto& x : t) overruns += x.overruns;
  std::fprintf(stderr,
               "\rhwr-robot t=%8.2fs frames=%" PRIu64 " imu=%" PRIu64 " mag=%" PRIu64 " gnss=%" PRIu64
               " dropped=%" PRIu64 " overruns=%" PRIu64 "   ",
               hwr::core::ns_to_s(now_ns - r->scheduler->start_ns()), c.frames, c.imu, c.mag, c.gnss,
               c.frames_dropped + r->streams->imu.dropped(), overruns);
  if (!isatty(STDERR_FILENO)) std::fputc('\n', stderr);
}

hwr::core::Expected<hwr::hal::ReplayLog> open_log(const std::string& spec) {
  if (spec.rfind("sim:", 0) == 0) {
#if HWR_WITH_SIM
    auto run = hwr::sim::open_sim_run_log(spec.substr(4));
    if (!run.ok()) return run.status();
    return std::move(run->log);
#else
    return hwr::core::Unavailable("this build has no simulator support (HWR_WITH_SIM=OFF)");
#endif
  }
  return hwr::hal::open_dataset_log(spec);
}

int run(const Args& args) {
  auto log = open_log(args.source);
  if (!log.ok()) {
    std::fprintf(stderr, "hwr-robot: %s\n", log.status().message().c_str());
    return 1;
  }
  const hwr::hal::SourceInfo info = log->info;
  hwr::hal::SensorStreamsConfig cfg;
  if (info.intrinsics.valid()) {
    cfg.width = info.intrinsics.width;
    cfg.height = info.intrinsics.height;
  }
  cfg.stereo = info.stereo;
  hwr::hal::SensorStreams streams(cfg);
  auto source = hwr::hal::ReplaySource::create(std::move(log.value()), &streams);
  if (!source.ok()) {
    std::fprintf(stderr, "hwr-robot: %s\n", source.status().message().c_str());
    return 1;
  }

  const int64_t t0 = info.first_t_ns;
  hwr::core::SimClock sim_clock(t0);
  PacedClock paced_clock(t0);
  hwr::core::MonotonicClock exec_clock;
  hwr::core::Clock& timeline = args.realtime ? static_cast<hwr::core::Clock&>(paced_clock) : sim_clock;

  hwr::core::Scheduler sched(kTasks, sizeof(kTasks) / sizeof(kTasks[0]), timeline);
  sched.set_execution_clock(exec_clock);  // budgets are checked against real work
  Robot robot;
  robot.streams = &streams;
  robot.source = source->get();
  robot.scheduler = &sched;
  robot.quiet = args.quiet;
  robot.imu = hwr::hal::StreamMonitor(info.imu_rate_hz > 0 ? info.imu_rate_hz : 200.0);
  robot.camera = hwr::hal::StreamMonitor(info.camera_rate_hz > 0 ? info.camera_rate_hz : 30.0);
  sched.bind(kHal, hal_task, &robot);
  sched.bind(kInertial, inertial_task, &robot);
  sched.bind(kCamera, camera_task, &robot);
  sched.bind(kTelemetry, telemetry_task, &robot);
  sched.start(t0);

  std::fprintf(stderr, "hwr-robot: source %s: %.1f s, %s%s%s%s\n", info.name.c_str(),
               hwr::core::ns_to_s(info.last_t_ns - info.first_t_ns), "camera", info.has_imu ? " + imu" : "",
               info.has_mag ? " + magnetometer" : "", info.has_gnss ? " + gnss" : "");
  const int64_t end = args.duration_s > 0 ? t0 + hwr::core::s_to_ns(args.duration_s)
                                          : info.last_t_ns + hwr::core::kNsPerS / 10;
  const int64_t wall0 = exec_clock.now_ns();
  hwr::core::Status st = sched.run_until(end);
  // Hand the last samples to the pipeline tasks.
  inertial_task(&robot, end);
  camera_task(&robot, end);
  const double wall_s = hwr::core::ns_to_s(exec_clock.now_ns() - wall0);
  if (!st.ok()) robot.error = st;
  if (!args.quiet) std::fputc('\n', stderr);

  char table[4096];
  sched.format_telemetry(table, sizeof(table));
  const hwr::hal::SourceCounters c = source.value()->counters();
  const auto& ih = robot.imu.health();
  const auto& ch = robot.camera.health();
  std::printf("scheduler telemetry (simulated %.2f s in %.2f s wall):\n%s",
              hwr::core::ns_to_s(sched.next_release_ns(0) - t0), wall_s, table);
  std::printf("camera: frames=%" PRIu64 " dropped=%" PRIu64 " unreadable=%" PRIu64 " gaps=%" PRIu64
              " low_depth=%" PRIu64 " max_interval_ms=%.1f\n",
              ch.samples, c.frames_dropped, c.frame_errors, ch.gaps, robot.camera.frames_low_depth(),
              ch.max_interval_ns * 1e-6);
  std::printf("imu: samples=%" PRIu64 " dropped=%" PRIu64 " gaps=%" PRIu64 " non_finite=%" PRIu64
              " non_increasing=%" PRIu64 "\n",
              ih.samples, streams.imu.dropped(), ih.gaps, ih.non_finite, ih.non_increasing_t);
  if (c.decode_waits > 0) {
    std::printf("replay: the hal task waited %" PRIu64
                " times, %.2f s in all, for frames to be decoded (replay is "
                "I/O-bound; these waits are the hal task's overruns)\n",
                c.decode_waits, hwr::core::ns_to_s(c.decode_wait_ns));
  }
  std::printf("magnetometer: samples=%" PRIu64 "  gnss: fixes=%" PRIu64 " with_3d_fix=%" PRIu64 "\n",
              robot.mag, robot.gnss, robot.gnss_3d);
  std::printf("pose estimation: not in this build yet (docs/architecture.md)\n");
  if (!robot.error.ok()) {
    std::fprintf(stderr, "hwr-robot: %s\n", robot.error.to_string().c_str());
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* name) -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "hwr-robot: %s needs a value\n", name);
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--source") {
      args.source = value("--source");
    } else if (a == "--duration") {
      char* end = nullptr;
      const char* v = value("--duration");
      args.duration_s = std::strtod(v, &end);
      if (*end != '\0' || !(args.duration_s > 0 && args.duration_s <= 1e6)) {
        std::fprintf(stderr, "hwr-robot: --duration: expected seconds in (0, 1e6], got '%s'\n", v);
        return 2;
      }
    } else if (a == "--realtime") {
      args.realtime = true;
    } else if (a == "--quiet") {
      args.quiet = true;
    } else if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else {
      std::fprintf(stderr, "hwr-robot: unknown option '%s'\n", a.c_str());
      usage();
      return 2;
    }
  }
  if (args.source.empty()) {
    usage();
    return 2;
  }
  return run(args);
}
