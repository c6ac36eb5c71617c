#!/usr/bin/env bash
# Runs every fleetgw test on a fresh Debian 12 machine (as root, or with sudo):
#   1. installs the Debian packages it needs (idempotent),
#   2. builds with warnings as errors and runs the whole CTest suite (unit, integration with a
#      real mosquitto, real SQLite files, and the SocketCAN tests inside a QEMU VM),
#   3. runs the libFuzzer target over the reassembler and decoder for FUZZ_SECONDS (default 60),
#   4. rebuilds with AddressSanitizer + UndefinedBehaviorSanitizer and runs the suite again.
#   The normal pass also builds and installs the Debian package (then purges it) and cross-builds
#   for arm64, running the unit tests under qemu-aarch64-static.
# Environment: JOBS (default: nproc), FUZZ_SECONDS, SKIP_ASAN=1, SKIP_FUZZ=1, SKIP_VM=1,
#   SKIP_ARM64=1.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
JOBS=${JOBS:-$(nproc)}
FUZZ_SECONDS=${FUZZ_SECONDS:-60}
SUMMARY=()
PASSED=0
FAILED=0

./scripts/install-deps.sh

run_ctest() {  # build-dir label-exclude
  local dir=$1 exclude=$2 log
  log=$(mktemp)
  set +e
  (cd "$dir" && ctest --output-on-failure -j "$JOBS" ${exclude:+-LE "$exclude"} --timeout 900) 2>&1 | tee "$log"
  local rc=${PIPESTATUS[0]}
  set -e
  local line
  line=$(grep -E "tests passed, [0-9]+ tests failed out of [0-9]+" "$log" | tail -1 || true)
  if [[ $line =~ ([0-9]+)\ tests\ failed\ out\ of\ ([0-9]+) ]]; then
    FAILED=$((FAILED + BASH_REMATCH[1]))
    PASSED=$((PASSED + BASH_REMATCH[2] - BASH_REMATCH[1]))
  fi
  SUMMARY+=("$dir: ${line:-no ctest summary} (exit $rc)")
  rm -f "$log"
  return "$rc"
}

status=0
echo "== build (warnings as errors)"
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFLEETGW_WERROR=ON >/dev/null
cmake --build build -j "$JOBS"
echo "== test"
exclude=""
[ "${SKIP_VM:-0}" = 1 ] && exclude="vm"
[ "${SKIP_ARM64:-0}" = 1 ] && exclude="${exclude:+$exclude|}arm64"
run_ctest build "$exclude" || status=1

if [ "${SKIP_FUZZ:-0}" != 1 ]; then
  echo "== fuzz (${FUZZ_SECONDS}s, libFuzzer + ASan/UBSan)"
  CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFLEETGW_FUZZ=ON \
    -DFLEETGW_BUILD_TESTS=OFF -DFLEETGW_BUILD_BENCH=OFF -DFLEETGW_ONLY_PROTOCOL=ON >/dev/null
  cmake --build build-fuzz --target fuzz_reassembler -j "$JOBS"
  mkdir -p build-fuzz/corpus
  if build-fuzz/tests/fuzz/fuzz_reassembler -max_total_time="$FUZZ_SECONDS" -print_final_stats=1 \
      build-fuzz/corpus "$ROOT/tests/fuzz/seeds" > build-fuzz/fuzz.log 2>&1; then
    SUMMARY+=("fuzz: $(grep -E 'stat::number_of_executed_units' build-fuzz/fuzz.log | awk '{print $2}') inputs in ${FUZZ_SECONDS}s, no crash")
    PASSED=$((PASSED + 1))
  else
    tail -50 build-fuzz/fuzz.log
    SUMMARY+=("fuzz: CRASH or sanitizer report (see build-fuzz/fuzz.log)")
    FAILED=$((FAILED + 1))
    status=1
  fi
fi

if [ "${SKIP_ASAN:-0}" != 1 ]; then
  echo "== build and test with AddressSanitizer + UndefinedBehaviorSanitizer"
  cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=Debug -DFLEETGW_SANITIZE=ON -DFLEETGW_WERROR=ON \
    -DFLEETGW_BUILD_BENCH=OFF >/dev/null
  cmake --build build-asan -j "$JOBS"
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    run_ctest build-asan "vm|bench|deploy|arm64" || status=1
fi

echo
echo "== summary"
printf '  %s\n' "${SUMMARY[@]}"
echo "fleetgw: $PASSED passed, $FAILED failed"
exit "$status"
