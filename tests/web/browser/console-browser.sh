#!/usr/bin/env bash
# Test-side helper: runs console_test.mjs (puppeteer-core driving Debian's chromium through the
# console) with the arguments given. puppeteer-core (pinned in package.json next to this script)
# is installed with npm on first use into a cache directory, $FLEETGW_NPM_CACHE_CONSOLE (default
# ~/.cache/fleetgw/npm/console), never into the source tree; later runs need no network.
#   console-browser.sh --install   only makes sure the package is in the cache
# Exit 77 (skip) when node, npm or chromium is missing or npm cannot fetch the package.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
cache=${FLEETGW_NPM_CACHE_CONSOLE:-${XDG_CACHE_HOME:-$HOME/.cache}/fleetgw/npm/console}
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
  echo "SKIP: node/npm not installed (scripts/install-deps.sh installs them)" >&2
  exit 77
fi
if ! command -v chromium >/dev/null; then
  echo "SKIP: chromium not installed (scripts/install-deps.sh installs it)" >&2
  exit 77
fi
mkdir -p "$cache"
if ! cmp -s "$here/package.json" "$cache/package.json" || [ ! -d "$cache/node_modules/puppeteer-core" ]; then
  exec 9>"$cache/.lock"
  flock 9
  if ! cmp -s "$here/package.json" "$cache/package.json" || [ ! -d "$cache/node_modules/puppeteer-core" ]; then
    cp "$here/package.json" "$cache/package.json"
    if ! (cd "$cache" && timeout 300 npm install --no-audit --no-fund --loglevel=error \
      --no-package-lock >&2); then
      rm -f "$cache/package.json"  # try again next time
      echo "SKIP: npm could not install puppeteer-core (registry unreachable?)" >&2
      exit 77
    fi
  fi
  exec 9>&-
fi
cp "$here"/*.mjs "$cache/"  # resolved against the cache's node_modules
[ "${1:-}" = --install ] && exit 0
#   console-browser.sh --script NAME.mjs SPEC   runs another of the scripts here
script=console_test.mjs
if [ "${1:-}" = --script ]; then script=$2; shift 2; fi
exec node "$cache/$script" "$@"
