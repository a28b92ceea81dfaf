#!/usr/bin/env bash
# Builds the tests with sanitizers and runs them (CI runs `all`):
#
#   deploy/sanitize.sh [asan|tsan|all] [--full] [ctest args...]
#
#   asan    AddressSanitizer + UndefinedBehaviorSanitizer (LeakSanitizer
#           included) in ./build-asan: the library unit tests
#   tsan    ThreadSanitizer in ./build-tsan: the threaded server and capture
#           daemon tests (job scheduler, take store and recorder, RPC
#           services, live follower, daemon)
#   all     both (the default)
#   --full  every test that makes sense under the sanitizer: all unit tests
#           and the end-to-end tests of tests/ (much longer; see README.md)
#
# Only the test binaries of the chosen set are built (plus the programs
# they start); further arguments go to ctest (e.g. -R TakeStore, -V).
# Undefined behaviour, a leak or a data race fails the test. Builds go
# through ccache when it is installed, like deploy/build.sh. Both builds use
# -O1 -g1: line tables are all a sanitizer report needs for file:line
# stacks, and full debug info makes the instrumented compile a third slower.
# Installs nothing: run deploy/setup-debian.sh first.
set -euo pipefail
cd "$(dirname "$0")/.."

usage() {
  sed -n '2,/^set -euo/p' "$0" | sed -e '$d' -e 's/^# \{0,1\}//' >&2
  exit 2
}

which=all
full=0
ctest_args=()
if (($#)); then
  case "$1" in
    asan|tsan|all) which="$1"; shift ;;
    -h|--help) usage ;;
  esac
fi
for arg in "$@"; do
  case "$arg" in
    --full) full=1 ;;
    -h|--help) usage ;;
    *) ctest_args+=("$arg") ;;
  esac
done

# The test binaries (ninja targets) of each set. CI's sets are the core
# libraries and the server's store, RPC, job and HTTP tests (ASan + UBSan), and
# the server's store and job tests (TSan): two more builds of the core of
# the tree, which a cold 2-core machine adds within CI's time. --full adds
# the rest: the live hub, the reenactment store and the capture daemon,
# the renderers and the end-to-end tests (README.md, "Sanitizers and
# fuzzing").
asan_tests=(
  base_test geometry_test body_test io_test rpc_security_test ingest_client_test server_store_test
  server_rpc_test server_jobs_test server_http_test)
asan_full_tests=(
  "${asan_tests[@]}"
  io_reenactment_test server_live_test server_reenactments_test capture_test
  methods_test methods_registry_test bodyfit_test carving_test mirror_test png_test video_writer_test render_types_test
  tracking_test server_main_test worker_main_test capture_sensors_test cli_jobs_test
  viewer_test
  # tests/: the real programs over loopback, and our files read by other
  # implementations.
  take_interop_test reenactment_interop_test reenactments_client_test
  reenactment_source_test trust_e2e_test)
# --full only: the tests that render through EGL (in process or in the
# programs they start). They run without LeakSanitizer: Mesa's driver leaks
# a few allocations of its own and is unloaded at eglTerminate, so its
# frames can no longer be told apart (or suppressed) when the leak check
# runs at exit. Memory errors and undefined behaviour are still caught.
asan_render_tests=(
  render_test board_test board_video_test synth_test recon_test cylinders_test body_method_test
  rigid_carved_test capture_pipeline_test capture_processing_test cli_test cli_view_test
  mirror_app_test view_test
  capture_ingest_test reenactment_e2e_test live_follow_e2e_test body_fidelity_test
  viewer_ar_test)
# TSan sees only the synchronisation of instrumented code. Debian's gRPC,
# protobuf and Abseil are not instrumented, so every hand-over inside gRPC
# (completion queues, reactors, message buffers) looks like a race: the
# tests that run gRPC in process are left out below, and TSan checks the
# threaded pieces that the other tests reach without gRPC.
tsan_tests=(
  base_test ingest_client_test server_store_test server_jobs_test)
tsan_full_tests=(
  "${tsan_tests[@]}"
  server_live_test server_reenactments_test capture_test capture_pipeline_test
  capture_processing_test capture_sensors_test body_method_test tracking_test)

