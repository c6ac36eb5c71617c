#!/usr/bin/env bash
# Installs the Debian 12 packages fleetgw needs to build, test and run its demo.
# Idempotent: packages already installed are skipped, and apt is not touched when none is missing.
# Usage: install-deps.sh [--build | --demo] [--list] [EXTRA_PACKAGE...]   (extras: e.g. the
#   arm64 cross packages, which tests/deploy/arm64-cross.sh --packages lists: installed in the
#   same apt run as the rest).
#   (no set): everything -- building, every test, the demo.
#   --build: only what compiling the x86 trees needs, with gcc and clang (scripts/test.sh installs
#   the rest -- brokers, gpsd, the VM, lintian, chromium, the cross packages -- while they build).
#   --demo: what scripts/demo.sh needs and nothing the tests alone need: the gcc build of
#   fleetgw, mosquitto (the demo's broker, mosquitto_pub), gpsd (the bike's GNSS), python3
#   (the demo's JSON questions), postgresql, libjs-leaflet and curl (its console stage); no
#   clang, VM, lintian, chromium or cross tools.
#   --list: print the set's packages, one a line, and install nothing.
set -euo pipefail

# Compiling fleetgw with gcc (the product, the demo).
GCC_BUILD_PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libpaho-mqttpp-dev libpaho-mqtt-dev libssl-dev openssl
  libprotobuf-dev protobuf-compiler
  libsqlite3-dev sqlite3
  libspdlog-dev libfmt-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libtomlplusplus-dev libcli11-dev nlohmann-json3-dev libasio-dev
  libsystemd-dev libgps-dev help2man
  libpq-dev
  libmosquitto-dev  # fleetgw-fleet-sim: thousands of MQTT 5 sessions on one event loop
  libcpp-httplib-dev libsodium-dev  # fleetgw serve: HTTPS server, Argon2id (docs/console.md)
  zlib1g-dev  # fleetgw serve: the fleet list's gzip copy, made once per build (libprotobuf-dev pulls it in; named so nobody relies on that)
)
# The sanitizer and fuzzing trees of scripts/test.sh.
CLANG_PACKAGES=(clang libclang-rt-14-dev lld)
BUILD_PACKAGES=("${GCC_BUILD_PACKAGES[@]}" "${CLANG_PACKAGES[@]}")
# postgresql, libjs-leaflet, curl: the demo's console stage (fleetgw ingest, fleetgw serve, its API)
DEMO_PACKAGES=(mosquitto mosquitto-clients gpsd python3 postgresql libjs-leaflet curl)
list=0
set_name=all
case "${1:-}" in
  --build | --demo) set_name=${1#--}; shift ;;
esac
if [ "${1:-}" = --list ]; then
  list=1
  shift
fi
case "$set_name" in
  build) PACKAGES=("${BUILD_PACKAGES[@]}" "$@") ;;
  demo) PACKAGES=("${GCC_BUILD_PACKAGES[@]}" "${DEMO_PACKAGES[@]}" "$@") ;;
  *)
    PACKAGES=(
      "${BUILD_PACKAGES[@]}"
      "${DEMO_PACKAGES[@]}"
      can-utils iproute2
      gpsd-clients
      postgresql
      qemu-system-x86 busybox-static cpio xz-utils kmod
      dpkg-dev file systemd adduser lintian
      chromium
      libjs-leaflet  # fleetgw serve: the console's map library, served from /usr/share/javascript
      nodejs  # test-side: aedes, a second MQTT broker (tests/support/aedes, fetched by npm)
      "$@"
    )
    # Debian's npm is its own package; a nodejs from elsewhere (NodeSource) brings npm with it,
    # and Debian's npm would conflict with it.
    command -v npm >/dev/null || PACKAGES+=(npm)
    ;;
esac
if [ "$list" = 1 ]; then
  printf '%s\n' "${PACKAGES[@]}"
  exit 0
fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
if [[ " ${missing[*]}" == *:arm64* ]] && ! dpkg --print-foreign-architectures | grep -qx arm64; then
  $SUDO dpkg --add-architecture arm64
fi
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
