#!/usr/bin/env bash
# Command results under a burst (issue 24, finding 4), through the shipped binaries: a local
# mosquitto, `fleetgw run` on the simulated parked bike, and N operators (`fleetgw command
# --lights on|off`, one process each). A benchmark, not a test.
#
# The burst: the service is frozen (SIGSTOP: a board stalled on I/O, or the link holding
# messages back; its MQTT connection stays up, keep-alive 30 s) while N operators send a command
# each; on SIGCONT its MQTT client reads all N at once. Every operator waits up to TIMEOUT_S for
# its result. Printed: how many succeeded, were refused busy / mc_busy / otherwise, and got NO
# result (the tool's exit 3), and the service's `fleetgw status` command counters. Then the junk
# row: JUNK zeroed-signature commands (a trusted key id, any bytes: what anyone who can publish
# on `cmd` can send) arrive together just before one genuine command, REPS times: was the
# genuine one answered and executed?
#
# The stop row (STOP_RUNS, default 3): a burst of STOP_N commands sent while the service is frozen,
# which is then stopped (SIGTERM, SIGCONT) and started again on the same store and persistent
# MQTT session: every command must still get exactly one result (shutting_down or busy from the
# stopping process, or an answer from the restarted one), none "no result".
#
# Environment: FLEETGW (binary, default build/bin/fleetgw), N (100), JUNK (60),
#   REPS (3), TIMEOUT_S (90), STOP_RUNS (3), STOP_N (40), KEEP=1 keeps the work directory.
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=$(realpath "${FLEETGW:-build/bin/fleetgw}")
N=${N:-100}
JUNK=${JUNK:-60}
REPS=${REPS:-3}
TIMEOUT_S=${TIMEOUT_S:-90}
VEHICLE=burst-bench
[[ -x $FLEETGW ]] || { echo "command-burst: no binary $FLEETGW" >&2; exit 1; }
for tool in mosquitto mosquitto_pub protoc; do
  command -v $tool >/dev/null || { echo "command-burst: needs $tool" >&2; exit 1; }
done

WORK=$(mktemp -d /tmp/fleetgw-burst-XXXXXX)
BROKER_PID="" SERVICE_PID=""
cleanup() {
  for p in $SERVICE_PID $BROKER_PID; do kill "$p" 2>/dev/null || true; done
  [[ ${KEEP:-0} == 1 ]] && echo "work directory: $WORK" || rm -rf "$WORK"
}
trap cleanup EXIT

