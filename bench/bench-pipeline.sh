#!/usr/bin/env bash
# Figures of the event-driven pipeline (issue 12), measured on the shipped binary. Benchmarks,
# not tests. docs/performance.md ("Pipeline") explains each line.
#
#   1. Replay throughput with SQLite: a simulated ride (RIDE_S s of config/scenarios/ride.toml,
#      recorded with `fleetgw sim --record`) replayed as fast as possible: CAN frames per second
#      of CPU (user + sys of the whole process, start-up included).
#   2. Worst case: the ride's frames re-timed to a saturated 250 kbit/s bus (2,200 frames/s, as
#      scripts/bench-runtime.sh does) for WORST_S s, so every value changes far more often per
#      bus-hour than on a real ride, with telemetry sampled every 100 ms while riding (the
#      smallest riding_interval_ms allowed): the store takes >= 60 k records per bus-hour.
#   3. Syscalls per bus-hour of both replays (strace -f -c, a separate run: strace slows it).
#   4. Real time against replay: `fleetgw run` on the simulator at speed 1 for RT_S s (bike
#      simulation included) and the first RT_S s of the ride log replayed at recorded speed,
#      each as CPU per bus-hour, against the replay of the same log as fast as possible.
# Environment: FLEETGW (binary, default build/bin/fleetgw), RIDE_S (1800), RT_S (60),
#   KEEP=1 keeps the work directory.
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=${FLEETGW:-build/bin/fleetgw}
RIDE_S=${RIDE_S:-1800}
RT_S=${RT_S:-60}
WORST_S=${WORST_S:-600}
[[ -x $FLEETGW ]] || { echo "bench-pipeline: no binary $FLEETGW" >&2; exit 1; }
WORK=$(mktemp -d /tmp/fleetgw-pipe-XXXXXX)
if [[ -z ${KEEP:-} ]]; then trap 'rm -rf "$WORK"' EXIT; fi

config() {  # file transport can-section-lines extra-sections...
  local f=$1 transport=$2 can_extra=$3
  shift 3
  {
    printf '[log]\nlevel = "warn"\n[can]\ntransport = "%s"\n%b\n' "$transport" "$can_extra"
    printf '[storage]\npath = "%s/db-%s/fleetgw.db"\n[mqtt]\nenabled = false\n' "$WORK" \
      "$(basename "$f" .toml)"
    for x in "$@"; do printf '%b\n' "$x"; done
  } >"$f"
}

# cpu NAME -- command...: CPU seconds (user + sys) of the command into $CPU.
cpu() {
  local name=$1
  shift 2
  /usr/bin/time -f '%U %S %e' -o "$WORK/$name.time" "$@" >"$WORK/$name.out" 2>"$WORK/$name.err" || {
    echo "bench-pipeline: $name failed" >&2
    tail -20 "$WORK/$name.err" >&2
    exit 1
  }
  CPU=$(awk '{ print $1 + $2 }' "$WORK/$name.time")
  WALL=$(awk '{ print $3 }' "$WORK/$name.time")
}

# syscalls NAME -- command...: total syscalls of the command into $SYSCALLS.
syscalls() {
  local name=$1
  shift 2
  strace -f -c -o "$WORK/$name.strace" "$@" >/dev/null 2>&1
  SYSCALLS=$(awk '$NF == "total" { print $(NF - 2) }' "$WORK/$name.strace")
  WRITES=$(awk '$NF ~ /^(pwrite64|write|fdatasync|fsync)$/ { n += $4 } END { print n + 0 }' \
    "$WORK/$name.strace")
}

echo "fleetgw: $FLEETGW, $(nproc) cores"
"$FLEETGW" sim --scenario config/scenarios/ride.toml --duration "$RIDE_S" --record "$WORK/ride.log" \
  2>/dev/null
FRAMES=$(wc -l <"$WORK/ride.log")

config "$WORK/ride.toml" replay ""
cpu ride -- "$FLEETGW" run --config "$WORK/ride.toml" --replay "$WORK/ride.log"
RIDE_CPU=$CPU
awk -v need="$((WORST_S * 2200))" -v fps=2200 '
  { lines[NR] = $0 }
  END {
    n = 0; t0 = 1717228800
    while (n < need) {
      for (i = 1; i <= NR && n < need; ++i) {
        split(lines[i], f, " ")
        us = int(n * 1000000 / fps)
        printf "(%d.%06d) %s %s\n", t0 + int(us / 1000000), us % 1000000, f[2], f[3]
        ++n
      }
    }
  }' "$WORK/ride.log" >"$WORK/worst.log"
