#!/usr/bin/env bash
# Checks the systemd unit: `systemd-analyze verify` must pass without a single warning, and the
# properties the deployment relies on must be present (so deleting one fails the test).
#
# Usage: unit-verify.sh SOURCE_DIR FLEETGW_BINARY
# systemd-analyze resolves ExecStart= and the unit's dependencies, so the check runs against a
# temporary root holding the host's systemd units, our unit and the built binary at
# /usr/bin/fleetgw -- the layout of the installed package -- without touching the real system.
# Exit: 0 pass, 1 fail, 77 skip (systemd-analyze absent).
set -euo pipefail
SRC=$1
BIN=$2
UNIT=$SRC/deploy/systemd/fleetgw.service
NETWORK=$SRC/deploy/systemd/80-can.network

command -v systemd-analyze >/dev/null || { echo "SKIP: systemd-analyze not installed (package systemd)"; exit 77; }
[ -x "$BIN" ] || { echo "no fleetgw binary at $BIN" >&2; exit 1; }

root=$(mktemp -d)
trap 'rm -rf "$root"' EXIT
mkdir -p "$root/usr/bin" "$root/lib/systemd/system" "$root/etc/systemd/system" "$root/tmp"
cp -a /lib/systemd/system/. "$root/lib/systemd/system/"
cp "$UNIT" "$root/lib/systemd/system/fleetgw.service"
cp "$BIN" "$root/usr/bin/fleetgw"

fail=0
out=$(systemd-analyze verify --root="$root" /lib/systemd/system/fleetgw.service 2>&1) || fail=1
# verify exits 0 on many problems (unknown keys, bad values are "ignored"): any output fails.
if [ -n "$out" ]; then
  echo "$out"
  fail=1
fi
[ $fail -eq 0 ] && echo "systemd-analyze verify: clean"

require() {  # file regex why
  if ! grep -Eq "$2" "$1"; then
    echo "FAIL: $(basename "$1") lacks $2 ($3)"
    fail=1
  fi
}
require "$UNIT" '^Type=notify$' "READY=1 once bus and store are open"
require "$UNIT" '^WatchdogSec=[1-9]' "pings from the event loop"
require "$UNIT" '^Restart=on-failure$' "restart a hung or crashed gateway"
require "$UNIT" '^StateDirectory=fleetgw$' "/var/lib/fleetgw for the database"
require "$UNIT" '^RuntimeDirectory=fleetgw$' "/run/fleetgw for the status socket"
require "$UNIT" '^NoNewPrivileges=yes$' "sandbox"
require "$UNIT" '^ProtectSystem=strict$' "sandbox: read-only system"
require "$UNIT" '^PrivateTmp=yes$' "sandbox"
require "$UNIT" '^RestrictAddressFamilies=.*AF_CAN' "SocketCAN must stay allowed"
require "$UNIT" '^RestrictAddressFamilies=.*AF_INET6?( |$)' "MQTT must stay allowed"
require "$UNIT" '^RestrictAddressFamilies=.*AF_UNIX' "sd_notify and the status socket"
require "$UNIT" '^ExecStart=/usr/bin/fleetgw run --config /etc/fleetgw/fleetgw.toml$' "packaged paths"
require "$NETWORK" '^BitRate=250000$' "MOTINOVA bus rate"
require "$NETWORK" '^SamplePoint=87.5%$' "MOTINOVA sample point"

# Exposure score of the sandbox, for the record (lower is better; not a pass/fail criterion).
if score=$(systemd-analyze security --offline=true --root="$root" \
    /lib/systemd/system/fleetgw.service 2>/dev/null | grep -Eo 'exposure level .*' | tail -1); then
  echo "systemd-analyze security: overall $score"
fi
exit $fail
