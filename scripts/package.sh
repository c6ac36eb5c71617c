#!/usr/bin/env bash
# Builds the Debian package in its own build tree (build-pkg/ unless BUILD_DIR is set) configured
# without tests and benchmarks, so `--target package` builds only what the package ships: the
# two binaries, their manual pages and the changelog. Prints the .deb's path.
#
# Usage: scripts/package.sh [extra cmake -D options, e.g. a toolchain file for a cross build]
set -euo pipefail
cd "$(dirname "$0")/.."
"$(pwd)/scripts/install-deps.sh"
BUILD=${BUILD_DIR:-build-pkg}
cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFLEETGW_BUILD_TESTS=OFF \
  -DFLEETGW_BUILD_BENCH=OFF "$@" >/dev/null
cmake --build "$BUILD" -j "$(nproc)" --target package >"$BUILD/package.log" 2>&1 ||
  { tail -30 "$BUILD/package.log"; exit 1; }
ls -t "$BUILD"/fleetgw_*.deb | head -1
