#!/usr/bin/env bash
# Builds the Debian packages in their own build tree (build-pkg/ unless BUILD_DIR is set)
# configured without tests and benchmarks, so `--target package` builds only what the packages
# ship: the binaries, their manual pages and the changelog. Prints the .debs' paths: fleetgw
# (the IoT node's) and, when libpq is found, fleetgw-ingest (a backend host's).
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
ls -t "$BUILD"/fleetgw-ingest_*.deb 2>/dev/null | head -1 || true
