#pragma once
// hwr-bench subcommands. Each bench file registers one command; `hwr-bench NAME [args]` runs it
// alone, `hwr-bench` lists them. A command prints its human-readable table, then one
// machine-readable `key=value` line per figure.

#include <vector>

namespace hwr::bench {

struct BenchCommand {
  const char* name;
  const char* help;
  int (*run)(int argc, char** argv);  // argv[0] is the command name
};

std::vector<BenchCommand>& bench_commands();

struct BenchRegistrar {
  explicit BenchRegistrar(BenchCommand c) { bench_commands().push_back(c); }
};

}  // namespace hwr::bench

#define HWR_BENCH_COMMAND(ident, name, help, fn) \
  static const ::hwr::bench::BenchRegistrar hwr_bench_registrar_##ident({name, help, fn})
