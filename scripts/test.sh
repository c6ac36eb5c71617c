#!/usr/bin/env bash
# Runs every fleetgw test on a fresh Debian 12 machine (as root, or with sudo), in timed phases:
#   deps      the Debian packages the two compilers need; the rest (brokers, gpsd, the VM,
#             lintian, chromium, the arm64 cross packages) is installed in the background during
#             the build;
#   build     the test tree build-san/: clang with AddressSanitizer + UndefinedBehaviorSanitizer
#             and libFuzzer coverage instrumentation, warnings as errors, unity batches: every
#             test executable, the fuzz targets and the binaries the tests run. The whole suite
#             runs once, sanitized (one tree, not a plain tree and a sanitizer tree: that halves
#             the compile, which is most of the run). Alongside it, at the lowest CPU priority,
#             the product tree build/ (gcc, Release, warnings as errors, unity batches: the
#             binaries as shipped, the test executables only when named; no benchmarks);
#   test      the CTest suite in build-san/ (unit, integration with a real mosquitto, real SQLite
#             files, real gpsd); alongside it, at low priority, what mostly waits or can use the
#             suite's idle time: the arm64 cross build with its emulated tests, and in the
#             product tree the SocketCAN tests inside a QEMU VM (a stock Debian kernel with vcan),
#             the deployment tests (the Debian package installed and purged, the systemd unit),
#             the `memory` tests (resident memory means nothing under ASan's quarantine) and,
#             once the sanitized suite is over, the demo's story (scripts/demo.sh on the binary
#             it ships, timed on the wall clock);
#   arm64     the result of the cross build of the protocol and storage unit tests, run under
#             qemu-aarch64-static (tests/deploy/arm64-cross.sh: -O1, no debug info);
#   fuzz      every libFuzzer target of FUZZ_TARGETS for FUZZ_SECONDS each, side by side, started
#             as soon as the sanitized suite ends (alongside the product tree's tests).
# The summary lists every phase with its elapsed time (README: the measured total).
# Environment: JOBS (default: nproc), FUZZ_SECONDS (default 30), FUZZ_TARGETS (default
#   "fuzz_reassembler fuzz_command"; a target the tree does not define yet is skipped and said
#   so), SKIP_ASAN=1 (the test tree without sanitizers; fuzzing then skipped too), SKIP_FUZZ=1,
#   SKIP_VM=1, SKIP_ARM64=1, SKIP_PRODUCT=1 (no product tree: no VM, deploy, memory or demo tests),
#   ARM64_FIGURES=1 (the release arm64 binary with its size, and the emulated protocol
#   benchmark), ARM64_TESTS (the emulated test executables; default "protocol_tests
#   storage_tests").
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
JOBS=${JOBS:-$(nproc)}
FUZZ_SECONDS=${FUZZ_SECONDS:-30}
FUZZ_TARGETS=${FUZZ_TARGETS:-fuzz_reassembler fuzz_command}
[ "${SKIP_ASAN:-0}" = 1 ] && SKIP_FUZZ=1
SUMMARY=()
PHASES=()
PASSED=0
FAILED=0
SECONDS=0
status=0

phase_start() {  # name
  PHASE_NAME=$1
  PHASE_T0=$SECONDS
  echo
  echo "== [$((SECONDS / 60))m$((SECONDS % 60))s] $1"
}
phase_end() {  # [result]
  local elapsed=$((SECONDS - PHASE_T0))
  PHASES+=("$(printf '%-7s %4d s  %s' "$PHASE_NAME" "$elapsed" "${1:-}")")
}

# Counts a finished ctest run (its output in `log`, its exit code `rc`) into the summary.
account_ctest() {  # log rc label
  local line
  line=$(grep -E "tests passed, [0-9]+ tests failed out of [0-9]+|No tests were found" "$1" |
    tail -1 || true)
  if [[ $line =~ ([0-9]+)\ tests\ failed\ out\ of\ ([0-9]+) ]]; then
    FAILED=$((FAILED + BASH_REMATCH[1]))
    PASSED=$((PASSED + BASH_REMATCH[2] - BASH_REMATCH[1]))
  fi
  SUMMARY+=("$3: ${line:-no ctest summary} (exit $2)")
  # A failed GoogleTest assertion, where the end of the run shows it: CI may show only the tail
  # of a long log, and the summary is the tail.
  if [ "$2" != 0 ]; then
    while IFS= read -r line; do SUMMARY+=("  ${line:0:240}"); done \
      < <(grep -E -A4 ": Failure$|^\[  FAILED  \] [A-Za-z]" "$1" | grep -v "^--$" | head -n 30)
  fi
}

