// Micro-benchmarks of the core building blocks (run with `hwr-bench micro`). Timings are for
// comparison between builds and machines only; no test depends on them.

#include <benchmark/benchmark.h>

#include <array>
#include <cstdint>
#include <random>
#include <vector>

#include "hwr/core/arena.hpp"
#include "hwr/core/object_pool.hpp"
#include "hwr/core/scheduler.hpp"
#include "hwr/core/so3.hpp"
#include "hwr/core/spsc_ring.hpp"

namespace hwr::core {
namespace {

void BM_SpscRingPushPop(benchmark::State& state) {
  SpscRing<uint64_t> ring(1024);
  uint64_t i = 0, out = 0;
  for (auto _ : state) {
    ring.try_push(i++);
    ring.try_pop(out);
    benchmark::DoNotOptimize(out);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SpscRingPushPop);

void BM_SpscRingPushDropOldestFull(benchmark::State& state) {
  SpscRing<uint64_t> ring(64);
  for (uint64_t i = 0; i < 64; ++i) ring.try_push(i);
  uint64_t i = 0;
  for (auto _ : state) ring.push_drop_oldest(i++);  // every push drops the oldest
  benchmark::DoNotOptimize(ring.dropped());
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SpscRingPushDropOldestFull);

void BM_ObjectPoolAcquireRelease(benchmark::State& state) {
  ObjectPool<std::array<double, 64>> pool(32);
  for (auto _ : state) {
    auto* p = pool.acquire();
    benchmark::DoNotOptimize(p);
    pool.release(p);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_ObjectPoolAcquireRelease);

void BM_ArenaAllocate(benchmark::State& state) {
  Arena arena(1 << 20);
  for (auto _ : state) {
    float* p = arena.allocate<float>(64);
    if (p == nullptr) {
      arena.reset();
      p = arena.allocate<float>(64);
    }
    benchmark::DoNotOptimize(p);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_ArenaAllocate);

std::vector<Eigen::Vector3d> random_rotation_vectors(size_t n, double max_angle) {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> a(0.0, max_angle);
  std::vector<Eigen::Vector3d> out(n);
  for (auto& w : out) w = a(rng) * Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
  return out;
}

void BM_So3Exp(benchmark::State& state) {
  const auto ws = random_rotation_vectors(256, 3.14);
  size_t i = 0;
  for (auto _ : state) {
    Eigen::Matrix3d R = so3_exp(ws[i++ & 255]);
    benchmark::DoNotOptimize(R.data());
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_So3Exp);

// state.range(0) = 0: generic angles, 1: within 0.1 rad of pi (the symmetric-part branch).
void BM_So3Log(benchmark::State& state) {
  const auto ws = random_rotation_vectors(256, 3.14);
  std::vector<Eigen::Matrix3d> Rs;
  for (const auto& w : ws) {
    const Eigen::Vector3d v = state.range(0) == 0 ? w : (3.1415 - 0.1 * w.norm() / 3.14) * w.normalized();
    Rs.push_back(so3_exp(v));
  }
  size_t i = 0;
  for (auto _ : state) {
    Eigen::Vector3d w = so3_log(Rs[i++ & 255]);
    benchmark::DoNotOptimize(w.data());
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_So3Log)->Arg(0)->Arg(1);

void BM_So3RightJacobianInverse(benchmark::State& state) {
  const auto ws = random_rotation_vectors(256, 3.14);
  size_t i = 0;
  for (auto _ : state) {
    Eigen::Matrix3d J = so3_right_jacobian_inverse(ws[i++ & 255]);
    benchmark::DoNotOptimize(J.data());
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_So3RightJacobianInverse);

void noop_task(void* ctx, int64_t now_ns) { *static_cast<int64_t*>(ctx) += now_ns & 1; }

// One scheduler cycle of the 200/30/10/1 Hz table on a SimClock (no sleeping, no task work):
// the scheduler's own overhead per cycle.
void BM_SchedulerStep(benchmark::State& state) {
  static constexpr TaskSpec kTasks[] = {{"imu", 200, 500'000, 0},
                                        {"camera", 30, 20'000'000, 1},
                                        {"keyframe", 10, 50'000'000, 2},
                                        {"map", 1, 10'000'000, 3}};
  SimClock clock(0);
  Scheduler sched(kTasks, 4, clock);
  int64_t sink = 0;
  for (size_t i = 0; i < 4; ++i) sched.bind(i, &noop_task, &sink);
  sched.start(0);
  int64_t runs = 0;
  for (auto _ : state) runs += sched.step();
  benchmark::DoNotOptimize(sink);
  state.counters["task_runs_per_cycle"] = static_cast<double>(runs) / static_cast<double>(state.iterations());
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SchedulerStep);

}  // namespace
}  // namespace hwr::core
