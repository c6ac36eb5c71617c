#!/usr/bin/env bash
# The three replay/decode figures of issue 12 in one run, measured on the shipped binary.
# Benchmarks, not tests: the machine is shared, so each figure is the best of RUNS runs and is
# CPU time (user + sys of the whole process, start-up included, in microseconds:
# bench/cputime.py), not wall time.
#
#   1. Simulated ride: `fleetgw sim --record` writes one hour of config/scenarios/ride.toml
#      (a 30-minute ride, then parked) as a candump -L log; `fleetgw run --replay` plays it as
#      fast as possible into SQLite (MQTT off). Target >= 2 M CAN frames/s of CPU.
#   2. Worst case: one hour of config/scenarios/worst-case.toml (riding the whole hour, every
#      value changing, every lock actuated every 2 s, a fault every 10 s) replayed with telemetry
#      at its fastest (riding_interval_ms = 100): records stored per bus-hour (>= 60 k) and
#      frames/s of CPU (target >= 1 M/s).
#   3. Syscalls per bus-hour of both replays (strace -f -c, a separate run: strace slows it).
#   4. `fleetgw decode LOG > /dev/null` on the ride log. Target >= 2 M frames/s of CPU.
#
# Environment: FLEETGW (binary, default build/bin/fleetgw), RUNS (3), KEEP=1 keeps the
#   work directory.
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=${FLEETGW:-build/bin/fleetgw}
RUNS=${RUNS:-3}
[[ -x $FLEETGW ]] || { echo "replay-bench: no binary $FLEETGW" >&2; exit 1; }
WORK=$(mktemp -d /tmp/fleetgw-replay-XXXXXX)
if [[ -z ${KEEP:-} ]]; then trap 'rm -rf "$WORK"' EXIT; fi

config() {  # name [extra TOML]
  printf '[log]\nlevel = "warn"\n[can]\ntransport = "replay"\n[storage]\npath = "%s/db-%s/fleetgw.db"\n[mqtt]\nenabled = false\n%b\n' \
    "$WORK" "$1" "${2:-}" >"$WORK/$1.toml"
}

# best_cpu NAME -- command...: the smallest user + sys over RUNS runs into $CPU (a fresh store
# each run).
best_cpu() {
  local name=$1
  shift 2
  CPU=""
  for ((i = 0; i < RUNS; i++)); do
    rm -rf "$WORK/db-$name" && mkdir -p "$WORK/db-$name"
    python3 bench/cputime.py "$WORK/$name.time" "$@" >/dev/null 2>"$WORK/$name.err" || {
      echo "replay-bench: $name failed" >&2
      tail -20 "$WORK/$name.err" >&2
      exit 1
    }
    local c
    c=$(awk '{ print $1 + $2 }' "$WORK/$name.time")
    if [[ -z $CPU ]] || awk -v a="$c" -v b="$CPU" 'BEGIN { exit !(a < b) }'; then CPU=$c; fi
  done
}

# syscalls NAME -- command...: total syscalls into $SYSCALLS, writes + syncs into $WRITES.
syscalls() {
  local name=$1
  shift 2
  rm -rf "$WORK/db-$name" && mkdir -p "$WORK/db-$name"
  strace -f -c -o "$WORK/$name.strace" "$@" >/dev/null 2>&1
  SYSCALLS=$(awk '$NF == "total" { print $(NF - 2) }' "$WORK/$name.strace")
  WRITES=$(awk '$NF ~ /^(pwrite64|write|fdatasync|fsync)$/ { n += $4 } END { print n + 0 }' \
    "$WORK/$name.strace")
}

records() {  # db file: every stored record (each also has its outbox entry)
  sqlite3 "$1" "select (select count(*) from telemetry) + (select count(*) from fault_events) +
    (select count(*) from lock_events) + (select count(*) from pack_snapshots) +
    (select count(*) from rides) + (select count(*) from command_results) +
    (select count(*) from alarms) + (select count(*) from zone_events)"
}

echo "fleetgw: $FLEETGW, $(nproc) cores, best of $RUNS runs"
"$FLEETGW" sim --scenario config/scenarios/ride.toml --duration 3600 --record "$WORK/ride.log" \
  >/dev/null 2>&1
"$FLEETGW" sim --scenario config/scenarios/worst-case.toml --duration 3600 \
  --record "$WORK/worst.log" >/dev/null 2>&1
RIDE_FRAMES=$(wc -l <"$WORK/ride.log")
WORST_FRAMES=$(wc -l <"$WORK/worst.log")

config ride
best_cpu ride -- "$FLEETGW" run --config "$WORK/ride.toml" --replay "$WORK/ride.log"
RIDE_CPU=$CPU RIDE_RECORDS=$(records "$WORK/db-ride/fleetgw.db")
config worst '[telemetry]\nriding_interval_ms = 100'
best_cpu worst -- "$FLEETGW" run --config "$WORK/worst.toml" --replay "$WORK/worst.log"
WORST_CPU=$CPU WORST_RECORDS=$(records "$WORK/db-worst/fleetgw.db")

syscalls ride -- "$FLEETGW" run --config "$WORK/ride.toml" --replay "$WORK/ride.log"
RIDE_SYS=$SYSCALLS RIDE_WR=$WRITES
syscalls worst -- "$FLEETGW" run --config "$WORK/worst.toml" --replay "$WORK/worst.log"
WORST_SYS=$SYSCALLS WORST_WR=$WRITES

# decode: 5 runs in a row per timing (one run is ~0.06 s).
DECODE_CPU=""
for ((i = 0; i < RUNS; i++)); do
  python3 bench/cputime.py "$WORK/decode.time" bash -c \
    'for k in 1 2 3 4 5; do "$1" decode "$2" >/dev/null 2>/dev/null || exit 1; done' \
    _ "$FLEETGW" "$WORK/ride.log"
  c=$(awk '{ print ($1 + $2) / 5 }' "$WORK/decode.time")
  if [[ -z $DECODE_CPU ]] || awk -v a="$c" -v b="$DECODE_CPU" 'BEGIN { exit !(a < b) }'; then
    DECODE_CPU=$c
  fi
done

rate() { awk -v f="$1" -v c="$2" 'BEGIN { printf "%.2f M", f / c / 1e6 }'; }
printf '\nride log: %d CAN frames in 1 bus-hour; worst-case log: %d CAN frames in 1 bus-hour\n' \
  "$RIDE_FRAMES" "$WORST_FRAMES"
printf 'replay, simulated ride:  %s frames/s of CPU (%.3f s CPU), %d records, %d syscalls per bus-hour (%d writes+syncs)   target >= 2 M/s\n' \
  "$(rate "$RIDE_FRAMES" "$RIDE_CPU")" "$RIDE_CPU" "$RIDE_RECORDS" "$RIDE_SYS" "$RIDE_WR"
printf 'replay, worst case:      %s frames/s of CPU (%.3f s CPU), %d records per bus-hour, %d syscalls per bus-hour (%d writes+syncs)   target >= 1 M/s, >= 60 k records\n' \
  "$(rate "$WORST_FRAMES" "$WORST_CPU")" "$WORST_CPU" "$WORST_RECORDS" "$WORST_SYS" "$WORST_WR"
printf 'fleetgw decode, ride:    %s frames/s of CPU (%.3f s CPU per run)   target >= 2 M/s\n' \
  "$(rate "$RIDE_FRAMES" "$DECODE_CPU")" "$DECODE_CPU"