# Tests left out (ctest name regexes), each with why.
asan_exclude=(
  # The fake worker raises SIGSEGV on purpose and the test wants the job to
  # fail with "killed by signal 11"; ASan catches the signal in the
  # (instrumented) worker, reports it and exits with status 1 instead.
  '^JobsService\.WorkerErrorsFailTheJobNotTheServer$'
)
tsan_exclude=(
  # gRPC in process (servers, clients, the daemon's uplink and control
  # service): uninstrumented libgrpc hands objects between threads through
  # synchronisation TSan cannot see, and each of these tests draws hundreds
  # of false reports.
  '^(Tls|CaptureControlAuth|TakeUplink|Daemon|DaemonAnchor|ReenactdFlags|StreamFramesTest|Ingest|RpcAuth|Takes|JobsService|DiskFull|FollowStreamTest|Reenactments|Work|SlurmWorkers)\.'
  # Asserts real-time pacing (p90 within 50 ms), which TSan's slowdown breaks.
  '^PlaybackSensor\.RealTimePacingFollowsHostStamps$'
)

# What the sanitizers do on a finding. Halting makes the test fail with the
# report in its output; the stack is printed for undefined behaviour too.
# Options already in the environment come last and so win (e.g.
# TSAN_OPTIONS=halt_on_error=0 to see every report of a run).
export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:check_initialization_order=1:strict_init_order=1:detect_stack_use_after_return=1${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:report_error_type=1${UBSAN_OPTIONS:+:$UBSAN_OPTIONS}"
export LSAN_OPTIONS="suppressions=$PWD/build-asan/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:history_size=4:suppressions=$PWD/deploy/tsan.supp${TSAN_OPTIONS:+:$TSAN_OPTIONS}"

# The sanitizer runtimes of GCC 12 need the address space layout they know:
# kernels that randomise mmap with more than 28 bits (newer than Debian 12's)
# make ThreadSanitizer stop with "unexpected memory mapping". Tests then run
# without address space randomisation.
run_prefix=()
if [ -r /proc/sys/vm/mmap_rnd_bits ] && (($(cat /proc/sys/vm/mmap_rnd_bits) > 28)); then
  run_prefix=(setarch "$(uname -m)" -R)
fi

# ccache, when installed, keeps rebuilds of unchanged sources cheap.
launcher=()
if command -v ccache >/dev/null 2>&1; then
  # Paths relative to the checkout, so that another clone hits the cache.
  export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi

# Runs the tests of the given binaries in build folder $1 that no exclusion
# names. ctest selects by test name only, so the tests are picked by number
# from ctest's own listing with the caller's arguments applied (ctest
# numbers the tests it lists after its own filters, and -I counts the same
# way).
run_tests() {
  local dir="$1" excludes="$2"
  shift 2
  local -A wanted=()
  local t
  for t in "$@"; do wanted[$t]=1; done
  local numbers=() n="" line name binary
  while IFS= read -r line; do
    if [[ "$line" =~ ^([0-9]+):\ Test\ command:\ ([^ ]+) ]]; then
      n="${BASH_REMATCH[1]}"
      binary="${BASH_REMATCH[2]##*/}"
    elif [[ -n "$n" && "$line" =~ ^\ +Test\ +#${n}:\ (.+)$ ]]; then
      name="${BASH_REMATCH[1]}"
      if [[ -n "${wanted[$binary]:-}" ]] && ! [[ -n "$excludes" && "$name" =~ $excludes ]]; then
        numbers+=("$n")
      fi
      n=""
    fi
  done < <("${run_prefix[@]}" ctest --test-dir "$dir" -N -V "${ctest_args[@]}")
  if ((${#numbers[@]} == 0)); then
    echo "sanitize.sh: no tests selected in $dir" >&2
    return 1
  fi
  local list
  list="$(IFS=,; echo "${numbers[*]}")"
  "${run_prefix[@]}" ctest --test-dir "$dir" --output-on-failure -j"$(nproc)" \
    -I "0,0,0,$list" "${ctest_args[@]}"
}

# Configures and builds build folder $1 with sanitizers $2 and the extra
# compiler flags $3; the rest: the test binaries (ninja targets).
# (Called in an if, where set -e does not apply: failures return.)
build() {
  local dir="$1" sanitizers="$2" extra_flags="$3"
  shift 3
  local flags="-O1 -g1 -DNDEBUG" start=$SECONDS
  echo "sanitize.sh: $dir (-fsanitize=$sanitizers): building $# test binaries" >&2
  cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "${launcher[@]}" \
    -DCMAKE_C_FLAGS_RELWITHDEBINFO="$flags" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="$flags" \
    -DCMAKE_C_FLAGS="$extra_flags" -DCMAKE_CXX_FLAGS="$extra_flags" \
    -DREENACT_SANITIZE="$sanitizers" -DREENACT_BUILD_BENCHMARKS=OFF \
    -DREENACT_WERROR=OFF >/dev/null || return 1
  # Test discovery runs the freshly built binaries, with the options above.
  "${run_prefix[@]}" ninja -C "$dir" -j"$(nproc)" "$@" || return 1
  echo "sanitize.sh: $dir: built in $((SECONDS - start)) s" >&2
}

# Joins regexes into one.
exclusion_regex() {
  local out="" entry
  for entry in "$@"; do
    out+="${out:+|}(${entry})"
  done
  echo "$out"
}

# Leaks that third-party libraries leave at exit, never our own (a leak of
# ours is fixed): written next to the build, where LSAN_OPTIONS points.
write_lsan_suppressions() {
  mkdir -p build-asan
  cat >build-asan/lsan.supp <<'EOF'
# c-ares, gRPC's DNS resolver, keeps an allocation of its own (10 bytes)
# that nothing frees before exit.
leak:libcares.so
# OpenNI2's device drivers (loaded by the OpenNI2 backend even when no
# device is found) leave small allocations of theirs behind.
leak:/OpenNI2/Drivers/
# OpenSSL's per-thread error state (904 bytes, allocated in libcrypto for
# each thread that enters it) stays behind when one of gRPC's TLS threads
# is still running or exits as the process ends. Its stack stops inside
# libcrypto, which has no frame pointers; our own use of OpenSSL (a
# SHA-256 digest in common/rpc/auth.cc) holds no OpenSSL object.
leak:CRYPTO_zalloc
EOF
}

status=0
if [[ "$which" == asan || "$which" == all ]]; then
  tests=("${asan_tests[@]}")
  render_tests=()
  if ((full)); then
    tests=("${asan_full_tests[@]}")
    render_tests=("${asan_render_tests[@]}")
  fi
  write_lsan_suppressions
  # Undefined behaviour stops the program, rather than printing and going
  # on. Eigen leaves out its "malloc is aligned already" shortcut under ASan
  # and frees through its own aligned allocator; Debian's Ceres (not
  # instrumented) allocates its matrices without it, and our code frees
  # some of them: both sides must agree, as they do outside ASan.
  if build build-asan address,undefined \
      "-fno-sanitize-recover=undefined -DEIGEN_MALLOC_ALREADY_ALIGNED=1" \
      "${tests[@]}" "${render_tests[@]}"; then
    start=$SECONDS
    excludes="$(exclusion_regex "${asan_exclude[@]}")"
    run_tests build-asan "$excludes" "${tests[@]}" || status=1
    if ((${#render_tests[@]})); then
      ASAN_OPTIONS="$ASAN_OPTIONS:detect_leaks=0" \
        run_tests build-asan "$excludes" "${render_tests[@]}" || status=1
    fi
    echo "sanitize.sh: build-asan: tests ran in $((SECONDS - start)) s" >&2
  else
    status=1
  fi
fi
if [[ "$which" == tsan || "$which" == all ]]; then
  tests=("${tsan_tests[@]}")
  if ((full)); then tests=("${tsan_full_tests[@]}"); fi
  if build build-tsan thread "" "${tests[@]}"; then
    start=$SECONDS
    run_tests build-tsan "$(exclusion_regex "${tsan_exclude[@]}")" "${tests[@]}" || status=1
    echo "sanitize.sh: build-tsan: tests ran in $((SECONDS - start)) s" >&2
  else
    status=1
  fi
fi
exit "$status"
