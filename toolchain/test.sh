#!/usr/bin/env bash
# Installs what is missing (bench peers included: the benches compile against them; Node.js and
# Chromium for the viewer's page and its browser test), builds the page and the host-release preset
# and runs the whole test suite.
# Real datasets are read from ../shared/data (see its README); tests that need one fail with a
# message naming the missing folder.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

toolchain/install-deps.sh --with-bench-peers --with-web --with-browser
toolchain/build-web.sh  # the viewer page: its browser test loads it
cmake --preset host-release
cmake --build --preset host-release
ctest --preset host-release "$@"