WORST_FRAMES=$(wc -l <"$WORK/worst.log")
config "$WORK/worst.toml" replay "" '[telemetry]\nriding_interval_ms = 100'
cpu worst -- "$FLEETGW" run --config "$WORK/worst.toml" --replay "$WORK/worst.log"
WORST_CPU=$CPU
WORST_RECORDS=$(sqlite3 "$WORK/db-worst/fleetgw.db" "select (select count(*) from telemetry) +
  (select count(*) from fault_events) + (select count(*) from lock_events) +
  (select count(*) from pack_snapshots) + (select count(*) from rides)" 2>/dev/null || echo 0)

rm -rf "$WORK/db-ride" "$WORK/db-worst"
syscalls ride-strace -- "$FLEETGW" run --config "$WORK/ride.toml" --replay "$WORK/ride.log"
RIDE_SYS=$SYSCALLS RIDE_WR=$WRITES
syscalls worst-strace -- "$FLEETGW" run --config "$WORK/worst.toml" --replay "$WORK/worst.log"
WORST_SYS=$SYSCALLS WORST_WR=$WRITES

# Real time: the simulator at speed 1, and the log replayed at recorded speed.
config "$WORK/sim1.toml" sim "" "[sim]\nscenario = \"$(pwd)/config/scenarios/ride.toml\"\nspeed = 1.0"
cpu sim1 -- "$FLEETGW" run --config "$WORK/sim1.toml" --duration "$RT_S"
SIM1_CPU=$CPU
head -n "$(awk -v s="$RT_S" 'NR == 1 { gsub(/[()]/, "", $1); t0 = $1 }
  { gsub(/[()]/, "", $1); if ($1 - t0 > s) { print NR - 1; exit } }' "$WORK/ride.log")" \
  "$WORK/ride.log" >"$WORK/rt.log"
config "$WORK/rt.toml" replay 'replay_speed = 1.0'
cpu rt -- "$FLEETGW" run --config "$WORK/rt.toml" --replay "$WORK/rt.log"
RT_CPU=$CPU
config "$WORK/rtfast.toml" replay ""
cpu rtfast -- "$FLEETGW" run --config "$WORK/rtfast.toml" --replay "$WORK/rt.log"
RTFAST_CPU=$CPU

per_hour() { echo "$1 * 3600 / $2" | bc -l; }
printf '\nride log: %d CAN frames, %d s of bus time\n' "$FRAMES" "$RIDE_S"
printf 'replay, simulated ride:      %8.0f frames/s of CPU (%.2f s CPU)   target >= 2 M/s\n' \
  "$(echo "$FRAMES / $RIDE_CPU" | bc -l)" "$RIDE_CPU"
printf 'replay, worst case:          %8.0f frames/s of CPU (%d frames, %.2f s CPU), %s records = %.0f per bus-hour   target >= 1 M/s\n' \
  "$(echo "$WORST_FRAMES / $WORST_CPU" | bc -l)" "$WORST_FRAMES" "$WORST_CPU" "$WORST_RECORDS" "$(per_hour "$WORST_RECORDS" "$WORST_S")"
printf 'syscalls per bus-hour:       ride %.0f (writes+syncs %.0f), worst case %.0f (writes+syncs %.0f)\n' \
  "$(per_hour "$RIDE_SYS" "$RIDE_S")" "$(per_hour "$RIDE_WR" "$RIDE_S")" \
  "$(per_hour "$WORST_SYS" "$WORST_S")" "$(per_hour "$WORST_WR" "$WORST_S")"
printf 'real time, sim at speed 1:   %.2f s CPU per bus-hour (bike simulation included)\n' \
  "$(per_hour "$SIM1_CPU" "$RT_S")"
printf 'real time, replay at 1x:     %.2f s CPU per bus-hour\n' "$(per_hour "$RT_CPU" "$RT_S")"
printf 'same %d s replayed fast:     %.2f s CPU per bus-hour -> real time / replay = %.2f (target <= 2)\n' \
  "$RT_S" "$(per_hour "$RTFAST_CPU" "$RT_S")" "$(echo "$RT_CPU / $RTFAST_CPU" | bc -l)"
