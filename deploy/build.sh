#!/usr/bin/env bash
# Configures and builds Reenact into ./build (Release with debug info).
# REENACT_WERROR=ON turns warnings into errors (CI does this).
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DREENACT_WERROR="${REENACT_WERROR:-OFF}" >/dev/null
ninja -C build -j"$(nproc)"
