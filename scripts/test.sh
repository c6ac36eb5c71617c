#!/usr/bin/env bash
# Runs every fleetgw test on a fresh Debian 12 machine (as root, or with sudo), in timed phases:
#   deps      installs the Debian packages, the arm64 cross packages included, in one apt run;
#   build     one configure of build/ (warnings as errors), then the whole tree;
#   test      the CTest suite without the VM and arm64 tests (unit, integration with a real
#             mosquitto, real SQLite files, the Debian package installed and purged);
#   vm        the SocketCAN tests inside a QEMU VM (a stock Debian kernel with vcan);
#   arm64     cross build of the service and the unit tests that run under qemu-aarch64-static
#             (tests/deploy/arm64-cross.sh: -O1, no debug info, no benchmarks);
#   fuzz      every libFuzzer target of FUZZ_TARGETS for FUZZ_SECONDS each (ASan/UBSan);
#   asan      a Debug build with AddressSanitizer + UndefinedBehaviorSanitizer (no benchmarks, no
#             VM test binary) and the suite again.
# The summary lists every phase with its elapsed time.
# Environment: JOBS (default: nproc), FUZZ_SECONDS (default 30), FUZZ_TARGETS (default
#   "fuzz_reassembler fuzz_command"; a target the tree does not define yet is skipped and said
#   so), SKIP_ASAN=1, SKIP_FUZZ=1, SKIP_VM=1, SKIP_ARM64=1, ARM64_BENCH=1 (also the emulated
#   protocol benchmark).
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

run_ctest() {  # build-dir ctest-args...
  local dir=$1 log
  shift
  log=$(mktemp)
  set +e
  (cd "$dir" && ctest --output-on-failure -j "$JOBS" --timeout 900 "$@") 2>&1 | tee "$log"
  local rc=${PIPESTATUS[0]}
  set -e
  local line
  line=$(grep -E "tests passed, [0-9]+ tests failed out of [0-9]+|No tests were found" "$log" |
    tail -1 || true)
  if [[ $line =~ ([0-9]+)\ tests\ failed\ out\ of\ ([0-9]+) ]]; then
    FAILED=$((FAILED + BASH_REMATCH[1]))
    PASSED=$((PASSED + BASH_REMATCH[2] - BASH_REMATCH[1]))
  fi
  SUMMARY+=("$dir $*: ${line:-no ctest summary} (exit $rc)")
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
extra_packages=()
if [ "${SKIP_ARM64:-0}" != 1 ]; then
  mapfile -t extra_packages < <(tests/deploy/arm64-cross.sh --packages)
fi
./scripts/install-deps.sh "${extra_packages[@]}"
phase_end

phase_start build
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFLEETGW_WERROR=ON "${LAUNCHER[@]}" >/dev/null
cmake --build build -j "$JOBS"
phase_end

phase_start test
run_ctest build -LE "vm|arm64" || status=1
phase_end

if [ "${SKIP_VM:-0}" != 1 ]; then
  phase_start vm
  run_ctest build -L vm || status=1
  phase_end
fi

if [ "${SKIP_ARM64:-0}" != 1 ]; then
  phase_start arm64
  run_ctest build -L arm64 || status=1
  if [ -f build/arm64-cross/summary.txt ]; then
    while IFS= read -r line; do SUMMARY+=("arm64 ${line#"${line%%[![:space:]]*}"}"); done \
      < <(grep -v "^==" build/arm64-cross/summary.txt)
  fi
  phase_end
fi

if [ "${SKIP_FUZZ:-0}" != 1 ]; then
  phase_start fuzz
  # The protocol library alone is enough for fuzzers over the frame path; a fuzzer over code
  # outside it (e.g. fuzz_command) needs the full tree, configured without tests or benchmarks.
  fuzz_configure() {  # only-protocol ON|OFF
    CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFLEETGW_FUZZ=ON \
      -DFLEETGW_BUILD_TESTS=OFF -DFLEETGW_BUILD_BENCH=OFF -DFLEETGW_ONLY_PROTOCOL="$1" \
      "${LAUNCHER[@]}" >/dev/null
    cmake --build build-fuzz --target help | sed -n 's/^\.\.\. //p'
  }
  available=$(fuzz_configure ON)
  for t in $FUZZ_TARGETS; do
    if ! grep -qx "$t" <<<"$available" && [ -f "tests/fuzz/$t.cc" ]; then
      available=$(fuzz_configure OFF)
      break
    fi
  done
  for t in $FUZZ_TARGETS; do
    if ! grep -qx "$t" <<<"$available"; then
      SUMMARY+=("fuzz $t: skipped (no such target in tests/fuzz yet)")
      continue
    fi
    cmake --build build-fuzz --target "$t" -j "$JOBS"
    corpus=build-fuzz/corpus/$t
    mkdir -p "$corpus"
    seeds=()
    for s in "tests/fuzz/seeds/$t" "tests/fuzz/seeds"; do
      if [ -d "$s" ]; then
        seeds=("$ROOT/$s")
        break
      fi
    done
    log=build-fuzz/$t.log
    if "build-fuzz/tests/fuzz/$t" -max_total_time="$FUZZ_SECONDS" -print_final_stats=1 \
      "$corpus" "${seeds[@]}" >"$log" 2>&1; then
      SUMMARY+=("fuzz $t: $(grep -E 'stat::number_of_executed_units' "$log" | awk '{print $2}') inputs in ${FUZZ_SECONDS}s, no crash")
      PASSED=$((PASSED + 1))
    else
      tail -50 "$log"
      SUMMARY+=("fuzz $t: CRASH or sanitizer report (see $log)")
      FAILED=$((FAILED + 1))
      status=1
    fi
  done
  phase_end "$FUZZ_TARGETS"
fi

if [ "${SKIP_ASAN:-0}" != 1 ]; then
  phase_start asan
  cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=Debug -DFLEETGW_SANITIZE=ON -DFLEETGW_WERROR=ON \
    -DFLEETGW_BUILD_BENCH=OFF "${LAUNCHER[@]}" >/dev/null
  # Everything the sanitizer run executes; not the VM test binary (it runs in the VM only).
  asan_targets=$(cmake --build build-asan --target help | sed -n 's/^\.\.\. //p' |
    grep -Ev '^(all|clean|depend|edit_cache|rebuild_cache|install.*|list_install_components|package.*|test|socketcan_vm_tests|.*_autogen)$' |
    grep -E '_tests$|_smoke$|^fleetgw(-watch)?$' || true)
  # shellcheck disable=SC2086
  cmake --build build-asan -j "$JOBS" --target $asan_targets
  asan_built=$SECONDS
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    run_ctest build-asan -LE "vm|bench|deploy|arm64" || status=1
  phase_end "build $((asan_built - PHASE_T0)) s, tests $((SECONDS - asan_built)) s"
fi

echo
echo "== summary"
printf '  %s\n' "${SUMMARY[@]}"
echo "== elapsed per phase"
printf '  %s\n' "${PHASES[@]}"
echo "  total   $((SECONDS / 60)) min $((SECONDS % 60)) s"
echo "fleetgw: $PASSED passed, $FAILED failed"
exit "$status"
