#!/usr/bin/env bash
# Runs every fleetgw test on a fresh Debian 12 machine (as root, or with sudo), in timed phases:
#   deps      the Debian packages the x86 build needs; the rest (brokers, gpsd, the VM, clang,
#             lintian, the arm64 cross packages) is installed in the background during the build;
#   build     one configure of build/ (Release, warnings as errors, test files compiled in unity
#             batches), then the whole tree;
#   test      the CTest suite without the arm64 tests (unit, integration with a real mosquitto,
#             real SQLite files, the Debian package installed and purged); alongside it, at low
#             CPU priority, what mostly waits or can use the suite's idle time: the SocketCAN
#             tests inside a QEMU VM (a stock Debian kernel with vcan), the arm64 cross build
#             with its emulated tests, and the sanitizer build;
#   arm64     the result of the cross build of the protocol and storage unit tests, run under
#             qemu-aarch64-static (tests/deploy/arm64-cross.sh: -O1, no debug info);
#   sanitize  one clang build with AddressSanitizer + UndefinedBehaviorSanitizer and libFuzzer
#             instrumentation (no benchmarks, no VM test binary): the suite again, then every
#             libFuzzer target of FUZZ_TARGETS for FUZZ_SECONDS each.
# The summary lists every phase with its elapsed time. On the project's 2-core machines the whole
# run takes about 28 minutes from a fresh clone, most of it the sanitizer build (README figures).
# Environment: JOBS (default: nproc), FUZZ_SECONDS (default 30), FUZZ_TARGETS (default
#   "fuzz_reassembler fuzz_command"; a target the tree does not define yet is skipped and said
#   so), SKIP_ASAN=1, SKIP_FUZZ=1, SKIP_VM=1, SKIP_ARM64=1, ARM64_FIGURES=1 (the release arm64
#   binary with its size, and the emulated protocol benchmark), ARM64_TESTS (the emulated test
#   executables; default "protocol_tests storage_tests").
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
JOBS=${JOBS:-$(nproc)}
FUZZ_SECONDS=${FUZZ_SECONDS:-30}
FUZZ_TARGETS=${FUZZ_TARGETS:-fuzz_reassembler fuzz_command}
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

phase_start deps
./scripts/install-deps.sh --build
# Everything else is installed while the x86 tree compiles (one apt run; waited for below).
extra_packages=()
if [ "${SKIP_ARM64:-0}" != 1 ]; then
  mapfile -t extra_packages < <(tests/deploy/arm64-cross.sh --packages)
fi
deps_log=$(mktemp)
./scripts/install-deps.sh "${extra_packages[@]}" >"$deps_log" 2>&1 &
deps_pid=$!
phase_end

phase_start build
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DFLEETGW_WERROR=ON -DFLEETGW_UNITY=ON \
  -DFLEETGW_UNITY_TESTS=ON \
  "${LAUNCHER[@]}" >/dev/null
cmake --build build -j "$JOBS"
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

# The sanitizer build: one clang tree serves both the sanitizer suite and the fuzzers. Everything
# is compiled with AddressSanitizer + UndefinedBehaviorSanitizer and libFuzzer's coverage
# instrumentation (-fsanitize=fuzzer-no-link); the fuzz targets link libFuzzer's main, the tests
# gtest's. -O1 with line tables: sanitizer reports keep file:line, the suite runs at a useful
# speed. Started when the x86 suite starts, at low priority: it compiles in the suite's idle time.
san_build() {
  CXX=clang++ CC=clang cmake -S . -B build-san -DCMAKE_BUILD_TYPE=Debug \
    "-DCMAKE_CXX_FLAGS_DEBUG=-O1 -gline-tables-only" -DFLEETGW_SANITIZE=ON -DFLEETGW_FUZZ=ON \
    -DFLEETGW_WERROR=ON -DFLEETGW_BUILD_BENCH=OFF -DFLEETGW_UNITY=ON -DFLEETGW_UNITY_TESTS=ON \
    "${LAUNCHER[@]}" \
    >/dev/null
  local san_targets build_targets=() t
  san_targets=$(cmake --build build-san --target help | sed -n 's/^\.\.\. //p')
  if [ "${SKIP_ASAN:-0}" != 1 ]; then
    # Everything the suite executes; not the VM test binary (it runs in the VM only).
    mapfile -t build_targets < <(grep -Ev '^(socketcan_vm_tests|.*_autogen)$' <<<"$san_targets" |
      grep -E '_tests$|_smoke$|^fleetgw(-watch)?$' || true)
  fi
  : >build/san-fuzz-targets
  if [ "${SKIP_FUZZ:-0}" != 1 ]; then
    for t in $FUZZ_TARGETS; do
      if grep -qx "$t" <<<"$san_targets"; then
        build_targets+=("$t")
        echo "$t" >>build/san-fuzz-targets
      else
        echo "fuzz $t: skipped (no such target in tests/fuzz)" >>build/san-fuzz-targets.skipped
      fi
    done
  fi
  nice -n 19 cmake --build build-san -j "$JOBS" --target "${build_targets[@]}"
}

