#!/usr/bin/env bash
# Configures and builds Reenact into ./build (Release with debug info).
# REENACT_WERROR=ON turns warnings into errors (CI does this).
set -euo pipefail
cd "$(dirname "$0")/.."
# ccache, when installed, keeps rebuilds of unchanged sources cheap.
launcher=()
if command -v ccache >/dev/null 2>&1; then
  # Paths relative to the checkout, so that another clone hits the cache.
  export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "${launcher[@]}" \
  -DREENACT_WERROR="${REENACT_WERROR:-OFF}" >/dev/null
ninja -C build -j"$(nproc)"
