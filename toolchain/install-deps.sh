#!/usr/bin/env bash
# Installs every Debian 12 package hwr-perception needs, skipping those already present.
# Usage: toolchain/install-deps.sh [--with-bench-peers] [--with-web] [--with-browser] [--agx]
#   --with-bench-peers  also installs packages only the peer benchmarks use (and pcl-tools, the
#                       independent PLY/PCD reader of the ground-station interop test).
#   --with-web          also installs Node.js and npm when `node` is missing (toolchain/build-web.sh
#                       builds hwr-ground's viewer page from npm packages with them).
#   --with-browser      also installs Debian's Chromium (the viewer's end-to-end browser test drives it
#                       headless through playwright-core; no browser is ever downloaded).
#   --agx               also installs the aarch64 cross compiler and qemu-user, and builds the
#                       arm64 sysroot for `cmake --preset agx` (toolchain/make-agx-sysroot.sh;
#                       Debian's amd64 and arm64 -dev packages of OpenCV, yaml-cpp, FLANN and LCM
#                       cannot be installed side by side, so they are unpacked into a folder).
# Idempotent: a second run installs nothing and exits 0.
set -euo pipefail

packages=(
  # build
  build-essential cmake ninja-build ccache pkg-config git clang-format
  # core
  libeigen3-dev libyaml-cpp-dev
  # hal
  libopencv-dev libembree-dev libusb-1.0-0-dev
  # estimation / recon (zlib: the map store's CRC32)
  libflann-dev liblz4-dev zlib1g-dev
  # mapio (draco: draco_decoder/draco_encoder, the interop check of chunk payloads)
  libdraco-dev liblcm-dev liblcm-bin draco
  # hwr-ground's viewer: the HTTP server and JSON
  libcpp-httplib-dev nlohmann-json3-dev
  # link tests: private network namespaces (unshare, ip), packet loss (nft), shaping (tc)
  util-linux iproute2 nftables
  # fuzz targets (libFuzzer ships with Debian's clang)
  clang
  # tests and benches (python3-onnx, python3-numpy: the tiny ONNX detector models the detect tests build)
  libgtest-dev libgmock-dev libbenchmark-dev python3-onnx python3-numpy
)
bench_peers=()
web=()
browser=()
agx=()
agx_packages=(g++-aarch64-linux-gnu qemu-user binutils-aarch64-linux-gnu)
for arg in "$@"; do
  case "$arg" in
    --with-bench-peers) bench_peers=(libopencv-contrib-dev libceres-dev libpcl-dev pcl-tools) ;;
    # A machine with its own Node.js (e.g. from NodeSource) keeps it: Debian's nodejs would conflict.
    --with-web) if ! command -v node >/dev/null || ! command -v npm >/dev/null; then web=(nodejs npm); fi ;;
    --with-browser) browser=(chromium) ;;
    --agx) agx=("${agx_packages[@]}") ;;
    *) echo "install-deps: unknown option '$arg' (use --with-bench-peers, --with-web, --with-browser, --agx)" >&2; exit 2 ;;
  esac
done

SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi

missing=()
for p in "${packages[@]}" "${bench_peers[@]}" "${web[@]}" "${browser[@]}" "${agx[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]} == 0)); then
  echo "install-deps: all $((${#packages[@]} + ${#bench_peers[@]} + ${#web[@]} + ${#browser[@]} + ${#agx[@]})) packages present"
else
  echo "install-deps: installing ${#missing[@]} missing package(s): ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
  echo "install-deps: done"
fi
if ((${#agx[@]})); then
  "$(dirname "${BASH_SOURCE[0]}")/make-agx-sysroot.sh"
fi
