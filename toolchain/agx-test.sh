#!/usr/bin/env bash
# The Jetson AGX cross build and its unit tests under qemu (issue #8): installs the aarch64 cross
# compiler, qemu-user and the arm64 sysroot (install-deps.sh --agx), builds every library, app and
# test of the `agx` preset for aarch64, and runs the tests through qemu-aarch64
# (CMAKE_CROSSCOMPILING_EMULATOR in toolchain/aarch64-jetson.cmake). Ends with one line per test
# target: how many of its tests ran under qemu and passed.
# Usage: toolchain/agx-test.sh            the CI set (below)
#        toolchain/agx-test.sh --all      every test (hours: see docs/hardware.md)
#        toolchain/agx-test.sh ARGS...    ctest arguments of your own
# The CI set is every test but those listed in toolchain/agx-qemu-slow.txt: tests that take minutes
# emulated (whole sim runs, the pipeline on a sequence, relocalization against a prior map: Embree and
# the pipeline run ~50-400x slower under qemu) and one mapio test whose 5 s link cut leaves a backlog
# the emulated Draco encoder cannot clear in time. They all run on the host in the README's test
# command.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

toolchain/install-deps.sh --agx
cmake --preset agx
cmake --build --preset agx
# The left-out names as one anchored regex ('.' taken literally; comments and blanks dropped).
slow_names=$(sed -e 's/#.*//' -e 's/[[:space:]]*$//' toolchain/agx-qemu-slow.txt | grep -v '^$' || true)
if [[ -z "$slow_names" ]]; then
  echo "agx-test: toolchain/agx-qemu-slow.txt names no test" >&2
  exit 2
fi
slow_regex="^($(sed 's/[.]/[.]/g' <<<"$slow_names" | paste -sd '|'))\$"
ci_set=(-E "$slow_regex")
if [[ $# -eq 0 ]]; then
  set -- "${ci_set[@]}"
elif [[ "$1" == "--all" ]]; then
  shift
fi
status=0
ctest --preset agx "$@" || status=$?

# Per test target (each suite's ctest label is its module): tests, and how many passed.
ctest --preset agx --show-only=json-v1 "$@" > build/agx/agx-tests.json
# ctest leaves an earlier run's failure list in place when every test passes: read it only after a
# failure (and keep it, for --rerun-failed).
python3 - build/agx/agx-tests.json build/agx/Testing/Temporary/LastTestsFailed.log "$status" <<'PY'
import collections, json, os, sys
tests = json.load(open(sys.argv[1]))["tests"]
failed = set()
if sys.argv[3] != "0" and os.path.exists(sys.argv[2]):
    failed = {line.strip().split(":", 1)[1] for line in open(sys.argv[2]) if ":" in line}
runs, passed = collections.Counter(), collections.Counter()
for t in tests:
    labels = [p["value"] for p in t.get("properties", []) if p["name"] == "LABELS"]
    target = "hwr_%s_tests" % labels[0][0] if labels and labels[0] else "other"
    runs[target] += 1
    passed[target] += t["name"] not in failed
for t in sorted(runs):
    print(f"agx-test: {t}: {passed[t]}/{runs[t]} passed under qemu-aarch64")
print(f"agx_tests_run={sum(runs.values())} agx_tests_passed={sum(passed.values())}")
PY
exit $status