phase_start test
# The SocketCAN tests boot a VM that mostly waits (≈ 70 s, ≈ 15 s of CPU); the arm64 cross build
# and the sanitizer build compile at low priority while the suite waits on brokers and child
# processes. Their output is printed once the suite is done.
# The test executables are listed once, here, before three ctest processes read the lists
# (gtest discovery at ctest time: concurrent discoveries would write the same files).
(cd build && ctest -N >/dev/null)
vm_pid=
if [ "${SKIP_VM:-0}" != 1 ]; then
  (cd build && exec ctest --output-on-failure --timeout 900 -L vm) >build/vm-tests.log 2>&1 &
  vm_pid=$!
fi
arm64_pid=
if [ "${SKIP_ARM64:-0}" != 1 ]; then
  (cd build && exec nice -n 19 ctest --output-on-failure --timeout 1500 -L arm64) \
    >build/arm64-tests.log 2>&1 &
  arm64_pid=$!
fi
san_pid=
rm -f build/san-fuzz-targets build/san-fuzz-targets.skipped
if [ "${SKIP_ASAN:-0}" != 1 ] || [ "${SKIP_FUZZ:-0}" != 1 ]; then
  san_build >build/san-build.log 2>&1 &
  san_pid=$!
fi
run_ctest build -LE "vm|arm64" || status=1
if [ -n "$vm_pid" ]; then
  vm_rc=0
  wait "$vm_pid" || vm_rc=$?
  echo "== SocketCAN tests in the VM (ran alongside)"
  cat build/vm-tests.log
  account_ctest build/vm-tests.log "$vm_rc" "build -L vm (alongside)"
  [ "$vm_rc" = 0 ] || status=1
fi
phase_end

if [ -n "$arm64_pid" ]; then
  phase_start arm64
  arm64_rc=0
  wait "$arm64_pid" || arm64_rc=$?
  cat build/arm64-tests.log
  account_ctest build/arm64-tests.log "$arm64_rc" "build -L arm64 (alongside)"
  [ "$arm64_rc" = 0 ] || status=1
  if [ -f build/arm64-cross/summary.txt ]; then
    while IFS= read -r line; do SUMMARY+=("arm64 ${line#"${line%%[![:space:]]*}"}"); done \
      < <(grep -v "^==" build/arm64-cross/summary.txt)
  fi
  phase_end
fi

if [ -n "$san_pid" ]; then
  phase_start sanitize
  san_rc=0
  wait "$san_pid" || san_rc=$?
  tail -5 build/san-build.log
  san_built=$SECONDS
  if [ "$san_rc" != 0 ]; then
    grep -E "error|Error" build/san-build.log | head -40
    SUMMARY+=("sanitizer build: FAILED (exit $san_rc, build/san-build.log)")
    FAILED=$((FAILED + 1))
    status=1
  else
    if [ "${SKIP_ASAN:-0}" != 1 ]; then
      ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
        UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
        run_ctest build-san -j "$((JOBS + 1))" -LE "vm|bench|deploy|arm64" || status=1
    fi
    san_tested=$SECONDS
    if [ -f build/san-fuzz-targets.skipped ]; then
      while IFS= read -r line; do SUMMARY+=("$line"); done <build/san-fuzz-targets.skipped
    fi
    # The fuzz targets run side by side (each is single-threaded), FUZZ_SECONDS each.
    mapfile -t fuzz_targets <build/san-fuzz-targets
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
      ( rc=0
        "build-san/tests/fuzz/$t" -max_total_time="$FUZZ_SECONDS" -print_final_stats=1 \
          "$corpus" "${seeds[@]}" >"build-san/$t.log" 2>&1 || rc=$?
        echo "$rc" >"build-san/$t.rc" ) &
    done
    wait
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
    phase_end "build waited $((san_built - PHASE_T0)) s, tests $((san_tested - san_built)) s, fuzz $((SECONDS - san_tested)) s"
  fi
  [ "$san_rc" = 0 ] || phase_end "build failed"
fi

echo
echo "== summary"
printf '  %s\n' "${SUMMARY[@]}"
echo "== elapsed per phase"
printf '  %s\n' "${PHASES[@]}"
echo "  total   $((SECONDS / 60)) min $((SECONDS % 60)) s"
echo "fleetgw: $PASSED passed, $FAILED failed"
exit "$status"
