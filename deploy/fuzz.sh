#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ into ./build-fuzz (clang, ASan and
# UBSan, REENACT_FUZZ=ON), writes their seed corpora with the project's own
# writers and the shared test data, runs every target (or those named) for
# N seconds and prints one line per target: executions, executions per
# second, corpus size and the outcome.
#
#   deploy/fuzz.sh [--seconds N] [--jobs J] [TARGET...]
#
#   --seconds N  time per target (default 60)
#   --jobs J     targets run at the same time (default 1)
#
# Corpora grow in build-fuzz/corpus/<target> (kept between runs); a crash,
# leak, timeout (10 s per input) or out-of-memory (2048 MB) input goes to
# build-fuzz/findings/<target>/ and makes the script exit with status 1.
# Logs: build-fuzz/logs/<target>.log. Reproduce a finding with
#   build-fuzz/fuzz/<target> build-fuzz/findings/<target>/<file>
# REENACT_TEST_DATA_DIR overrides where the shared test data is looked for
# (../shared/data beside the checkout).
# Installs nothing: it stops, saying what is missing, without clang.
set -euo pipefail
cd "$(dirname "$0")/.."

all_targets=(fuzz_mcap_summary fuzz_mcap_recovery fuzz_depth_codec fuzz_mask_rle
             fuzz_frame_set_validation fuzz_bvh fuzz_asf_amc fuzz_makehuman_obj
             fuzz_makehuman_json fuzz_reenactment_file fuzz_board_spec fuzz_intrinsics_file
             fuzz_web_request)

usage() {
  sed -n '2,/^set -euo/p' "$0" | sed -e '$d' -e 's/^# \{0,1\}//' >&2
  echo "targets: ${all_targets[*]}" >&2
  exit 2
}

seconds=60
jobs=1
targets=()
while (($#)); do
  case "$1" in
    --seconds) seconds="${2:-}"; shift 2 || usage ;;
    --seconds=*) seconds="${1#*=}"; shift ;;
    --jobs) jobs="${2:-}"; shift 2 || usage ;;
    --jobs=*) jobs="${1#*=}"; shift ;;
    -h|--help) usage ;;
    -*) echo "fuzz.sh: unknown option $1" >&2; usage ;;
    *) targets+=("$1"); shift ;;
  esac
done
[[ "$seconds" =~ ^[1-9][0-9]*$ ]] || { echo "fuzz.sh: --seconds needs a positive integer" >&2; exit 2; }
[[ "$jobs" =~ ^[1-9][0-9]*$ ]] || { echo "fuzz.sh: --jobs needs a positive integer" >&2; exit 2; }
((${#targets[@]})) || targets=("${all_targets[@]}")
for t in "${targets[@]}"; do
  [[ " ${all_targets[*]} " == *" $t "* ]] || { echo "fuzz.sh: unknown target $t" >&2; usage; }
done

# What the build needs beyond deploy/setup-debian.sh: clang with its
# libFuzzer and sanitizer runtimes.
missing=()
for tool in clang clang++ cmake ninja; do
  command -v "$tool" >/dev/null 2>&1 || missing+=("$tool")
done
if ((${#missing[@]})); then
  echo "fuzz.sh: missing ${missing[*]}; on Debian 12: sudo apt-get install clang cmake ninja-build" >&2
  exit 1
fi
probe_dir="$(mktemp -d)"
trap 'rm -rf "$probe_dir"' EXIT
printf '#include <cstddef>\n#include <cstdint>\nextern "C" int LLVMFuzzerTestOneInput(const uint8_t*, size_t) { return 0; }\n' \
  >"$probe_dir/probe.cc"
if ! clang++ -fsanitize=fuzzer,address,undefined "$probe_dir/probe.cc" -o "$probe_dir/probe" \
    >"$probe_dir/log" 2>&1; then
  echo "fuzz.sh: clang++ cannot link a libFuzzer target (-fsanitize=fuzzer,address,undefined):" >&2
  sed 's/^/  /' "$probe_dir/log" >&2
  echo "fuzz.sh: on Debian 12 the runtimes come with clang (package libclang-rt-14-dev)" >&2
  exit 1
fi

# ccache, when installed, keeps rebuilds of unchanged sources cheap.
launcher=()
if command -v ccache >/dev/null 2>&1; then
  # Paths relative to the checkout, so that another clone hits the cache.
  export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi
out=build-fuzz
cmake -S . -B "$out" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "${launcher[@]}" \
  -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DREENACT_FUZZ=ON \
  -DREENACT_BUILD_TESTS=OFF -DREENACT_BUILD_BENCHMARKS=OFF >/dev/null
mkdir -p "$out/logs"
if ! ninja -C "$out" -j"$(nproc)" "${targets[@]}" make_seeds >"$out/logs/build.log" 2>&1; then
  tail -n 40 "$out/logs/build.log" >&2
  echo "fuzz.sh: build failed (log: $out/logs/build.log)" >&2
  exit 1
fi

data_dir="${REENACT_TEST_DATA_DIR:-$PWD/../shared/data}"
rm -rf "$out/seeds"
"$out/fuzz/make_seeds" "$out/seeds" "$data_dir"

run_target() {
  local t="$1"
  mkdir -p "$out/corpus/$t" "$out/findings/$t" "$out/seeds/$t"
  # New inputs go to the first folder (the corpus); the seeds are only read.
  "$out/fuzz/$t" -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 \
    -print_final_stats=1 -artifact_prefix="$out/findings/$t/" \
    "$out/corpus/$t" "$out/seeds/$t" >"$out/logs/$t.log" 2>&1
}

declare -A status
pids=()
names=()
running=0
for t in "${targets[@]}"; do
  echo "fuzzing $t for ${seconds} s" >&2
  run_target "$t" &
  pids[$running]=$!
  names[$running]="$t"
  running=$((running + 1))
  if ((running == jobs)); then
    for i in "${!pids[@]}"; do
      rc=0; wait "${pids[$i]}" || rc=$?
      status[${names[$i]}]=$rc
    done
    pids=(); names=(); running=0
  fi
done
for i in "${!pids[@]}"; do
  rc=0; wait "${pids[$i]}" || rc=$?
  status[${names[$i]}]=$rc
done

failed=0
printf '%-26s %12s %9s %8s  %s\n' target executions exec/s corpus result
for t in "${targets[@]}"; do
  log="$out/logs/$t.log"
  execs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)"
  rate="$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -n 1)"
  corpus="$(find "$out/corpus/$t" -type f | wc -l)"
  result=ok
  if ((status[$t] != 0)); then
    failed=1
    kind="$(grep -m1 -oE 'ERROR: (AddressSanitizer|UndefinedBehaviorSanitizer|LeakSanitizer|libFuzzer): [^ ]+( [^ ]+)?|runtime error: .*|fuzz invariant broken: .*' "$log" || true)"
    unit="$(sed -n 's/.*Test unit written to //p' "$log" | tail -n 1)"
    result="FOUND (exit ${status[$t]}) ${kind:-see $log}${unit:+; input: $unit}"
  fi
  printf '%-26s %12s %9s %8s  %s\n' "$t" "${execs:-?}" "${rate:-?}" "$corpus" "$result"
done
if ((failed)); then
  echo "fuzz.sh: findings above (logs in $out/logs)" >&2
  exit 1
fi
