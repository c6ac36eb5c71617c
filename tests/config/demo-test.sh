#!/usr/bin/env bash
# demo.story: runs scripts/demo.sh on an already built tree (--build-dir: no packages, no build)
# with a real mosquitto, and checks that the story was told: each step's line as it happened and
# the summary sentence naming the ride, the fault, the succeeded unlock, the interlock refusal
# and the theft alarm; the route through gpsd, the slow zone applied and lifted (back to the
# operator's cap, not the bike's own limit) and the ride's GNSS track; then the fleet's side:
# the ingest subscribed before the bike published, and the console (fleetgw serve) shows the
# demo bike at its position in Ljubljana with its theft alarm, through its API after a login.
#   demo-test.sh BUILD_DIR OUT_DIR       exit 0 pass, 1 fail, 77 skipped (no mosquitto)
set -uo pipefail
build=${1:?usage: demo-test.sh BUILD_DIR OUT_DIR}
out=${2:?usage: demo-test.sh BUILD_DIR OUT_DIR}
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
if ! command -v mosquitto >/dev/null && [ ! -x /usr/sbin/mosquitto ]; then
  echo "SKIP: mosquitto is not installed"
  exit 77
fi
rm -rf "$out"  # the test's own directory: a fresh demo every run
mkdir -p "$out"
log=$out.log
start=$(date +%s)
"$root/scripts/demo.sh" --build-dir "$build" --out "$out" > "$log" 2>&1
rc=$?
took=$(($(date +%s) - start))
cat "$log"
echo "== demo.sh exit $rc after $took s"
failures=0
check() {  # check WHAT PATTERN FILE
  if grep -qE -- "$2" "$3"; then
    echo "ok: $1"
  else
    echo "FAIL: $1 (no line matching /$2/ in $3)"
    failures=$((failures + 1))
  fi
}
[ "$rc" = 0 ] || { echo "FAIL: demo.sh exited $rc"; failures=$((failures + 1)); }
check "unlock succeeded" '^  \[ *[0-9]+ s\] remote unlock \(frame lock\): succeeded in [0-9.]+ s$' "$log"
check "lock refused while riding" \
  '^  \[ *[0-9]+ s\] remote lock \(frame lock\) at [0-9.]+ km/h: refused \(interlock_moving\)' "$log"
check "lock succeeded when parked" '^  \[ *[0-9]+ s\] remote lock \(frame lock\): succeeded' "$log"
check "speed limit confirmed by the MC" \
  '^  \[ *[0-9]+ s\] remote speed limit 15 km/h: succeeded, the MC reads back 15 km/h' "$log"
check "the bike rides under the cap" 'status: the bike rides at [0-9.]+ km/h, under the 15 km/h cap' "$log"
check "GNSS fix through gpsd and the zone bundle in force" \
  'GNSS: fix at 46\.05[0-9]+,14\.50[0-9]+ through gpsd; zones: bundle v1 from fleet/v1/zones accepted' "$log"
check "slow zone entered" "zone: entered slow zone 'Old Town' at 46\.06[0-9]+,14\.5[234][0-9]+: the limit ramps down to 10 km/h" "$log"
check "the bike rides under the zone's limit" \
  'status: the bike rides at [0-9.]+ km/h in the slow zone, the MC.s limit is 10 km/h' "$log"
check "slow zone left, the operator's cap restored" \
  "zone: left 'Old Town' at [0-9.]+,[0-9.]+: the MC's limit is back to 15 km/h" "$log"
check "the ride's GNSS track" 'ride: GNSS track of [0-9]+ points, [3-9]\.[0-9]+ km' "$log"
check "fault raised" 'fault: mc over_heat_protect raised' "$log"
check "fault cleared" 'fault: mc over_heat_protect cleared' "$log"
check "status shows the open ride" 'status: [0-9.]+ km/h, SOC [0-9.]+ %, open ride [0-9.]+ km' "$log"
check "ride reached the broker" 'ride: ended by the lock and reached the broker: [0-9.]+ km' "$log"
check "theft alarm" 'theft alarm: .*unauthorised_movement raised' "$log"
# The summary sentence: one ride of several km, two faults raised and cleared, the four
# commands (unlock, speed limit and lock succeeded, the interlock refusal), the theft.
summary=$out/summary.txt
check "summary: the ride" '^1 ride, [3-9]\.[0-9] km, [0-9]+ min; ' "$summary"
check "GNSS fault until the first fix" 'fault: iot gps \(warning\) raised until the first fix, now cleared' "$log"
check "summary: the faults (GNSS until the first fix, the over-heat)" \
  '; 2 faults raised, 2 cleared; ' "$summary"
check "summary: which faults" ' 1 iot:gps, 1 mc:over_heat_protect; 2 cleared' "$summary"
check "summary: the commands" \
  '; 4 commands: 3 succeeded, 1 refused \(interlock_moving\); ' "$summary"
check "summary: the alarm" '; 1 alarm \(theft\)$' "$summary"
check "the ingest subscribed before the bike started" \
  '^  \[ *[0-9]+ s\] backend: PostgreSQL up, fleetgw ingest subscribed to the broker$' "$log"
check "console: up, the operator logged in" \
  '^  \[ *[0-9]+ s\] console: up at http://127\.0\.0\.1:[0-9]+, operator demo logged in' "$log"
check "console: the demo bike at its position" \
  'console: the demo bike demo-bike-01 at 46\.0[0-9]+,14\.5[0-9]+ \(/api/fleet\); vehicles in the fleet: 1$' "$log"
check "console: the theft alarm in the alarm feed" \
  'console: its theft alarm in the alarm feed \(/api/alarms\): unauthorised_movement raised then cleared' "$log"
check "console: URL and credentials printed" \
  'the operator console: +http://127\.0\.0\.1:[0-9]+ +user demo, password [A-Za-z0-9_-]{8,}$' "$log"
# How long the story took is a figure, not a verdict: on a quiet machine about a minute (the
# simulator at 40x), longer beside a CPU burner, where the story must still be right (the checks
# above). ctest's TIMEOUT ends a hung demo.
echo "== the story took $took s (about 60 s on a quiet machine)"
echo "== $failures failure(s)"
[ "$failures" -eq 0 ]
