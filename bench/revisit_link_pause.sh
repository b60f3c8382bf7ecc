#!/usr/bin/env bash
# A revisit's link under a stalled ground station: hwr-ground is paused (SIGSTOP) for a while near the
# end of a second visit, when the map update's changed prior segments go out behind the map's last
# batches, and the robot's exit code and link line are reported per pause offset. A run that refuses
# a batch (a hole in the ground station's map) exits 1.
#
#   bench/revisit_link_pause.sh [--build DIR] [--robot BIN] [--at "7 8 9"] [--pause S] [--work DIR]
#
# --build: the build tree (build/host-release); --robot: the hwr-robot to test (default: the build's,
# e.g. another commit's to compare); --at: seconds after the robot starts at which the ground station
# is paused (default "7 8 9 10 11 12"); --pause: for how long (8 s); --work: scratch folder (the prior
# map is made there once, by a 32 s lab run). Ends with key=value lines.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
build=build/host-release
robot=""
offsets="7 8 9 10 11 12"
pause_s=8
work="${TMPDIR:-/tmp}/hwr_revisit_link_pause"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --build) build="$2"; shift 2 ;;
    --robot) robot="$2"; shift 2 ;;
    --at) offsets="$2"; shift 2 ;;
    --pause) pause_s="$2"; shift 2 ;;
    --work) work="$2"; shift 2 ;;
    *) echo "revisit_link_pause.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
robot="${robot:-$build/apps/hwr-robot/hwr-robot}"
ground="$build/apps/hwr-ground/hwr-ground"
for bin in "$robot" "$ground"; do
  [[ -x "$bin" ]] || { echo "revisit_link_pause.sh: $bin is not built" >&2; exit 2; }
done
# A port of its own, so that a test suite running beside it is not disturbed.
url='udpm://239.255.76.67:7671?ttl=0&recv_buf_size=8388608'
mkdir -p "$work"
if [[ ! -f "$work/map1/detections.yaml" ]]; then
  echo "prior map: a 32 s lab run -> $work/map1"
  rm -rf "$work/map1"
  "$robot" --source sim:lab --duration 32 --quiet --regions geometry --map-out "$work/map1" \
    > "$work/map1.txt" 2>&1 || { echo "the prior map's run failed: $work/map1.txt" >&2; exit 1; }
fi

runs=0
failed=0
for at in $offsets; do
  rm -rf "$work/map2" "$work/ground"
  "$ground" --out "$work/ground" --link "$url" --status-interval 0 > "$work/ground.txt" 2>&1 &
  ground_pid=$!
  sleep 1
  ( sleep "$at"; kill -STOP "$ground_pid"; sleep "$pause_s"; kill -CONT "$ground_pid" ) &
  pauser=$!
  rc=0
  "$robot" --source sim:lab --duration 12 --quiet --regions geometry --link "$url" --robot-id welder \
    --link-wait 20 --prior-map "$work/map1" --map-out "$work/map2" > "$work/robot_at_$at.txt" 2>&1 || rc=$?
  wait "$pauser" 2>/dev/null || true
  kill -CONT "$ground_pid" 2>/dev/null || true
  kill -INT "$ground_pid" 2>/dev/null || true
  wait "$ground_pid" 2>/dev/null || true
  runs=$((runs + 1))
  [[ $rc -eq 0 ]] || failed=$((failed + 1))
  link=$(grep -E '^link: ' "$work/robot_at_$at.txt" | sed -E 's/.*(refused batches [0-9]+).*(all acknowledged|NOT all acknowledged).*/\1, \2/' || true)
  echo "paused at ${at} s for ${pause_s} s: rc ${rc}; ${link:-no link line} ($work/robot_at_$at.txt)"
done
echo "revisit_link_pause_runs=$runs"
echo "revisit_link_pause_failed=$failed"
