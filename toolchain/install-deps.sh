#!/usr/bin/env bash
# Installs every Debian 12 package hwr-perception needs, skipping those already present.
# Usage: toolchain/install-deps.sh [--with-bench-peers]
#   --with-bench-peers also installs packages only the peer benchmarks use.
# Idempotent: a second run installs nothing and exits 0.
set -euo pipefail

packages=(
  # build
  build-essential cmake ninja-build ccache pkg-config git clang-format
  # core
  libeigen3-dev libyaml-cpp-dev
  # hal
  libopencv-dev libembree-dev libusb-1.0-0-dev
  # estimation / recon
  libflann-dev liblz4-dev
  # mapio
  libdraco-dev liblcm-dev liblcm-bin
  # tests and benches
  libgtest-dev libgmock-dev libbenchmark-dev
)
bench_peers=()
if [[ "${1:-}" == "--with-bench-peers" ]]; then
  bench_peers=(libopencv-contrib-dev)
fi

missing=()
for p in "${packages[@]}" "${bench_peers[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]} == 0)); then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${#missing[@]} missing package(s): ${missing[*]}"
SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
echo "install-deps: done"
