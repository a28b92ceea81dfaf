#!/bin/bash
# `cmake --install` into a scratch prefix, then reenact-server started with
# the ExecStart line of the shipped systemd unit (its paths moved under the
# prefix): it must come up and answer `reenact takes list`, and find the
# installed tracker network and worker beside it.
#   tests/install_test.sh BUILD_DIR
set -euo pipefail
build=$(cd "$1" && pwd)
scratch=$(mktemp -d)
server_pid=
cleanup() {
  if [ -n "$server_pid" ]; then kill "$server_pid" 2>/dev/null || true; wait "$server_pid" 2>/dev/null || true; fi
  rm -rf "$scratch"
}
trap cleanup EXIT
prefix=$scratch/prefix
cmake --install "$build" --prefix "$prefix" > "$scratch/install.log"
for f in bin/reenact-server bin/reenact-worker bin/reenact share/reenact/models/tracker/pose_net.onnx \
         lib/systemd/system/reenact-server.service; do
  [ -e "$prefix/$f" ] || { echo "FAIL: cmake --install did not install $f" >&2; exit 1; }
done
unit=$prefix/lib/systemd/system/reenact-server.service
exec_start=$(sed -n 's/^ExecStart=//p' "$unit")
[ -n "$exec_start" ] || { echo "FAIL: no ExecStart in $unit" >&2; exit 1; }
# The unit's paths, moved under the prefix; a free port instead of 50051.
command=${exec_start//\/usr\/local/$prefix}
command=${command//\/var\/lib\/reenact/$scratch/data}
command=${command//127.0.0.1:50051/127.0.0.1:0}
echo "running: $command --port-file $scratch/port"
# shellcheck disable=SC2086
$command --port-file "$scratch/port" > "$scratch/server.log" 2>&1 &
server_pid=$!
for _ in $(seq 1 100); do
  [ -s "$scratch/port" ] && break
  kill -0 "$server_pid" 2>/dev/null || { cat "$scratch/server.log" >&2; echo "FAIL: the unit's command exited" >&2; exit 1; }
  sleep 0.1
done
address=$(head -n1 "$scratch/port")
[ -n "$address" ] || { cat "$scratch/server.log" >&2; echo "FAIL: no port" >&2; exit 1; }
"$prefix/bin/reenact" takes list --server "$address" > "$scratch/list.txt"
grep -q "no takes" "$scratch/list.txt" || { cat "$scratch/list.txt" >&2; echo "FAIL: takes list" >&2; exit 1; }
grep -q "ExecReload=/bin/kill -HUP" "$unit" || { echo "FAIL: no ExecReload" >&2; exit 1; }
kill -HUP "$server_pid"
sleep 0.5
kill -0 "$server_pid" || { echo "FAIL: SIGHUP stopped the server" >&2; exit 1; }
kill -TERM "$server_pid"
wait "$server_pid"
server_pid=
echo "PASS: installed under $prefix; the unit's command serves on $address"
