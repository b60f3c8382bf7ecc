#!/usr/bin/env bash
# Builds an aarch64 sysroot of Debian 12 arm64 -dev packages for `cmake --preset agx`, without
# touching the host's installed packages: Debian's amd64 and arm64 OpenCV/yaml-cpp/FLANN/LCM -dev
# packages are not co-installable, so apt only *downloads* the arm64 packages with their
# dependencies and they are unpacked into the sysroot folder.
# Usage: toolchain/make-agx-sysroot.sh [SYSROOT]   (default: build/agx-sysroot)
# A binary meant for the device itself should instead be built against a JetPack sysroot (older
# glibc); pass it to cmake with -DHWR_SYSROOT=/path.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
sysroot=$(realpath -m "${1:-build/agx-sysroot}")

packages=(
  libc6-dev libstdc++-12-dev
  libeigen3-dev libyaml-cpp-dev
  libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev libopencv-calib3d-dev
  libopencv-features2d-dev libopencv-flann-dev libopencv-dnn-dev
  libusb-1.0-0-dev libflann-dev libdraco-dev liblcm-dev libembree-dev libcpp-httplib-dev nlohmann-json3-dev
  libgtest-dev libgmock-dev libbenchmark-dev
)

SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
if ! dpkg --print-foreign-architectures | grep -qx arm64; then
  $SUDO dpkg --add-architecture arm64
  $SUDO apt-get update -q
fi

# dpkg-deb -x runs no maintainer scripts, so the update-alternatives links that libblas3 and
# liblapack3 register (libblas.so.3, liblapack.so.3 in the multiarch folder; OpenCV core needs them)
# are made here. Idempotent.
link_alternatives() {
  local lib_dir="$sysroot/usr/lib/aarch64-linux-gnu" alt
  for alt in "$lib_dir"/blas/libblas.so.3 "$lib_dir"/lapack/liblapack.so.3; do
    [[ -e "$alt" ]] || continue
    [[ -e "$lib_dir/$(basename "$alt")" ]] || ln -sfn "${alt#"$lib_dir"/}" "$lib_dir/$(basename "$alt")"
  done
}

stamp="$sysroot/.hwr-sysroot-packages"
if [[ -f "$stamp" && "$(cat "$stamp")" == "${packages[*]}" ]]; then
  link_alternatives
  echo "make-agx-sysroot: $sysroot is up to date"
  exit 0
fi

debs=$(mktemp -d)
chmod 755 "$debs"
trap 'rm -rf "$debs"' EXIT
mkdir -p "$debs/partial"
# apt resolves the arm64 closure against an empty package status (as if nothing were installed,
# so every dependency is fetched) and --download-only never installs or removes anything.
: > "$debs/status"
$SUDO apt-get install -y -q --download-only --no-install-recommends \
  -o Dir::State::status="$debs/status" -o APT::Architecture=arm64 -o APT::Architectures::=arm64 \
  -o Dir::Cache::archives="$debs" -o Debug::NoLocking=1 "${packages[@]}" > "$debs/apt.log" 2>&1 \
  || { cat "$debs/apt.log"; exit 1; }

mkdir -p "$sysroot"
count=0
for deb in "$debs"/*_arm64.deb "$debs"/*_all.deb; do
  [[ -e "$deb" ]] || continue
  dpkg-deb -x "$deb" "$sysroot"
  count=$((count + 1))
done
# Absolute symlinks inside the sysroot (e.g. lib*.so -> /lib/...) must point into it.
find "$sysroot" -type l -lname '/*' | while read -r link; do
  target=$(readlink "$link")
  ln -sfn "$sysroot$target" "$link"
done
link_alternatives
echo "${packages[*]}" > "$stamp"
echo "make-agx-sysroot: unpacked $count packages into $sysroot"
