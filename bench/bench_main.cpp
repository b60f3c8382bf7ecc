#include <algorithm>
#include <cstdio>
#include <cstring>

#include <benchmark/benchmark.h>

#include "bench_command.hpp"

namespace hwr::bench {

std::vector<BenchCommand>& bench_commands() {
  static std::vector<BenchCommand> commands;
  return commands;
}

namespace {
// `hwr-bench micro [--benchmark_filter=...]`: every Google Benchmark micro-benchmark.
int run_micro(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 2;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
}  // namespace

HWR_BENCH_COMMAND(micro, "micro", "Google Benchmark micro-benchmarks (accepts --benchmark_* flags)",
                  run_micro);

}  // namespace hwr::bench

int main(int argc, char** argv) {
  auto& commands = hwr::bench::bench_commands();
  std::sort(commands.begin(), commands.end(),
            [](const auto& a, const auto& b) { return std::strcmp(a.name, b.name) < 0; });
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0) {
    std::printf("usage: hwr-bench COMMAND [args]\ncommands:\n");
    for (const auto& c : commands) std::printf("  %-14s %s\n", c.name, c.help);
    return argc < 2 ? 2 : 0;
  }
  for (const auto& c : commands) {
    if (std::strcmp(argv[1], c.name) == 0) return c.run(argc - 1, argv + 1);
  }
  std::fprintf(stderr, "hwr-bench: unknown command '%s' (run without arguments for the list)\n", argv[1]);
  return 2;
}
