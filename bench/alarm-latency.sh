#!/usr/bin/env bash
# Alarm latency (issue 13, figures): time from the first wheel movement of a locked bike to the
# UNAUTHORISED_MOVEMENT alarm reaching the broker, through the shipped `fleetgw run` on the
# simulator at speed 1 (config/scenarios/theft.toml: the wheel starts turning at 20 s) with the
# uplink on to a local mosquitto. A benchmark, not a test. Per run it prints the alarm's
# debounce (first evidence -> decision, bus time: alarms.movement_debounce_ms) and the whole
# latency: the wall time at which mosquitto_sub received the alarm minus the alarm's
# first_evidence_us. At speed 1 with sim.start_now (the default) the simulated bus clock is the
# system clock from the service's start on, so both are on one clock; the simulator delivers
# frames in batches of up to 500 ms (docs/ARCHITECTURE.md), which the figure includes.
# Environment: FLEETGW (binary, default build/bin/fleetgw), RUNS (3), KEEP=1 keeps the
#   work directory.
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=$(realpath "${FLEETGW:-build/bin/fleetgw}")
RUNS=${RUNS:-3}
VEHICLE=alarm-bench
[[ -x $FLEETGW ]] || { echo "alarm-latency: no binary $FLEETGW" >&2; exit 1; }
command -v mosquitto_sub >/dev/null || { echo "alarm-latency: needs mosquitto-clients" >&2; exit 1; }

WORK=$(mktemp -d /tmp/fleetgw-alarm-XXXXXX)
BROKER_PID="" SUB_PID=""
cleanup() {
  for p in $SUB_PID $BROKER_PID; do kill "$p" 2>/dev/null || true; done
  [[ ${KEEP:-0} == 1 ]] && echo "work directory: $WORK" || rm -rf "$WORK"
}
trap cleanup EXIT

PORT=$(/usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
printf 'listener %s 127.0.0.1\nallow_anonymous true\nlog_dest stderr\n' "$PORT" >"$WORK/mosquitto.conf"
mosquitto -c "$WORK/mosquitto.conf" 2>"$WORK/mosquitto.log" &
BROKER_PID=$!
for _ in $(seq 100); do  # until the broker accepts a connection
  mosquitto_pub -h 127.0.0.1 -p "$PORT" -t probe -m up 2>/dev/null && break
  sleep 0.05
done

for run in $(seq "$RUNS"); do
  cat >"$WORK/fleetgw.toml" <<TOML
[vehicle]
id = "$VEHICLE"
[log]
level = "warn"
[can]
transport = "sim"
[sim]
scenario = "$PWD/config/scenarios/theft.toml"
speed = 1
[storage]
path = "$WORK/fleetgw-$run.db"
[mqtt]
enabled = true
uri = "tcp://127.0.0.1:$PORT"
TOML
  rm -f "$WORK/alarm.bin" "$WORK/arrived"
  # One alarm message, stamped with the wall clock the moment it arrives.
  (mosquitto_sub -h 127.0.0.1 -p "$PORT" -q 1 -N -C 1 -t "fleet/v1/$VEHICLE/alarm" >"$WORK/alarm.bin" &&
    date +%s.%N >"$WORK/arrived") &
  SUB_PID=$!
  # (The wheel starts turning 20 s into the scenario: the subscription is long in place.)
  "$FLEETGW" run --config "$WORK/fleetgw.toml" --duration 30 >"$WORK/fleetgw-$run.log" 2>&1
  wait "$SUB_PID" || true
  SUB_PID=""
  [[ -s $WORK/arrived ]] || { echo "run $run: no alarm received"; cat "$WORK/fleetgw-$run.log"; exit 1; }
  TEXT=$(protoc --decode=fleetgw.v1.Envelope -I proto proto/fleetgw/v1/envelope.proto <"$WORK/alarm.bin")
  FIRST=$(sed -n 's/^ *first_evidence_us: //p' <<<"$TEXT")
  AT=$(sed -n 's/^ *at_us: //p' <<<"$TEXT")
  /usr/bin/python3 - "$(cat "$WORK/arrived")" "$FIRST" "$AT" "$run" <<'PY'
import sys
arrived, first, at, run = sys.argv[1:]
print(f"run {run}: debounce {(int(at) - int(first)) / 1e6:.3f} s (bus time), "
      f"first wheel movement -> broker {float(arrived) - int(first) / 1e6:.3f} s")
PY
done
