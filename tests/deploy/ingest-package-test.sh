#!/usr/bin/env bash
# Builds the Debian packages and checks fleetgw-ingest, the backend host's: its contents and
# dependencies (libpq5 here, and only here), lintian, an install on THIS machine without the
# gateway's package, the installed program, manual page, system user and unit, a run of the
# installed program as its system user with the packaged settings file against a private
# PostgreSQL (it migrates the schema), the conffile across a reinstall, remove and purge.
# Root required: the test really installs. Idempotent: leftovers of an aborted run are purged
# first, and the trap purges again whatever happens.
#
# Usage: ingest-package-test.sh BUILD_DIR
# Exit: 0 pass, 1 fail, 77 skip (not root, or dpkg absent).
set -euo pipefail
BUILD=$(cd "$1" && pwd)

# fail/ok, the skip and the install lock, the package build, lintian: lib-package.sh.
# shellcheck source=tests/deploy/lib-package.sh
. "$(dirname "$0")/lib-package.sh"
begin_package_test

status_of() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null || true; }
purge() {
  local p
  for p in fleetgw-ingest fleetgw; do
    [ -z "$(status_of $p)" ] || dpkg --purge $p >/dev/null 2>&1 || true
  done
}
pg_dir=
cleanup() {
  if [ -n "$pg_dir" ]; then
    runuser -u postgres -- "$pg_bin/pg_ctl" -D "$pg_dir/data" -m immediate -w stop \
      >/dev/null 2>&1 || true
    rm -rf "$pg_dir"
  fi
  purge
}
trap cleanup EXIT
purge

echo "== build the packages"
build_packages "$BUILD"
deb=$(ls -t "$BUILD"/fleetgw-ingest_*.deb 2>/dev/null | head -1)
[ -n "$deb" ] || { echo "FAIL: no fleetgw-ingest_*.deb in $BUILD"; exit 1; }
echo "package: $(basename "$deb") ($(stat -c %s "$deb") bytes)"

echo "== package metadata and contents"
project_version=$(sed -n 's/^CMAKE_PROJECT_VERSION:STATIC=//p' "$BUILD/CMakeCache.txt")
[ "$(dpkg-deb -f "$deb" Package)" = fleetgw-ingest ] && ok "Package: fleetgw-ingest" ||
  fail "Package: $(dpkg-deb -f "$deb" Package)"
[ "$(dpkg-deb -f "$deb" Version)" = "$project_version-1" ] && ok "Version: $project_version-1" ||
  fail "Version $(dpkg-deb -f "$deb" Version), project $project_version"
[ "$(basename "$deb")" = "fleetgw-ingest_${project_version}-1_$(dpkg --print-architecture).deb" ] &&
  ok "file name" || fail "file name $(basename "$deb")"
[ "$(dpkg-deb -f "$deb" Architecture)" = "$(dpkg --print-architecture)" ] ||
  fail "architecture $(dpkg-deb -f "$deb" Architecture)"
contents=$(dpkg-deb -c "$deb")
for f in ./usr/bin/fleetgw-ingest ./usr/bin/fleetgw-fleet-sim \
         ./usr/share/man/man1/fleetgw-fleet-sim.1.gz ./lib/systemd/system/fleetgw-ingest.service \
         ./etc/fleetgw-ingest/ingest.env ./usr/share/man/man1/fleetgw-ingest.1.gz \
         ./usr/share/doc/fleetgw-ingest/copyright ./usr/share/doc/fleetgw-ingest/backend.md \
         ./usr/share/doc/fleetgw-ingest/changelog.Debian.gz; do
  grep -q " $f\$" <<<"$contents" && ok "contains $f" || fail "package lacks $f"
done
# Nothing of the gateway: its binaries, service, configuration.
for f in ./usr/bin/fleetgw ./usr/bin/fleetgw-watch ./lib/systemd/system/fleetgw.service \
         ./etc/fleetgw/fleetgw.toml; do
  grep -q " $f\$" <<<"$contents" && fail "package contains $f (the gateway's)" ||
    ok "does not contain $f"
