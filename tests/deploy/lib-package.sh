# shellcheck shell=bash
# Shared steps of the package tests (package-test.sh: fleetgw, ingest-package-test.sh:
# fleetgw-ingest), sourced by both so that each check exists once.
#
# Contract (the caller runs under `set -euo pipefail`):
#  * fail MSG / ok MSG print one result line; fail counts into $failures (starts at 0 here).
#  * begin_package_test exits 77 (ctest's skip) when not root or not a dpkg system, then takes
#    /var/lock/fleetgw-package-test.lock on fd 9 (held until the shell exits), so two builds'
#    runs never install at the same time (exit 1 after 600 s), and starts $SECONDS at 0.
#  * build_packages BUILD removes old .deb files and builds the `package` target; on failure it
#    prints the build log's tail and exits 1.
#  * check_stripped DEB PATH: the program PATH inside DEB (e.g. /usr/bin/fleetgw) is stripped.
#  * check_lintian DEB: Debian's own checker reports no error and no warning but
#    initial-upload-closes-no-bugs (the first changelog entry closes no ITP bug); every other
#    tag fails. The report is printed for the record. lintian missing is a failure, not a skip.

failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
ok() { echo "ok: $*"; }

begin_package_test() {
  [ "$(id -u)" -eq 0 ] || { echo "SKIP: must run as root (it installs the package)"; exit 77; }
  command -v dpkg >/dev/null || { echo "SKIP: not a dpkg system"; exit 77; }
  exec 9>/var/lock/fleetgw-package-test.lock
  flock -w 600 9 || { echo "FAIL: another package test holds the lock" >&2; exit 1; }
  SECONDS=0
}

build_packages() {
  local build=$1
  rm -f "$build"/fleetgw_*.deb "$build"/fleetgw-ingest_*.deb
  cmake --build "$build" --target package >"$build/package-build.log" 2>&1 ||
    { tail -30 "$build/package-build.log"; exit 1; }
}

check_stripped() {
  local deb=$1 path=$2 unpacked kind
  unpacked=$(mktemp -d)
  dpkg-deb -x "$deb" "$unpacked"
  kind=$(file -b "$unpacked$path")
  rm -rf "$unpacked"
  [[ $kind == *", stripped"* ]] && ok "binary is stripped" || fail "binary: $kind"
}

check_lintian() {
  local deb=$1 report
  if ! command -v lintian >/dev/null; then
    fail "lintian is not installed (scripts/install-deps.sh installs it)"
    return 0
  fi
  if report=$(lintian --fail-on error,warning --suppress-tags initial-upload-closes-no-bugs \
      "$deb" 2>&1); then
    ok "lintian: no errors, no new warnings"
  else
    fail "lintian reports errors or warnings"
  fi
  # Written so that an empty report still returns 0 (the caller runs under set -e).
  [ -z "$report" ] || sed 's/^/  lintian: /' <<<"$report"
}
