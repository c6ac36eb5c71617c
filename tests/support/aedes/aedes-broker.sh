#!/usr/bin/env bash
# Test-side helper: runs aedes (npm; a second MQTT broker implementation, MQTT 3.1.1) on
# 127.0.0.1:PORT in the foreground, its event lines (broker.mjs) on stdout.
#   aedes-broker.sh PORT        exec's node; exit 77 when npm cannot fetch aedes, 2 on usage
#   aedes-broker.sh --install   only makes sure the packages are in the cache (same exit codes)
# The packages (versions pinned in package.json next to this script) are installed with npm on
# first use into a cache directory, $FLEETGW_NPM_CACHE (default ~/.cache/fleetgw/npm/aedes),
# never into the source tree; later runs need no network.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
cache=${FLEETGW_NPM_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/fleetgw/npm/aedes}
arg=${1:?usage: aedes-broker.sh PORT | --install}
if [ "$arg" != --install ] && ! [[ "$arg" =~ ^[0-9]+$ ]]; then
  echo "aedes-broker.sh: PORT must be a number, got '$arg'" >&2
  exit 2
fi
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
  echo "SKIP: node/npm not installed (scripts/install-deps.sh installs them)" >&2
  exit 77
fi
mkdir -p "$cache"
# Installed and matching this package.json: nothing to do. Otherwise (first use, or the pinned
# versions changed) install once, under a lock so parallel tests do not race.
if ! cmp -s "$here/package.json" "$cache/package.json" || [ ! -d "$cache/node_modules/aedes" ]; then
  exec 9>"$cache/.lock"
  flock 9
  if ! cmp -s "$here/package.json" "$cache/package.json" || [ ! -d "$cache/node_modules/aedes" ]; then
    cp "$here/package.json" "$cache/package.json"
    if ! (cd "$cache" && timeout 300 npm install --no-audit --no-fund --loglevel=error \
      --no-package-lock >&2); then
      rm -f "$cache/package.json"  # try again next time
      echo "SKIP: npm could not install aedes (registry unreachable?)" >&2
      exit 77
    fi
  fi
  exec 9>&-
fi
cp "$here/broker.mjs" "$cache/broker.mjs"  # resolved against the cache's node_modules
[ "$arg" = --install ] && exit 0
exec node "$cache/broker.mjs" "$arg"