done
conffiles=$(dpkg-deb --ctrl-tarfile "$deb" | tar -xO ./conffiles)
[ "$conffiles" = /etc/fleetgw-ingest/ingest.env ] && ok "conffile /etc/fleetgw-ingest/ingest.env" ||
  fail "conffiles is \"$conffiles\""
depends=$(dpkg-deb -f "$deb" Depends)
echo "Depends: $depends"
for lib in libpq5 libc6 libstdc++6 libpaho-mqttpp3 libmosquitto1 adduser; do
  grep -q "$lib" <<<"$depends" && ok "depends on $lib" || fail "Depends lacks $lib"
done
grep -qw fleetgw <<<"${depends//fleetgw-ingest/}" && fail "depends on the gateway's package" ||
  ok "does not depend on fleetgw"
check_stripped "$deb" /usr/bin/fleetgw-ingest
check_stripped "$deb" /usr/bin/fleetgw-fleet-sim

echo "== lintian"
check_lintian "$deb"

echo "== install on a backend host (without the gateway's package)"
dpkg -i "$deb" || { fail "dpkg -i failed"; exit 1; }
[[ $(status_of fleetgw-ingest) == *"ok installed" ]] && ok "installed" ||
  fail "dpkg does not list fleetgw-ingest as installed"
[ -z "$(status_of fleetgw)" ] && [ ! -e /usr/bin/fleetgw ] && ok "the gateway is not installed" ||
  fail "installing fleetgw-ingest brought the gateway"
if out=$(/usr/bin/fleetgw-ingest --help 2>&1) && [[ $out == *"--pg"* ]]; then
  ok "/usr/bin/fleetgw-ingest --help"
else
  fail "/usr/bin/fleetgw-ingest --help: $out"
fi
page=/usr/share/man/man1/fleetgw-ingest.1.gz
[ -f $page ] && zgrep -q '^fleetgw\\-ingest \\-' $page && ok "manual page fleetgw-ingest(1)" ||
  fail "no $page, or its NAME is not fleetgw-ingest"
if command -v man >/dev/null; then
  [ "$(man -w fleetgw-ingest 2>&1)" = $page ] && ok "man -w fleetgw-ingest: $page" ||
    fail "man -w fleetgw-ingest: $(man -w fleetgw-ingest 2>&1)"
fi
getent passwd fleetgw-ingest >/dev/null && ok "system user fleetgw-ingest" ||
  fail "no fleetgw-ingest user"
[ "$(stat -c '%U:%G %a' /etc/fleetgw-ingest/ingest.env)" = "root:fleetgw-ingest 640" ] &&
  ok "settings root:fleetgw-ingest 0640" ||
  fail "settings permissions $(stat -c '%U:%G %a' /etc/fleetgw-ingest/ingest.env)"
unit=/lib/systemd/system/fleetgw-ingest.service
if command -v systemd-analyze >/dev/null; then
  out=$(systemd-analyze verify $unit 2>&1) && [ -z "$out" ] && ok "systemd-analyze verify: clean" ||
    fail "systemd-analyze verify $unit: $out"
  score=$(systemd-analyze security --offline=true $unit 2>/dev/null |
    grep -Eo 'exposure level .*' | tail -1 || true)
  echo "systemd-analyze security: overall $score"
fi
for key in '^User=fleetgw-ingest$' '^EnvironmentFile=/etc/fleetgw-ingest/ingest.env$' \
           '^ExecStart=/usr/bin/fleetgw-ingest$' '^ProtectSystem=strict$' '^NoNewPrivileges=yes$' \
           '^RestrictAddressFamilies=AF_UNIX AF_INET AF_INET6$' '^CapabilityBoundingSet=$'; do
  grep -Eq "$key" $unit && ok "unit: $key" || fail "unit lacks $key"
