#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (tests/fuzz/, -DHWR_BUILD_FUZZ=ON) and runs each for a
# short, fixed number of executions (ctest -L fuzz): the CI smoke run. Long runs: tests/fuzz/README.md.
# Usage: toolchain/fuzz-smoke.sh [RUNS]   (executions per target, default 20000)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
runs="${1:-20000}"
CC=clang CXX=clang++ cmake -S . -B build/fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DHWR_BUILD_FUZZ=ON -DHWR_WITH_SIM=OFF -DHWR_BUILD_BENCH=OFF -DHWR_FUZZ_SMOKE_RUNS="$runs" >/dev/null
cmake --build build/fuzz -j2 --target hwr_fuzz_all
ctest --test-dir build/fuzz -L fuzz --output-on-failure
