#!/usr/bin/env bash
# Sets everything up on Debian 12 and runs the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/setup-debian.sh
bash deploy/build.sh
ctest --test-dir build --output-on-failure -j"$(nproc)" "$@"
