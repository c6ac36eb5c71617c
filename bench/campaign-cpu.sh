#!/usr/bin/env bash
# Issue 29's figure: CPU per bus-hour of the worst-case log replayed by `fleetgw run` with 10
# campaigns in force against none (target <= 1.2x). A benchmark, not a test: the machine is
# shared, so each figure is the best of RUNS runs of CPU time (user + sys of the whole process,
# start-up included: bench/cputime.py), not wall time; both configurations run side by side.
#
# The 10 campaigns are among the most expensive the rules accept together (their bytes an hour
# under the 256 MiB cap) on the busiest messages: 16 signals each (cell voltages, MC running
# data, BMS status) every 100 ms, three of them window campaigns around an over-temperature
# condition with a 10 s ring, four on_change in an all-day time window, three always. Without
# MQTT nothing is acknowledged: once a campaign's 6 MiB disk budget is full its samples are
# dropped (counted), as on a bike offline for long. They are signed with a fresh key (`fleetgw keygen`, `fleetgw campaign sign`) and stored
# in the store's meta table as the gateway stores accepted ones, so the replay (MQTT off) restores
# and runs them from its first frame.
#
# Environment: FLEETGW (binary, default build/bin/fleetgw), RUNS (3), KEEP=1 keeps the
#   work directory.
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=${FLEETGW:-build/bin/fleetgw}
RUNS=${RUNS:-3}
[[ -x $FLEETGW ]] || { echo "campaign-cpu: no binary $FLEETGW" >&2; exit 1; }
WORK=$(mktemp -d /tmp/fleetgw-campaign-XXXXXX)
if [[ -z ${KEEP:-} ]]; then trap 'rm -rf "$WORK"' EXIT; fi

"$FLEETGW" keygen "$WORK/eng" >"$WORK/keygen.out"
KEY_LINE=$(grep -o 'eng = "[^"]*"' "$WORK/keygen.out")
"$FLEETGW" sim --scenario config/scenarios/worst-case.toml --duration 3600 \
  --record "$WORK/worst.log" >/dev/null 2>&1
FRAMES=$(wc -l <"$WORK/worst.log")

config() {  # name [extra TOML]
  printf '[log]\nlevel = "warn"\n[can]\ntransport = "replay"\n[storage]\npath = "%s/db-%s/fleetgw.db"\n[mqtt]\nenabled = false\n[telemetry]\nriding_interval_ms = 100\n[command.trusted_keys]\n%s\n' \
    "$WORK" "$1" "$KEY_LINE" >"$WORK/$1.toml"
}
config none
config ten

# Ten campaigns, valid for the log's bus time (the simulator records from a fixed epoch; the
# gateway judges a campaign's start and end on the bus's clock).
now_us=$(head -1 "$WORK/worst.log" | sed 's/^(\([0-9]*\)\..*/\1/')000000
cells='"bms.cells.cells_mv[0]"'
for i in $(seq 1 15); do cells="$cells, \"bms.cells.cells_mv[$i]\""; done
mc='"mc.status.speed_kmh", "mc.status.motor_rpm", "mc.status.power_w", "mc.status.voltage_v",
  "mc.status.current_a", "mc.status.cadence_rpm", "mc.status.torque_nm", "mc.status.soc_pct",
  "mc.status.motor_temp_c", "mc.status.mcu_temp_c", "mc.status.pcb_temp_c", "mc.status.odo_km",
  "bms.status.voltage_v", "bms.status.current_a", "bms.status.temp_c", "bms.status.soc_pct"'
INDEX=""
for i in $(seq 1 10); do
  signals=$cells
  ((i % 2 == 0)) && signals=$mc
  case $((i % 3)) in
    0) trigger='kind = "always"'; sampling='kind = "every"' ;;
    1) trigger='kind = "time_window"
day_start_s = 0
day_end_s = 86400'; sampling='kind = "on_change"' ;;
    *) trigger='kind = "condition"
condition = { kind = "above", signal = "mc.status.motor_temp_c", threshold = 50, hysteresis = 2 }'
       sampling='kind = "window"
before_ms = 10000
after_ms = 10000' ;;
  esac
  cat >"$WORK/c$i.toml" <<EOF
id = "bench-$i"
version = 1
signals = [$signals]
disk_budget_bytes = 6291456
start_us = $((now_us - 86400000000))
end_us = $((now_us + 30 * 86400000000))
[trigger]
$trigger
[sampling]
$sampling
period_ms = 100
[target]
all_vehicles = true
EOF
  "$FLEETGW" campaign sign "$WORK/c$i.toml" --key "$WORK/eng.pem" --out "$WORK/c$i.signed" \
    >>"$WORK/sign.out"
  INDEX="$INDEX bench-$i"
done

# A store with the ten campaigns in its meta table, as the gateway keeps accepted ones.
prepare() {  # name
  rm -rf "$WORK/db-$1" && mkdir -p "$WORK/db-$1"
  head -1 "$WORK/worst.log" >"$WORK/one.log"
  "$FLEETGW" run --config "$WORK/$1.toml" --replay "$WORK/one.log" >/dev/null 2>&1
  if [[ $1 == ten ]]; then
    for i in $(seq 1 10); do
      sqlite3 "$WORK/db-ten/fleetgw.db" "INSERT OR REPLACE INTO meta VALUES ('campaign.bench-$i', '$(base64 -w0 "$WORK/c$i.signed")')"
    done
    sqlite3 "$WORK/db-ten/fleetgw.db" "INSERT OR REPLACE INTO meta VALUES ('campaign.index', '${INDEX# }')"
  fi
}

best_cpu() {  # name
  CPU=""
  for ((r = 0; r < RUNS; r++)); do
    prepare "$1"
    python3 bench/cputime.py "$WORK/$1.time" "$FLEETGW" run --config "$WORK/$1.toml" \
      --replay "$WORK/worst.log" >/dev/null 2>"$WORK/$1.err" || {
      echo "campaign-cpu: $1 failed" >&2
      tail -20 "$WORK/$1.err" >&2
      exit 1
    }
    local c
    c=$(awk '{ print $1 + $2 }' "$WORK/$1.time")
    if [[ -z $CPU ]] || awk -v a="$c" -v b="$CPU" 'BEGIN { exit !(a < b) }'; then CPU=$c; fi
  done
}

best_cpu none
NONE_CPU=$CPU
best_cpu ten
TEN_CPU=$CPU
RECORDS=$(sqlite3 "$WORK/db-ten/fleetgw.db" "select count(*), ifnull(sum(length(payload)), 0) from outbox where kind = 'campaign'")

if [[ ${RECORDS%|*} == 0 ]]; then
  echo "campaign-cpu: the 10 campaigns recorded nothing (not restored? see $WORK/ten.err)" >&2
  exit 1
fi
echo "fleetgw: $FLEETGW, $(nproc) cores, best of $RUNS runs; worst-case log: $FRAMES CAN frames in 1 bus-hour"
printf 'no campaign:   %.3f s CPU per bus-hour\n' "$NONE_CPU"
printf '10 campaigns:  %.3f s CPU per bus-hour (%s campaign records, bytes: %s)\n' \
  "$TEN_CPU" "${RECORDS%|*}" "${RECORDS#*|}"
printf 'ratio:         %.3fx   target <= 1.2x\n' "$(awk -v a="$TEN_CPU" -v b="$NONE_CPU" 'BEGIN { print a / b }')"