run_ctest() {  # build-dir ctest-args...
  local dir=$1 log
  shift
  log=$(mktemp)
  set +e
  (cd "$dir" && ctest --output-on-failure -j "$JOBS" --timeout 900 "$@") 2>&1 | tee "$log"
  local rc=${PIPESTATUS[0]}
  set -e
  account_ctest "$log" "$rc" "$dir $*"
  rm -f "$log"
  return "$rc"
}

# With ccache installed (and its directory kept between CI runs) unchanged files are not
# compiled again in any of the builds; without it nothing changes.
LAUNCHER=()
if command -v ccache >/dev/null; then
  LAUNCHER=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi

# man-db rebuilds its index after every dpkg run that installs a manual page: the package
# installs below and the deployment tests' `dpkg -i` (≈ 23 s of CPU each time, measured, on a
# 2-core machine where the run is CPU-bound). Paused for this run and restored when it ends,
# however it ends; the daily man-db timer (or `mandb`) brings the index up to date.
MANDB_FLAG=/var/lib/man-db/auto-update
if [ "$(id -u)" = 0 ] && { [ -e "$MANDB_FLAG" ] || [ -e "$MANDB_FLAG.fleetgw-paused" ]; }; then
  # (A run killed before its EXIT trap left the flag paused: this run restores it.)
  [ -e "$MANDB_FLAG" ] && mv "$MANDB_FLAG" "$MANDB_FLAG.fleetgw-paused"
  trap 'mv "$MANDB_FLAG.fleetgw-paused" "$MANDB_FLAG" 2>/dev/null || true' EXIT
fi

phase_start deps
./scripts/install-deps.sh --build
# Every new tree is generated for Ninja (an existing one keeps its generator: cmake cannot
# switch). Measured on 2 cores, the product tree: 169 s and 321 CPU-s with Ninja against 276 s
# and 420 CPU-s with Make, whose recursive per-target makefiles build each one-batch library
# only once the libraries before it are archived, and re-scan dependencies per target.
if [ -z "${CMAKE_GENERATOR:-}" ] && command -v ninja >/dev/null; then export CMAKE_GENERATOR=Ninja; fi
# Everything else is installed while the trees compile (one apt run; waited for below).
extra_packages=()
if [ "${SKIP_ARM64:-0}" != 1 ]; then
  mapfile -t extra_packages < <(tests/deploy/arm64-cross.sh --packages)
fi
mkdir -p build build-san
deps_log=build/deps.log
./scripts/install-deps.sh "${extra_packages[@]}" >"$deps_log" 2>&1 &
deps_pid=$!
phase_end

# The product tree: the binaries exactly as shipped (gcc, Release, -Os, static protobuf and
# SQLite); test executables are built only when named (the VM test binary and
# the `memory` tests). Compiled at nice 19, so it only takes CPU the test tree leaves idle.
# (Tried: nice 10, ahead of the arm64 cross build, so that its tests run during the sanitized
# suite: the product tail shrank by a minute and the suite grew by as much, with more timing
# contention for its wall-clock tests.)
product_build() {
  # No benchmarks: nothing in this run runs them (bench/ scripts and README figures build them),
  # and their compile was the product tree's longest tail.
  cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DFLEETGW_WERROR=ON -DFLEETGW_UNITY=ON \
    -DFLEETGW_UNITY_TESTS=ON -DFLEETGW_UNITY_BATCH_SIZE=32 -DFLEETGW_TESTS_IN_ALL=OFF \
    -DFLEETGW_BUILD_BENCH=OFF "${LAUNCHER[@]}" >/dev/null
  local targets=(all cli_memory_tests uplink_contract_tests)
  [ "${SKIP_VM:-0}" = 1 ] || targets+=(socketcan_vm_tests)
  nice -n 19 cmake --build build -j "$JOBS" --target "${targets[@]}"
}
product_pid=
rm -f build/product.rc build-san/suite.done
if [ "${SKIP_PRODUCT:-0}" != 1 ]; then
  ( rc=0; product_build >build/product-build.log 2>&1 || rc=$?; echo "$rc" >build/product.rc ) &
  product_pid=$!
fi

