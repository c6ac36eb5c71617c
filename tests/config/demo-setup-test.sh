#!/usr/bin/env bash
# The demo's first run (scripts/demo.sh without --build-dir), without running it: its build
# progress shows the time since the build started (it showed 0m00s on every line: mawk read
# the build's pipe in blocks), and its packages are the demo's set, not the tests' (it installed
# chromium, qemu, lintian and the cross tools too).
# Usage: demo-setup-test.sh [DEMO_SCRIPT [INSTALL_DEPS_SCRIPT]]   (defaults: the source tree's)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
DEMO=${1:-$ROOT/scripts/demo.sh}
DEPS=${2:-$ROOT/scripts/install-deps.sh}
failures=0
ok() { echo "ok: $1"; }
fail() {
  echo "FAIL: $1" >&2
  failures=$((failures + 1))
}

# A build that takes 2.2 s between its first and its last progress line, as ninja prints them.
progress=$({
  echo "[1/10] Building CXX object a.o"
  echo "some compiler warning"
  sleep 1.1
  echo "[5/10] Building CXX object b.o"
  sleep 1.1
  echo "[10/10] Linking CXX executable fleetgw"
} | "$DEMO" --build-progress) || fail "demo.sh --build-progress failed"
echo "$progress"
mapfile -t elapsed < <(sed -n 's/^   build: *\([0-9]*\) %  (\([0-9]*\)m\([0-9]*\)s)$/\1 \2 \3/p' <<<"$progress")
if [ "${#elapsed[@]}" != 3 ]; then
  fail "expected 3 progress lines (10, 50, 100 %), got ${#elapsed[@]}"
else
  read -r p1 m1 s1 <<<"${elapsed[0]}"
  read -r p3 m3 s3 <<<"${elapsed[2]}"
  [ "$p1" = 10 ] && [ "$p3" = 100 ] && ok "progress 10 % .. 100 %" || fail "progress $p1 .. $p3"
  spent=$(((10#$m3 * 60 + 10#$s3) - (10#$m1 * 60 + 10#$s1)))
  # 2.2 s passed between the first and the last line: whole seconds, at least 2.
  [ "$spent" -ge 2 ] && ok "elapsed time advances ($spent s)" ||
    fail "elapsed time did not advance: $spent s between the first and the last line"
fi

# The demo's packages: what it runs and builds, none of the tests' alone.
demo_set=$("$DEPS" --demo --list) || fail "install-deps.sh --demo --list failed"
for p in build-essential cmake libgps-dev mosquitto mosquitto-clients gpsd python3 \
  postgresql libjs-leaflet curl; do  # the last three: the demo's console stage
  grep -qx "$p" <<<"$demo_set" && ok "demo set has $p" || fail "demo set lacks $p"
done
for p in chromium qemu-system-x86 lintian clang busybox-static nodejs; do
  grep -qx "$p" <<<"$demo_set" && fail "demo set has the tests' $p" || ok "demo set without $p"
done
grep -Eq '^[^#]*install-deps\.sh --demo' "$DEMO" && ok "demo.sh installs the demo set" ||
  fail "demo.sh does not call install-deps.sh --demo"
# scripts/test.sh's two calls keep their sets: --build (gcc and clang) then everything else.
build_set=$("$DEPS" --build --list)
grep -qx clang <<<"$build_set" && ! grep -qx chromium <<<"$build_set" &&
  ok "--build: the compilers, no test programs" || fail "--build set changed"
all_set=$("$DEPS" --list crossbuild-essential-arm64)
for p in chromium lintian qemu-system-x86 mosquitto gpsd clang crossbuild-essential-arm64; do
  grep -qx "$p" <<<"$all_set" || fail "the full set lacks $p"
done

[ "$failures" = 0 ] && echo "demo-setup: all checks passed" || exit 1
