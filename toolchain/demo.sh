#!/usr/bin/env bash
# Installs what is missing, builds, and runs the pipeline as far as it exists:
#   simulator (hwr-sim) → robot process (hwr-robot: HAL replay → fixed-rate scheduler)
# Outputs go to out/demo/ (override with HWR_DEMO_OUT=DIR). Pass --duration S to shorten the
# simulated run (default: the whole ~50 m lab walk).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
out=$(realpath -m "${HWR_DEMO_OUT:-out/demo}")
duration=()
if [[ "${1:-}" == "--duration" && -n "${2:-}" ]]; then duration=(--duration "$2"); fi

toolchain/install-deps.sh
cmake --preset host-release
cmake --build --preset host-release
bin=build/host-release/apps

echo
echo "== 1/2 simulator: the lab welding workshop with exact ground truth =="
rm -rf "$out/sim-lab"
"$bin/hwr-sim/hwr-sim" --scenario lab --out "$out/sim-lab" --threads 2 "${duration[@]}"

echo
echo "== 2/2 robot: HAL replay of the run through the fixed-rate scheduler =="
"$bin/hwr-robot/hwr-robot" --source "sim:$out/sim-lab" --quiet | tee "$out/robot-telemetry.txt"


cat <<MSG

demo outputs:
  $out/sim-lab/                 simulated run (TUM layout: rgb/, depth/, rgb.txt, depth.txt,
                                groundtruth.txt; imu.csv, mag.csv, calibration.yaml,
                                weld_groundtruth.yaml, scenario_resolved.yaml)
  $out/robot-telemetry.txt      scheduler and sensor-stream telemetry of the replay

pose estimation is the next stage (docs/architecture.md); once it writes a trajectory,
  build/host-release/apps/hwr-eval/hwr-eval ate $out/sim-lab/groundtruth.txt TRAJECTORY
scores it against the simulator's ground truth.
MSG