phase_start build
san_flags=(-DFLEETGW_SANITIZE=ON -DFLEETGW_FUZZ=ON)
[ "${SKIP_ASAN:-0}" = 1 ] && san_flags=(-DFLEETGW_SANITIZE=OFF -DFLEETGW_FUZZ=OFF)
# -O1 with line tables: sanitizer reports keep file:line, the suite runs at a useful speed. The
# test files themselves at -O0 (half their compile; the code under test keeps -O1), and so are the
# CLI front end, the configuration and the status code, which run once per command
# (FLEETGW_CLI_COMPILE_OPTIONS). (Tried: all the service's code at -O0, 22 % less compile CPU,
# but the sanitized simulator then falls behind the wall clock and five end-to-end tests fail.)
# Each library and test executable is one unity batch (FLEETGW_UNITY_BATCH_SIZE=32): the heavy
# headers (protobuf, asio, fmt, gtest) parsed once per target. Linked with lld: a third of GNU
# ld's time for the ≈ 40 executables.
CXX=clang++ CC=clang cmake -S . -B build-san -DCMAKE_BUILD_TYPE=Debug \
  "-DCMAKE_CXX_FLAGS_DEBUG=-O1 -gline-tables-only" "${san_flags[@]}" \
  -DFLEETGW_TEST_COMPILE_OPTIONS=-O0 -DFLEETGW_CLI_COMPILE_OPTIONS=-O0 \
  -DCMAKE_EXE_LINKER_FLAGS=-fuse-ld=lld \
  -DFLEETGW_WERROR=ON -DFLEETGW_BUILD_BENCH=OFF -DFLEETGW_UNITY=ON -DFLEETGW_UNITY_TESTS=ON \
  -DFLEETGW_UNITY_BATCH_SIZE=32 "${LAUNCHER[@]}" >/dev/null
cmake --build build-san -j "$JOBS"
echo "== the rest of the packages (installed during the build)"
deps_rc=0
wait "$deps_pid" || deps_rc=$?
tail -3 "$deps_log"
if [ "$deps_rc" != 0 ]; then
  cat "$deps_log"
  echo "install-deps failed (exit $deps_rc)" >&2
  exit 1
fi
phase_end

phase_start test
# The test executables are listed once, here, before concurrent ctest processes read the lists
# (gtest discovery at ctest time: concurrent discoveries would write the same files).
(cd build-san && ctest -N >/dev/null)
arm64_pid=
if [ "${SKIP_ARM64:-0}" != 1 ]; then
  (cd build-san && exec nice -n 19 ctest --output-on-failure --timeout 1500 -L arm64) \
    >build-san/arm64-tests.log 2>&1 &
  arm64_pid=$!
fi
# Once the product tree is built: the SocketCAN tests in the VM (≈ 70 s, mostly waiting), the
# deployment tests and the memory tests, one after the other (the package test installs the
# package on this machine).
product_tests_pid=
if [ -n "$product_pid" ]; then
  (
    while kill -0 "$product_pid" 2>/dev/null; do sleep 1; done
    [ "$(cat build/product.rc 2>/dev/null)" = 0 ] || exit 0
    cd build
    ctest -N >/dev/null
    # The demo's story (about a minute, mostly waiting on its simulated bike at 40x the wall
    # clock) once the sanitized suite is over: it reacts to what the bike does in wall time, and
    # a machine busy with three ASan tests at once would only test the machine.
    ( while [ ! -e "$ROOT/build-san/suite.done" ]; do sleep 1; done
      rc=0; ctest --output-on-failure --timeout 900 -L demo >demo-tests.log 2>&1 || rc=$?
      echo "$rc" >demo-tests.rc ) &
    demo_pid=$!
    # The VM test (one QEMU core, mostly booting) beside the deployment tests (dpkg and lintian,
    # one at a time: they install packages on this machine), then the memory tests.
    vm_pid=
    if [ "${SKIP_VM:-0}" != 1 ]; then
      ( rc=0; ctest --output-on-failure --timeout 900 -L vm >vm-tests.log 2>&1 || rc=$?
        echo "$rc" >vm-tests.rc ) &
      vm_pid=$!
    fi
    rc=0; ctest --output-on-failure --timeout 900 -L deploy -LE arm64 >deploy-tests.log 2>&1 ||
      rc=$?
    echo "$rc" >deploy-tests.rc
    rc=0; ctest --output-on-failure --timeout 900 -L memory >memory-tests.log 2>&1 || rc=$?
    echo "$rc" >memory-tests.rc
    [ -z "$vm_pid" ] || wait "$vm_pid"
    wait "$demo_pid"
  ) &
  product_tests_pid=$!
fi
if [ "${SKIP_ASAN:-0}" != 1 ]; then
  # One documented ASan suppression: a race inside Paho C itself (tests/sanitizer/asan.supp).
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:suppressions=$ROOT/tests/sanitizer/asan.supp
  export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  # And one for LeakSanitizer: memory Paho C itself does not free (tests/sanitizer/lsan.supp).
  export LSAN_OPTIONS=suppressions=$ROOT/tests/sanitizer/lsan.supp
fi
run_ctest build-san -j "$((JOBS + 1))" -LE "vm|deploy|arm64|demo" || status=1
touch build-san/suite.done
unset ASAN_OPTIONS UBSAN_OPTIONS LSAN_OPTIONS
phase_end