done
[ -e /etc/systemd/system/multi-user.target.wants/fleetgw-ingest.service ] &&
  fail "the unit was enabled by the package" || ok "unit not enabled"

echo "== the installed program, as its user, with the packaged settings file"
# What the unit does (EnvironmentFile=, User=), without systemd: a private PostgreSQL on a Unix
# socket, FLEETGW_INGEST_PG pointed at it in /etc/fleetgw-ingest/ingest.env.
pg_bin=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -1)
if [ -z "$pg_bin" ] || ! getent passwd postgres >/dev/null; then
  fail "PostgreSQL server (postgresql-15) and its postgres user are needed for this step"
else
  pg_dir=$(mktemp -d)
  chmod 0755 "$pg_dir"
  chown postgres: "$pg_dir"
  runuser -u postgres -- "$pg_bin/initdb" -D "$pg_dir/data" -A trust -U fleet >/dev/null
  runuser -u postgres -- "$pg_bin/pg_ctl" -D "$pg_dir/data" -l "$pg_dir/log" -w \
    -o "-k $pg_dir -p 5432 -c listen_addresses=''" start >/dev/null
  conninfo="host=$pg_dir port=5432 user=fleet dbname=postgres"
  sed -i "s|^FLEETGW_INGEST_PG=.*|FLEETGW_INGEST_PG=\"$conninfo\"|" /etc/fleetgw-ingest/ingest.env
  if out=$(set -a && . /etc/fleetgw-ingest/ingest.env && set +a &&
      runuser -u fleetgw-ingest -- /usr/bin/fleetgw-ingest --gaps 2>&1); then
    ok "fleetgw-ingest --gaps as fleetgw-ingest, settings from ingest.env: $(tail -1 <<<"$out")"
  else
    fail "fleetgw-ingest --gaps as fleetgw-ingest: $out"
  fi
  tables=$(runuser -u postgres -- "$pg_bin/psql" -h "$pg_dir" -p 5432 -U fleet -d postgres -Atc \
    "SELECT count(*) FROM pg_tables WHERE tablename IN ('rides','telemetry_samples')" 2>&1 || true)
  [ "$tables" = 2 ] && ok "the installed program migrated the schema" ||
    fail "tables after --gaps: $tables"
fi

echo "== the administrator's settings survive a reinstall (conffile)"
dpkg -i "$deb" >/dev/null || fail "reinstall failed"
grep -q "^FLEETGW_INGEST_PG=\"host=$pg_dir " /etc/fleetgw-ingest/ingest.env && ok "edit kept" ||
  fail "edit lost"

echo "== remove keeps the settings, purge leaves nothing"
dpkg -r fleetgw-ingest >/dev/null || fail "dpkg -r failed"
[ ! -e /usr/bin/fleetgw-ingest ] && ok "binary removed" || fail "binary left after remove"
[ -f /etc/fleetgw-ingest/ingest.env ] && ok "settings kept" || fail "remove deleted the settings"
mkdir -p /etc/fleetgw-ingest/certs && echo "fake key" >/etc/fleetgw-ingest/certs/client.key
dpkg --purge fleetgw-ingest >/dev/null || fail "dpkg --purge failed"
for p in /etc/fleetgw-ingest /usr/bin/fleetgw-ingest $unit $page /usr/share/doc/fleetgw-ingest; do
  [ ! -e "$p" ] && ok "gone: $p" || fail "left after purge: $p"
done
getent passwd fleetgw-ingest >/dev/null && fail "user fleetgw-ingest left" || ok "user removed"
[ -z "$(status_of fleetgw-ingest)" ] && ok "dpkg forgot fleetgw-ingest" ||
  fail "dpkg still knows fleetgw-ingest"

echo "== $failures failure(s), $SECONDS s"
[ "$failures" -eq 0 ]
