#!/usr/bin/env bash
# `fleetgw decode` throughput (issue 12: >= 2 M CAN frames/s of CPU on a 1-hour log).
#
#   1. `fleetgw sim --record` writes RIDE_S (default 3600) seconds of config/scenarios/ride.toml
#      as a candump -L log (kept in the work directory between runs unless FRESH=1).
#   2. `fleetgw decode LOG > /dev/null`, REPEAT times in a row (default 5: one run takes ~0.2 s,
#      and /usr/bin/time counts in 10 ms steps), is timed RUNS times (default 3); the figure is
#      CAN frames / (user + sys) seconds of the best run, i.e. CPU time, not wall time.
#   3. The JSON output of one run is checked: one valid JSON object per line (python3 -m json
#      would be slow on millions of lines, so a sample of 2,000 lines is parsed).
#
# Environment: BUILD_DIR (default build-bench-decode, RelWithDebInfo like the package), FLEETGW (binary; overrides
#   BUILD_DIR), RIDE_S (3600), RUNS (3), REPEAT (5), WORK (default /tmp/fleetgw-bench-decode), FRESH=1.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
RIDE_S=${RIDE_S:-3600}
RUNS=${RUNS:-3}
REPEAT=${REPEAT:-5}
WORK=${WORK:-/tmp/fleetgw-bench-decode}

if [[ -z ${FLEETGW:-} ]]; then
  BUILD_DIR=${BUILD_DIR:-build-bench-decode}
  if [[ ! -f $BUILD_DIR/CMakeCache.txt ]]; then
    cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFLEETGW_BUILD_TESTS=OFF \
      -DFLEETGW_BUILD_BENCH=OFF >/dev/null
  fi
  cmake --build "$BUILD_DIR" --target fleetgw -j "$(nproc)" >/dev/null
  FLEETGW=$(find "$BUILD_DIR" -type f -name fleetgw -perm -u+x | head -1)
fi
[[ -x $FLEETGW ]] || { echo "decode-bench: no fleetgw binary" >&2; exit 1; }

mkdir -p "$WORK"
LOG=$WORK/ride-${RIDE_S}s.log
if [[ ! -s $LOG || ${FRESH:-0} == 1 ]]; then
  echo "recording ${RIDE_S} s of config/scenarios/ride.toml ..."
  "$FLEETGW" sim --scenario "$ROOT/config/scenarios/ride.toml" --duration "$RIDE_S" \
    --record "$LOG" >/dev/null 2>&1
fi
FRAMES=$(wc -l < "$LOG")
echo "log: $LOG, $FRAMES CAN frames, $(du -h "$LOG" | cut -f1)"

best=""
for ((i = 1; i <= RUNS; i++)); do
  /usr/bin/time -f "%U %S" -o "$WORK/time" bash -c \
    'for ((k = 0; k < $3; k++)); do "$1" decode "$2" >/dev/null 2>"$4" || exit 1; done' \
    _ "$FLEETGW" "$LOG" "$REPEAT" "$WORK/err" || {
    cat "$WORK/err" >&2
    exit 1
  }
  read -r user sys < "$WORK/time"
  rate=$(awk -v f="$((FRAMES * REPEAT))" -v u="$user" -v s="$sys" 'BEGIN { printf "%.0f", f / (u + s) }')
  awk -v i="$i" -v u="$user" -v s="$sys" -v r="$rate" \
    'BEGIN { printf "run %d: user %.2f s, sys %.2f s -> %.2f M frames/s of CPU\n", i, u, s, r / 1e6 }'
  if [[ -z $best ]] || ((rate > best)); then best=$rate; fi
done
tail -1 "$WORK/err"

"$FLEETGW" decode "$LOG" 2>/dev/null | awk 'NR % 500 == 1' | head -2000 |
  /usr/bin/python3 -c 'import json, sys
n = 0
for line in sys.stdin:
    json.loads(line); n += 1
print(f"output check: {n} sampled lines parse as JSON")'

awk -v r="$best" -v n="$RUNS" \
  'BEGIN { printf "fleetgw decode: %.2f M CAN frames/s of CPU (best of %d runs)\n", r / 1e6, n }'