# The fuzz targets (each single-threaded, FUZZ_SECONDS each) start as soon as the sanitized suite
# is over, side by side with the product tree's remaining tests, which mostly wait.
fuzz_targets=()
fuzz_pids=()
if [ "${SKIP_FUZZ:-0}" != 1 ]; then
  for t in $FUZZ_TARGETS; do
    if [ -x "build-san/tests/fuzz/$t" ]; then
      fuzz_targets+=("$t")
    else
      SUMMARY+=("fuzz $t: skipped (no such target in tests/fuzz)")
    fi
  done
  for t in "${fuzz_targets[@]}"; do
    corpus=build-san/corpus/$t
    mkdir -p "$corpus"
    seeds=()
    for s in "tests/fuzz/seeds/$t" "tests/fuzz/seeds"; do
      if [ -d "$s" ]; then
        seeds=("$ROOT/$s")
        break
      fi
    done
    rm -f "build-san/$t.rc"
    ( rc=0
      "build-san/tests/fuzz/$t" -max_total_time="$FUZZ_SECONDS" -print_final_stats=1 \
        "$corpus" "${seeds[@]}" >"build-san/$t.log" 2>&1 || rc=$?
      echo "$rc" >"build-san/$t.rc" ) &
    fuzz_pids+=($!)
  done
fi

if [ -n "$product_pid" ]; then
  phase_start product
  wait "$product_pid" || true
  wait "$product_tests_pid" || true
  if [ "$(cat build/product.rc 2>/dev/null)" != 0 ]; then
    grep -E "error|Error" build/product-build.log | head -40
    SUMMARY+=("product build: FAILED (build/product-build.log)")
    FAILED=$((FAILED + 1))
    status=1
  else
    for t in vm deploy memory demo; do
      [ -f "build/$t-tests.rc" ] || continue
      echo "== $t tests (product tree, ran alongside)"
      cat "build/$t-tests.log"
      rc=$(cat "build/$t-tests.rc")
      account_ctest "build/$t-tests.log" "$rc" "build -L $t (alongside)"
      if [ "$rc" != 0 ]; then
        status=1
        # What failed, where the end of the run shows it (the summary).
        while IFS= read -r line; do SUMMARY+=("  $t: $line"); done \
          < <(grep -E "MISSED|^FAIL|demo.sh exit" "build/$t-tests.log" | head -n 12)
      fi
    done
  fi
  phase_end
fi

if [ -n "$arm64_pid" ]; then
  phase_start arm64
  arm64_rc=0
  wait "$arm64_pid" || arm64_rc=$?
  cat build-san/arm64-tests.log
  account_ctest build-san/arm64-tests.log "$arm64_rc" "build-san -L arm64 (alongside)"
  [ "$arm64_rc" = 0 ] || status=1
  if [ -f build-san/arm64-cross/summary.txt ]; then
    while IFS= read -r line; do SUMMARY+=("arm64 ${line#"${line%%[![:space:]]*}"}"); done \
      < <(grep -v "^==" build-san/arm64-cross/summary.txt)
  fi
  phase_end
fi

if [ "${SKIP_FUZZ:-0}" != 1 ]; then
  phase_start fuzz
  [ ${#fuzz_pids[@]} = 0 ] || wait "${fuzz_pids[@]}" || true
  for t in "${fuzz_targets[@]}"; do
    log=build-san/$t.log
    if [ "$(cat "build-san/$t.rc")" = 0 ]; then
      runs=$(grep -E 'stat::number_of_executed_units' "$log" | awk '{print $2}')
      SUMMARY+=("fuzz $t: $runs inputs in ${FUZZ_SECONDS}s ($((runs / FUZZ_SECONDS))/s), no crash")
      PASSED=$((PASSED + 1))
    else
      tail -50 "$log"
      SUMMARY+=("fuzz $t: CRASH or sanitizer report (see $log)")
      FAILED=$((FAILED + 1))
      status=1
    fi
  done
  phase_end
fi

echo
echo "== summary"
printf '  %s\n' "${SUMMARY[@]}"
echo "== elapsed per phase"
printf '  %s\n' "${PHASES[@]}"
echo "  total   $((SECONDS / 60)) min $((SECONDS % 60)) s"
# The CPU time of everything the run started (user, system): on a shared or busy machine the
# elapsed time varies, this much less.
times >build/cpu-times.txt  # in this shell: a subshell's `times` would not see the children
read -r cpu_user cpu_sys < <(tail -1 build/cpu-times.txt)
echo "  cpu     $cpu_user user, $cpu_sys system"
echo "fleetgw: $PASSED passed, $FAILED failed"
exit "$status"
