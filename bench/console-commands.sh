#!/usr/bin/env bash
# Issue 28's click-to-result figure: an operator clicks unlock/lock N times on a vehicle page in
# Debian's chromium (puppeteer-core), through fleetgw-serve -> mosquitto -> a real `fleetgw run`
# on a simulated bike (parked scenario, real time) -> the simulated locks -> back, and the time
# from the click to `succeeded` on screen is taken for each. Runs the browser test
# web.WebBrowser.OperatorLocksARealBikeWithAClickAndAViewerCannot with FLEETGW_CONSOLE_CLICKS=N
# and prints p50/p90/p99/max over the clicks (whole-vehicle unlock and lock alternate; every
# click must succeed or the test fails).
#   bench/console-commands.sh [BUILD_DIR] [N]      (defaults: build, 100)
set -euo pipefail
build=${1:-build}
n=${2:-100}
bin="$build/tests/web/web_tests"
[ -x "$bin" ] || { echo "no $bin: build the web_tests target first" >&2; exit 2; }
log=$(mktemp)
trap 'rm -f "$log"' EXIT
FLEETGW_CONSOLE_CLICKS=$n "$bin" \
  --gtest_filter='WebBrowser.OperatorLocksARealBikeWithAClickAndAViewerCannot' >"$log" 2>&1 || {
  cat "$log" >&2
  exit 1
}
python3 - "$log" "$n" <<'PY'
import json, sys
line = json.loads(next(l for l in open(sys.argv[1]) if l.startswith('{"click_to_result_ms"')))
def pct(t, p):
    return t[min(len(t) - 1, max(0, int(round(p / 100 * len(t) + 0.5)) - 1))]
def show(name, values):
    t = sorted(values)
    print(f'{name}: p50 {pct(t, 50)} ms, p90 {pct(t, 90)} ms, p99 {pct(t, 99)} ms, '
          f'max {t[-1]} ms, min {t[0]} ms')
clicks, bike = line['click_to_result_ms'], line['bike_duration_ms']
print(f'{len(clicks)} clicks (whole-vehicle unlock/lock alternating)')
show('click to "succeeded" on screen', clicks)
show('the bike\'s own time (receipt to result)', bike)
show('the rest (browser, fleetgw serve, broker, both ways)', [c - b for c, b in zip(clicks, bike)])
PY