PORT=$(/usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
# log_type all: "Received PUBLISH" lines tell when every queued command is in the broker.
printf 'listener %s 127.0.0.1\nallow_anonymous true\nset_tcp_nodelay true\nlog_dest stderr\nlog_type all\nmax_queued_messages 10000\n' \
  "$PORT" >"$WORK/mosquitto.conf"
mosquitto -c "$WORK/mosquitto.conf" 2>"$WORK/mosquitto.log" &
BROKER_PID=$!
for _ in $(seq 100); do
  mosquitto_pub -h 127.0.0.1 -p "$PORT" -t probe -m up 2>/dev/null && break
  sleep 0.05
done

"$FLEETGW" keygen "$WORK/ops" >"$WORK/keygen.out" 2>"$WORK/keygen.err"
cat >"$WORK/fleetgw.toml" <<TOML
[vehicle]
id = "$VEHICLE"
[log]
level = "info"
[can]
transport = "sim"
[sim]
scenario = "$PWD/config/scenarios/parked.toml"
speed = 1
[storage]
path = "$WORK/fleetgw.db"
[status]
socket = "$WORK/status.sock"
[mqtt]
enabled = true
uri = "tcp://127.0.0.1:$PORT"
[command.trusted_keys]
$(cat "$WORK/keygen.out")
TOML

start_service() {  # log name
  "$FLEETGW" run --config "$WORK/fleetgw.toml" >"$WORK/$1.log" 2>&1 &
  SERVICE_PID=$!
  for _ in $(seq 600); do
    grep -q "uplink: connected" "$WORK/$1.log" && return 0
    sleep 0.05
  done
  echo "command-burst: the service did not connect" >&2
  tail -20 "$WORK/$1.log" >&2
  exit 1
}
stop_service() {
  kill -TERM "$SERVICE_PID"
  wait "$SERVICE_PID" || true
  SERVICE_PID=""
}
operator() {  # out-file lights [timeout]
  "$FLEETGW" command --vehicle "$VEHICLE" --key "$WORK/ops.pem" --broker "tcp://127.0.0.1:$PORT" \
    --lights "$2" --timeout-s "${3:-$TIMEOUT_S}" --expires-in-s 600 >"$1" 2>"$1.err"
}
cmd_publishes() {  # PUBLISH packets the broker received on the vehicle's cmd topic so far
  grep -c "Received PUBLISH from .*'fleet/v1/$VEHICLE/cmd'" "$WORK/mosquitto.log" || true
}
wait_publishes() {  # count
  for _ in $(seq 1200); do
    (($(cmd_publishes) >= $1)) && return 0
    sleep 0.05
  done
  echo "command-burst: only $(cmd_publishes) of $1 commands reached the broker" >&2
  exit 1
}
status_commands() {
  "$FLEETGW" status --config "$WORK/fleetgw.toml" --format json 2>/dev/null |
    /usr/bin/python3 -c 'import json, sys; print(json.dumps(json.load(sys.stdin).get("commands")))'
}

# The MC is known (an early command is refused mc_offline).
start_service service
for _ in $(seq 30); do
  operator "$WORK/warm.out" off 10 || true
  grep -q '"result":"succeeded"' "$WORK/warm.out" && break
  sleep 0.5
done

# ---- the burst ----
# Freezes the service and sends it `count` commands (lights on/off alternating), one operator
# each, their results in PREFIX-i.out; returns once the broker holds them all. OPS: the operators.
frozen_burst() {  # prefix count
  local sent i
  sent=$(cmd_publishes)
  kill -STOP "$SERVICE_PID"
  OPS=()
  for i in $(seq "$2"); do
    operator "$WORK/$1-$i.out" "$([[ $((i % 2)) == 0 ]] && echo on || echo off)" &
    OPS+=($!)
  done
  wait_publishes $((sent + $2))
}
declare -a OPS=()
frozen_burst op "$N"
kill -CONT "$SERVICE_PID"
for p in "${OPS[@]}"; do wait "$p" || true; done
tally_results() {  # prefix count title
/usr/bin/python3 - "$WORK" "$2" "$1" "$3" <<'PY'
import json, pathlib, sys
work, n, prefix, title = pathlib.Path(sys.argv[1]), int(sys.argv[2]), sys.argv[3], sys.argv[4]
tally = {}
for i in range(1, n + 1):
    text = (work / f"{prefix}-{i}.out").read_text().strip()
    if not text:
        key = "no result"
    else:
        r = json.loads(text)
        key = r["result"] if r["result"] != "rejected" else r["reason"].split(":")[0]
    tally[key] = tally.get(key, 0) + 1
print(f"{title}:")
for k in sorted(tally, key=lambda k: -tally[k]):
    print(f"  {k:<12} {tally[k]}")
if "no result" not in tally:
    print(f"  {'no result':<12} 0")
PY
}
tally_results op "$N" "burst of $N signed commands (the service frozen while they were sent)"
echo "  fleetgw status commands: $(status_commands)"

# ---- junk before a genuine command ----
answered=0
for rep in $(seq "$REPS"); do
  /usr/bin/python3 - "$WORK" "$VEHICLE" "$JUNK" "$rep" <<'PY'
import pathlib, subprocess, sys, time
work, vehicle, junk, rep = pathlib.Path(sys.argv[1]), sys.argv[2], int(sys.argv[3]), sys.argv[4]
now = int(time.time() * 1e6)
for i in range(junk):
    text = (f'command_id: "junk-{rep}-{i}" vehicle_id: "{vehicle}" issued_at_us: {now} '
            f'expires_at_us: {now + 600_000_000} headlight {{ on: true }}')
    cmd = subprocess.run(["protoc", "--encode=fleetgw.v1.Command", "-I", "proto",
                          "proto/fleetgw/v1/command.proto"], input=text.encode(),
                         capture_output=True, check=True).stdout
    escaped = "".join(f"\\{b:03o}" for b in cmd)
    signed = subprocess.run(["protoc", "--encode=fleetgw.v1.SignedCommand", "-I", "proto",
                             "proto/fleetgw/v1/command.proto"],
                            input=(f'command: "{escaped}" key_id: "ops" signature: "'
                                   + "\\000" * 64 + '"').encode(),
                            capture_output=True, check=True).stdout
    (work / f"junk-{i}.bin").write_bytes(signed)
PY
  sent=$(cmd_publishes)
  kill -STOP "$SERVICE_PID"
  for i in $(seq 0 $((JUNK - 1))); do
    mosquitto_pub -h 127.0.0.1 -p "$PORT" -q 1 -t "fleet/v1/$VEHICLE/cmd" -f "$WORK/junk-$i.bin"
  done
  operator "$WORK/genuine-$rep.out" "$([[ $((rep % 2)) == 0 ]] && echo off || echo on)" &
  op=$!
  wait_publishes $((sent + JUNK + 1))
  kill -CONT "$SERVICE_PID"
  wait "$op" || true
  if grep -q '"result":"succeeded"' "$WORK/genuine-$rep.out"; then
    answered=$((answered + 1))
  else
    echo "  repetition $rep: genuine command: $(cat "$WORK/genuine-$rep.out" "$WORK/genuine-$rep.out.err")"
  fi
done
echo "junk flood: $JUNK zeroed-signature commands just before a genuine one:" \
  "genuine command answered and executed in $answered of $REPS repetitions"
echo "  fleetgw status commands: $(status_commands)"
stop_service

# ---- a burst sent while frozen, then a stop and a restart ----
for run in $(seq "${STOP_RUNS:-3}"); do
  n=${STOP_N:-40}
  [[ -n $SERVICE_PID ]] || start_service "service-restart-$run"
  frozen_burst "stop$run" "$n"
  kill -TERM "$SERVICE_PID"
  kill -CONT "$SERVICE_PID"
  wait "$SERVICE_PID" || true
  SERVICE_PID=""
  start_service "service-after-stop-$run"
  for p in "${OPS[@]}"; do wait "$p" || true; done
  tally_results "stop$run" "$n" "stop row $run: $n commands sent while frozen, then SIGTERM and a restart"
done
stop_service
