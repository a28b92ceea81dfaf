#!/usr/bin/env bash
# Sets everything up on Debian 12 and runs the demo on the built-in teacher:
# synthesises a 2-sensor take of a procedural body doing a front kick and
# draws its contact sheet. Outputs go to ./out/demo.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/setup-debian.sh
bash deploy/build.sh
out=out/demo
mkdir -p "$out"
reenact=build/bin/reenact
"$reenact" synth --motion builtin:front-kick --body procedural --sensors 2 --seconds 3 \
  --out "$out/take.mcap"
"$reenact" take info "$out/take.mcap"
"$reenact" take sheet "$out/take.mcap" --out "$out/sheet.png"
echo
echo "demo: take          $PWD/$out/take.mcap"
echo "demo: contact sheet $PWD/$out/sheet.png"
