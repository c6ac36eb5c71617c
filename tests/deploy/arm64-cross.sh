#!/usr/bin/env bash
# Cross-builds fleetgw for arm64 (deploy/toolchains/aarch64-linux-gnu.cmake), runs the unit tests
# that need neither a broker nor a network under qemu-aarch64-static; with ARM64_FIGURES=1 also
# the release service binary (its stripped size) and the protocol benchmark -- EMULATED figures,
# not arm64 hardware figures.
#
# Usage: arm64-cross.sh [SOURCE_DIR] [BUILD_DIR]
#   defaults: the repository containing this script, and SOURCE_DIR/build-arm64.
#        arm64-cross.sh --packages   prints the Debian packages it needs, one a line (for
#                                    scripts/install-deps.sh: one apt transaction for all).
# Environment: JOBS (default nproc), BENCH_MIN_TIME (default 0.2 s per benchmark),
#   ARM64_FIGURES=1: the release build (RelWithDebInfo, -Os as deployed) plus the emulated
#   protocol benchmark, for the figures in the README. Without it (CI) the build is what the
#   emulated tests need and no more: -O1, no debug info, no benchmarks -- the tests check the
#   code on arm64, the size printed is then that of the CI build, not of the release.
# Exit: 0 all passed, 1 a build or test failed, 77 (skip) only when the cross packages cannot be
# installed (not root, or apt cannot reach them).
set -euo pipefail
PRINT_PACKAGES=0
if [ "${1:-}" = --packages ]; then
  PRINT_PACKAGES=1
  shift
fi
HERE=$(cd "$(dirname "$0")" && pwd)
SRC=$(cd "${1:-$HERE/../..}" && pwd)
BUILD=${2:-$SRC/build-arm64}
JOBS=${JOBS:-$(nproc)}
BENCH_MIN_TIME=${BENCH_MIN_TIME:-0.2}
TRIPLE=aarch64-linux-gnu
QEMU=qemu-aarch64-static
SECONDS=0

# What the cross build needs: the compiler, the project's -dev libraries for arm64 (headers-only
# and Architecture: all ones need no :arm64; libtomlplusplus-dev is per-architecture), the host's protoc, and qemu to run tests.
PACKAGES=(
  crossbuild-essential-arm64 qemu-user-static protobuf-compiler
  libsqlite3-dev:arm64 libprotobuf-dev:arm64 libspdlog-dev:arm64 libfmt-dev:arm64
  libgtest-dev:arm64 libgmock-dev:arm64
  libpaho-mqttpp-dev:arm64 libpaho-mqtt-dev:arm64 libssl-dev:arm64 libsystemd-dev:arm64
  libtomlplusplus-dev:arm64 libgps-dev:arm64 libcli11-dev nlohmann-json3-dev libasio-dev
)
FIGURES=${ARM64_FIGURES:-0}
[ "$FIGURES" = 1 ] && PACKAGES+=(libbenchmark-dev:arm64)
if [ "$PRINT_PACKAGES" = 1 ]; then
  printf '%s\n' "${PACKAGES[@]}"
  exit 0
fi
# Unit tests with no broker, no network and no CAN hardware. By default the layers where the
# architecture shows (byte order, alignment, integer widths): the protocol library (CRC, frames,
# reassembly, every catalogue decode) and the SQLite store (records, outbox, budget); the logic
# above them is plain C++ over those values. ARM64_TESTS="protocol_tests status_tests
# storage_tests node_tests domain_tests sim_tests" runs the wider set (≈ 3x the build).
read -r -a TESTS <<<"${ARM64_TESTS:-protocol_tests storage_tests}"

skip() { echo "arm64-cross: SKIP: $*"; exit 77; }
step() { echo "== arm64-cross [$((SECONDS / 60))m$((SECONDS % 60))s] $*"; }

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  step "installing ${missing[*]}"
  [ "$(id -u)" -eq 0 ] || skip "missing ${missing[*]} and not root to install them"
  if ! dpkg --print-foreign-architectures | grep -qx arm64; then dpkg --add-architecture arm64; fi
  apt-get update -qq || skip "apt-get update failed (no package mirror reachable?)"
  for p in "${missing[@]}"; do
    apt-cache policy "$p" 2>/dev/null | grep -q "Candidate: [0-9]" || skip "no package $p in the archive"
  done
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" ||
    skip "apt-get install of the cross packages failed"
fi
# protoc runs on the host, libprotobuf on the target: their versions must be the same release.
host_protoc=$(dpkg-query -W -f='${Version}' protobuf-compiler)
arm_protobuf=$(dpkg-query -W -f='${Version}' libprotobuf-dev:arm64)
if [ "$host_protoc" != "$arm_protobuf" ]; then
  echo "arm64-cross: protoc $host_protoc does not match libprotobuf-dev:arm64 $arm_protobuf" >&2
  exit 1
fi

if [ "$FIGURES" = 1 ]; then
  build_flags=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DFLEETGW_BUILD_BENCH=ON)
  targets=(fleetgw bench_protocol)
