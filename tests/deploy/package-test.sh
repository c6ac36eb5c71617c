#!/usr/bin/env bash
# Builds the Debian packages, checks the gateway's (fleetgw; fleetgw-ingest has
# ingest-package-test.sh), installs it on THIS machine with dpkg, checks what it installed and
# that it started nothing, checks that a technician's config edit survives a reinstall (conffile),
# removes it (data and config stay), purges it (nothing stays). Root required: the test really
# installs, as issue 7 asks. Idempotent: a leftover fleetgw package from an aborted run is purged
# first, and the trap purges again whatever happens.
#
# Usage: package-test.sh BUILD_DIR
# Exit: 0 pass, 1 fail, 77 skip (not root, or dpkg absent).
set -euo pipefail
BUILD=$(cd "$1" && pwd)

# fail/ok, the skip and the install lock, the package build, lintian: lib-package.sh.
# shellcheck source=tests/deploy/lib-package.sh
. "$(dirname "$0")/lib-package.sh"
begin_package_test

installed() { dpkg-query -W -f='${Status}' fleetgw 2>/dev/null | grep -q "ok installed"; }
known() { dpkg-query -W -f='${Status}' fleetgw >/dev/null 2>&1; }
purge() { if known; then dpkg --purge fleetgw >/dev/null 2>&1 || true; fi; }
# fleetgw processes started from the installed binary (other fleetgw builds may run here).
running_installed() {
  local p
  for p in /proc/[0-9]*; do
    [ "$(readlink "$p/exe" 2>/dev/null)" = /usr/bin/fleetgw ] && return 0
  done
  return 1
}

trap purge EXIT
purge

echo "== build the package"
build_packages "$BUILD"
deb=$(ls -t "$BUILD"/fleetgw_*.deb | head -1)
echo "package: $(basename "$deb") ($(stat -c %s "$deb") bytes)"

echo "== package contents"
contents=$(dpkg-deb -c "$deb")
for f in ./usr/bin/fleetgw ./usr/bin/fleetgw-watch ./etc/fleetgw/fleetgw.toml ./lib/systemd/system/fleetgw.service \
         ./usr/libexec/fleetgw/fleetgw-can-setup ./usr/share/doc/fleetgw/deployment.md \
         ./usr/share/doc/fleetgw/examples/80-can.network ./usr/share/doc/fleetgw/copyright \
         ./usr/share/doc/fleetgw/changelog.Debian.gz ./usr/share/man/man1/fleetgw.1.gz \
         ./usr/share/man/man1/fleetgw-run.1.gz ./usr/share/man/man1/fleetgw-watch.1.gz \
         ./usr/share/bash-completion/completions/fleetgw; do
  grep -q " $f\$" <<<"$contents" && ok "contains $f" || fail "package lacks $f"
done
# The backend consumer is package fleetgw-ingest (ingest-package-test.sh): nothing of it here.
grep -q "fleetgw-ingest" <<<"$contents" && fail "package contains fleetgw-ingest files" ||
  ok "no fleetgw-ingest files"
# A manual page for every subcommand `fleetgw --help` lists (fleetgw-ingest's, fleetgw-serve's and
# fleetgw-fleet-sim's are in package fleetgw-ingest, with their programs).
subcommands=$("$BUILD/bin/fleetgw" --help |
  sed -n '/^Subcommands:/,/^$/s/^  \([a-z][a-z0-9-]*\).*/\1/p')
[ -n "$subcommands" ] || fail "no subcommands in fleetgw --help"
for sub in $subcommands; do
  case $sub in ingest | fleet-sim | serve) continue ;; esac
  grep -q " ./usr/share/man/man1/fleetgw-$sub.1.gz\$" <<<"$contents" &&
    ok "manual page fleetgw-$sub(1)" || fail "no manual page for fleetgw $sub"
done
conffiles=$(dpkg-deb --ctrl-tarfile "$deb" | tar -xO ./conffiles)
[ "$conffiles" = /etc/fleetgw/fleetgw.toml ] && ok "conffile /etc/fleetgw/fleetgw.toml" ||
  fail "conffiles is \"$conffiles\""
depends=$(dpkg-deb -f "$deb" Depends)
echo "Depends: $depends"
# dpkg-shlibdeps must have found the real runtime libraries, not left only the manual ones.
for lib in libc6 libstdc++6 libpaho-mqttpp3 adduser; do
  grep -q "$lib" <<<"$depends" && ok "depends on $lib" || fail "Depends lacks $lib"
done
# libgps is loaded at run time ([gnss]), so dpkg-shlibdeps cannot see it: declared by hand.
grep -Eq "(^|, )libgps[0-9]+" <<<"$depends" && ok "depends on libgps (loaded at run time)" ||
  fail "Depends lacks libgps"
# A bike never installs PostgreSQL's client library.
grep -q libpq <<<"$depends" && fail "depends on libpq" || ok "no libpq dependency"
# protobuf and SQLite are linked statically (FLEETGW_STATIC_DEPS, the default: resident memory).
static_deps=$(grep -s "^FLEETGW_STATIC_DEPS:" "$BUILD/CMakeCache.txt" | cut -d= -f2 || true)
for lib in libsqlite3-0 libprotobuf32; do
  if [ "$static_deps" = OFF ]; then
    grep -q "$lib" <<<"$depends" && ok "depends on $lib" || fail "Depends lacks $lib"
  else
    grep -q "$lib" <<<"$depends" && fail "depends on $lib, linked statically" ||
      ok "no $lib dependency (linked statically)"
  fi