else
  # -O1 without -g: about half the compile time of -O2 -g on these TUs, and the emulated tests
  # still run at a useful speed. -Os (FLEETGW_OPTIMIZE_SIZE) would override -O1: off here.
  build_flags=(-DCMAKE_BUILD_TYPE=Release "-DCMAKE_CXX_FLAGS_RELEASE=-O1 -DNDEBUG"
    -DFLEETGW_OPTIMIZE_SIZE=OFF -DFLEETGW_BUILD_BENCH=OFF -DFLEETGW_UNITY=ON -DFLEETGW_UNITY_TESTS=ON
    -DFLEETGW_UNITY_BATCH_SIZE=32  # a library or test executable: one batch, headers parsed once
    -DFLEETGW_TEST_COMPILE_OPTIONS=-O0)  # the test files unoptimised: the code under test is -O1
  # Only what runs under emulation: the test binaries (the service binary is the figures build's).
  targets=()
fi
if command -v ccache >/dev/null; then
  build_flags+=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi
step "configure ($BUILD: ${build_flags[*]})"
cmake -S "$SRC" -B "$BUILD" -DCMAKE_TOOLCHAIN_FILE="$SRC/deploy/toolchains/$TRIPLE.cmake" \
  -DFLEETGW_WERROR=ON "${build_flags[@]}" \
  -DCMAKE_GTEST_DISCOVER_TESTS_DISCOVERY_MODE=PRE_TEST >"$BUILD.configure.log" 2>&1 ||
  { cat "$BUILD.configure.log"; exit 1; }

# The tree's targets, one name per line, from either generator (Make: "... name"; Ninja:
# "name: phony" among its rules).
if [ -f "$BUILD/build.ninja" ]; then
  known_targets=$(ninja -C "$BUILD" -t targets all | sed -n 's/^\([^:]*\): .*/\1/p')
else
  known_targets=$(cmake --build "$BUILD" --target help | sed -n 's/^\.\.\. //p')
fi
present=()
for t in "${TESTS[@]}"; do
  # An area whose tests do not exist yet is not a failure of the cross build.
  if grep -qx "$t" <<<"$known_targets"; then targets+=("$t"); present+=("$t"); fi
done
step "build ${targets[*]}"
build_t0=$SECONDS
cmake --build "$BUILD" -j "$JOBS" --target "${targets[@]}"
build_s=$((SECONDS - build_t0))

step "check the binaries are arm64"
if [ "$FIGURES" = 1 ]; then
  bin="$BUILD/bin/fleetgw"
else
  bin=$(find "$BUILD/tests" -type f -name "${present[0]}" -perm -u+x | head -1)
fi
kind=$(file -L "$bin")
echo "$kind"
grep -q "ARM aarch64" <<<"$kind" || { echo "not an arm64 binary" >&2; exit 1; }
if [ "$FIGURES" = 1 ]; then
  "$TRIPLE-strip" -o "$BUILD/fleetgw.stripped" "$bin"
  size_bytes=$(stat -c %s "$BUILD/fleetgw.stripped")
  "$QEMU" "$bin" --version
fi

# The emulated test binaries run JOBS at a time (each is single-threaded under qemu); each
# writes its output and its result to files, printed in a fixed order afterwards.
status=0
results=()
run_one() {  # test-name exe
  local start=$SECONDS rc=0
  # FLEETGW_EMULATED: tests skip their wall-clock bounds (an emulated instruction stream on a
  # shared box says nothing about the hardware's latency); every functional check still runs.
  (cd "$(dirname "$2")" && FLEETGW_EMULATED=1 "$QEMU" "$2" --gtest_brief=1) \
    >"$BUILD/$1.emulated.log" 2>&1 || rc=$?
  echo "$rc $((SECONDS - start))" >"$BUILD/$1.result"
}
step "run ${present[*]} under $QEMU, $JOBS at a time"
for t in "${present[@]}"; do
  exe=$(find "$BUILD/tests" -type f -name "$t" -perm -u+x | head -1)
  [ -n "$exe" ] || continue
  rm -f "$BUILD/$t.result"
  while [ "$(jobs -rp | wc -l)" -ge "$JOBS" ]; do wait -n || true; done
  run_one "$t" "$exe" &
done
wait
for t in "${present[@]}"; do
  [ -f "$BUILD/$t.result" ] || continue
  read -r rc took <"$BUILD/$t.result"
  if [ "$rc" = 0 ]; then
    results+=("$t: passed ($took s emulated)")
  else
    cat "$BUILD/$t.emulated.log"
    results+=("$t: FAILED (exit $rc, $BUILD/$t.emulated.log)")
    status=1
  fi
done

if [ "$FIGURES" = 1 ]; then
  step "protocol benchmark under $QEMU"
  bench=$(find "$BUILD/bench" -type f -name bench_protocol -perm -u+x | head -1)
  "$QEMU" "$bench" --benchmark_min_time="$BENCH_MIN_TIME" | tee "$BUILD/bench_protocol.emulated.txt"
fi

{
  echo "== arm64 summary (EMULATED: qemu-aarch64-static user mode on $(uname -m); not arm64 hardware figures)"
  printf '  %s\n' "${results[@]}"
  if [ "$FIGURES" = 1 ]; then
    echo "  fleetgw stripped arm64 binary (release build): $size_bytes bytes ($((size_bytes / 1024)) KiB)"
    echo "  protocol benchmark (emulated): $BUILD/bench_protocol.emulated.txt"
  else
    echo "  (CI build: test binaries only, -O1; ARM64_FIGURES=1 builds the release binary and its size)"
  fi
  echo "  total time: $((SECONDS / 60)) min $((SECONDS % 60)) s (build $build_s s)"
} | tee "$BUILD/summary.txt"
exit "$status"