done
[ "$(dpkg-deb -f "$deb" Architecture)" = "$(dpkg --print-architecture)" ] ||
  fail "architecture $(dpkg-deb -f "$deb" Architecture)"
check_stripped "$deb" /usr/bin/fleetgw

echo "== lintian"
check_lintian "$deb"

echo "== install"
dpkg -i "$deb" || { fail "dpkg -i failed"; exit 1; }
installed && ok "installed" || fail "dpkg does not list fleetgw as installed"
[ -x /usr/bin/fleetgw ] && ok "/usr/bin/fleetgw" || fail "no /usr/bin/fleetgw"
[ -f /lib/systemd/system/fleetgw.service ] && ok "unit" || fail "no unit"
dpkg-query -W -f='${Conffiles}\n' fleetgw | grep -q "/etc/fleetgw/fleetgw.toml" &&
  ok "dpkg tracks the conffile" || fail "conffile not registered"
getent passwd fleetgw >/dev/null && ok "system user fleetgw" || fail "no fleetgw user"
[ "$(stat -c '%U:%G %a' /var/lib/fleetgw 2>/dev/null)" = "fleetgw:fleetgw 750" ] &&
  ok "/var/lib/fleetgw fleetgw:fleetgw 0750" || fail "/var/lib/fleetgw: $(stat -c '%U:%G %a' /var/lib/fleetgw 2>&1)"
[ "$(stat -c '%U:%G %a' /etc/fleetgw/fleetgw.toml)" = "root:fleetgw 640" ] &&
  ok "config root:fleetgw 0640" || fail "config permissions $(stat -c '%U:%G %a' /etc/fleetgw/fleetgw.toml)"

# `fleetgw watch` runs the installed fleetgw-watch: no broker here, so it must say it could not
# subscribe (its own message), not that the helper is missing.
out=$(/usr/bin/fleetgw watch --broker tcp://127.0.0.1:1 --duration 1 2>&1 || true)
[[ $out == *"cannot subscribe"* ]] && ok "fleetgw watch runs /usr/bin/fleetgw-watch" ||
  fail "fleetgw watch: $out"

[ -f /usr/share/man/man1/fleetgw-run.1.gz ] && ok "manual page fleetgw-run(1) installed" ||
  fail "no /usr/share/man/man1/fleetgw-run.1.gz"
# The installed completion is the installed binary's own (generated at build time from the
# same definitions), and bash takes it: `fleetgw dec<TAB>` completes to decode.
completion=/usr/share/bash-completion/completions/fleetgw
if [ -f "$completion" ] && cmp -s "$completion" <(/usr/bin/fleetgw completion bash); then
  ok "bash completion installed, the binary's own"
else
  fail "$completion missing or not what /usr/bin/fleetgw completion bash prints"
fi
words=$(bash -c 'source "$1" && COMP_WORDS=(fleetgw dec) COMP_CWORD=1 && _fleetgw &&
  echo "${COMPREPLY[*]}"' _ "$completion" 2>&1 || true)
[ "$words" = decode ] && ok "bash completion: fleetgw dec<TAB> -> decode" ||
  fail "bash completion of 'fleetgw dec': \"$words\""
version=$(/usr/bin/fleetgw --version)
pkg_version=$(dpkg-query -W -f='${Version}' fleetgw)
[ "$version" = "fleetgw ${pkg_version%-*}" ] && ok "--version: $version" ||
  fail "--version says \"$version\", package is $pkg_version"
if out=$(/usr/bin/fleetgw check-config /etc/fleetgw/fleetgw.toml 2>&1); then
  ok "check-config: $out"
else
  fail "check-config of the packaged config: $out"
fi
# Nothing started: no process runs the installed binary, the unit is not enabled.
sleep 0.5
running_installed && fail "a fleetgw process runs from /usr/bin/fleetgw" || ok "nothing started"
[ -e /etc/systemd/system/multi-user.target.wants/fleetgw.service ] &&
  fail "the unit was enabled by the package" || ok "unit not enabled"

echo "== a technician's edit survives a reinstall (conffile)"
sed -i 's/^id = .*/id = "bike-test-4711"/' /etc/fleetgw/fleetgw.toml
dpkg -i "$deb" >/dev/null || fail "reinstall failed"
grep -q '^id = "bike-test-4711"' /etc/fleetgw/fleetgw.toml && ok "edit kept" || fail "edit lost"

echo "== remove keeps data and configuration"
echo "fake db" >/var/lib/fleetgw/fleetgw.db
mkdir -p /etc/fleetgw/certs && echo "fake key" >/etc/fleetgw/certs/client.key
dpkg -r fleetgw >/dev/null || fail "dpkg -r failed"
[ ! -e /usr/bin/fleetgw ] && ok "binary removed" || fail "binary left after remove"
[ -f /var/lib/fleetgw/fleetgw.db ] && [ -f /etc/fleetgw/fleetgw.toml ] &&
  ok "data and config kept" || fail "remove deleted data or config"

echo "== purge leaves nothing"
dpkg --purge fleetgw >/dev/null || fail "dpkg --purge failed"
for p in /etc/fleetgw /var/lib/fleetgw /usr/bin/fleetgw /lib/systemd/system/fleetgw.service \
         /usr/libexec/fleetgw /usr/share/doc/fleetgw \
         /usr/share/bash-completion/completions/fleetgw; do
  [ ! -e "$p" ] && ok "gone: $p" || fail "left after purge: $p"
done
getent passwd fleetgw >/dev/null && fail "user fleetgw left" || ok "user removed"
known && fail "dpkg still knows fleetgw" || ok "dpkg forgot fleetgw"

echo "== $failures failure(s), $SECONDS s"
[ "$failures" -eq 0 ]
