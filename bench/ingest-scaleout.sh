#!/usr/bin/env bash
# Scale-out, tested (issue 25): WORKERS `fleetgw ingest` workers, each in its own network
# namespace (ip netns + a veth pair: a host of its own, reaching the broker and PostgreSQL over
# TCP at 10.99.K.1), one shared-subscription group against one mosquitto and one PostgreSQL,
# while fleetgw-fleet-sim plays VEHICLES vehicles for DURATION_S. Every KILL_EVERY_S one worker
# (in turn) is SIGKILLed and started again in its namespace. Then the exactly-once check: the
# fleet-sim's own count of records per store (all acknowledged) against the rows in PostgreSQL,
# and the gap report, which must be empty. Exit 0 only then. LEAVE=1: every other turn the worker
# instead leaves the group for good (SIGUSR1: it unsubscribes, commits what the broker queued for
# it, ends its sessions, exits 0) and a new member with its client id joins in its place.
# Root (namespaces, PostgreSQL as `postgres`). Every step has a timeout (see ingest-lib.sh).
# Environment: FLEETGW (default build/bin/fleetgw, fleetgw-ingest and fleetgw-fleet-sim
#   beside it), VEHICLES (2000), DURATION_S (90), RIDING_SHARE (0.3), WORKERS (3),
#   KILL_EVERY_S (15), LEAVE (0), INGEST_ARGS, KEEP=1.
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=$(realpath -m "${FLEETGW:-build/bin/fleetgw}")
VEHICLES=${VEHICLES:-2000}
DURATION_S=${DURATION_S:-90}
RIDING_SHARE=${RIDING_SHARE:-0.3}
NWORKERS=${WORKERS:-3}
KILL_EVERY_S=${KILL_EVERY_S:-15}
command -v ip >/dev/null || { echo "ingest-scaleout: needs iproute2" >&2; exit 77; }
source bench/ingest-lib.sh
SIM=$(dirname "$FLEETGW")/fleetgw-fleet-sim
[[ -x $SIM ]] || { echo "ingest-scaleout: no $SIM" >&2; exit 1; }

# Namespaces fgw-<pid>-K with veth fgh<K>-<pid>/fgn<K> (host side 10.99.K.1, worker 10.99.K.2).
NS_PREFIX="fgw-$$"
NAMESPACES=()
scaleout_cleanup() {
  local ns
  for ns in "${NAMESPACES[@]}"; do ip netns del "$ns" 2>/dev/null || true; done
  cleanup
}
trap scaleout_cleanup EXIT
LISTEN=""
for k in $(seq "$NWORKERS"); do
  ns="$NS_PREFIX-$k"
  ip netns add "$ns"
  NAMESPACES+=("$ns")
  ip link add "fgh$k-$$" type veth peer name fgn$k netns "$ns"
  ip addr add "10.99.$k.1/24" dev "fgh$k-$$"
  ip link set "fgh$k-$$" up
  ip -n "$ns" addr add "10.99.$k.2/24" dev fgn$k
  ip -n "$ns" link set fgn$k up
  ip -n "$ns" link set lo up
  LISTEN+="${LISTEN:+,}10.99.$k.1"
done
PG_LISTEN=$LISTEN PG_HBA_NET=10.99.0.0/16 start_postgres
PGPORT=$(sed 's/.*port=\([0-9]*\).*/\1/' <<<"$CONNINFO")
BROKER_BIND=0.0.0.0 start_broker

# start_worker K: worker K in its namespace, over TCP to the host side of its veth.
start_worker() {
  local k=$1
  ip netns exec "$NS_PREFIX-$k" "$FLEETGW" ingest --broker "tcp://10.99.$k.1:$BROKER_PORT" \
    --group bench --client-id "bench-worker-$k" \
    --pg "host=10.99.$k.1 port=$PGPORT user=fleet dbname=postgres" ${INGEST_ARGS:-} \
    >>"$WORK/worker-$k.log" 2>&1 &
  WORKERS[$((k - 1))]=$!
  PIDS+=("$!")
}
wait_subscribed() {  # K COUNT: worker K's log has COUNT "subscribed to" lines (STARTUP_TIMEOUT_S)
  local deadline=$((SECONDS + ${STARTUP_TIMEOUT_S:-300}))
  until [[ $(grep -c "subscribed to" "$WORK/worker-$1.log") -ge $2 ]]; do
    [[ $SECONDS -lt $deadline ]] || { echo "worker $1 not subscribed"; tail -20 "$WORK/worker-$1.log"; exit 1; }
    sleep 0.1
  done
}
WORKERS=()
declare -A STARTS
for k in $(seq "$NWORKERS"); do
  start_worker "$k"
  STARTS[$k]=1
done
for k in $(seq "$NWORKERS"); do wait_subscribed "$k" 1; done

echo "ingest-scaleout: $VEHICLES vehicles for $DURATION_S s -> mosquitto -> $NWORKERS workers in $NWORKERS network namespaces (one SIGKILLed and restarted every $KILL_EVERY_S s) -> PostgreSQL"
timeout -k 10 $((DURATION_S + 180)) "$SIM" --vehicles "$VEHICLES" --broker "$BROKER_URI" \
  --duration-s "$DURATION_S" --riding-share "$RIDING_SHARE" --report "$WORK/sim.json" \
  2>"$WORK/sim.log" &
SIM_PID=$!
KILLS=0
LEAVES=0
LEAVE_FAILS=0
turn=0
next=1
while kill -0 "$SIM_PID" 2>/dev/null; do
  for _ in $(seq $((KILL_EVERY_S * 10))); do kill -0 "$SIM_PID" 2>/dev/null && sleep 0.1; done
  kill -0 "$SIM_PID" 2>/dev/null || break
  if [[ ${LEAVE:-0} == 1 && $((turn++ % 2)) == 1 ]]; then
    kill -USR1 "${WORKERS[$((next - 1))]}" 2>/dev/null || true
    rc=0
    wait "${WORKERS[$((next - 1))]}" || rc=$?
    [[ $rc == 0 ]] || { LEAVE_FAILS=$((LEAVE_FAILS + 1)); echo "worker $next: the leave exited $rc"; }
    LEAVES=$((LEAVES + 1))
  else
    kill -KILL "${WORKERS[$((next - 1))]}" 2>/dev/null || true
    wait "${WORKERS[$((next - 1))]}" 2>/dev/null || true
    KILLS=$((KILLS + 1))
  fi
  start_worker "$next"
  STARTS[$next]=$((STARTS[$next] + 1))
  wait_subscribed "$next" "${STARTS[$next]}"
  next=$((next % NWORKERS + 1))
done
SIM_OK=1
wait "$SIM_PID" || { SIM_OK=0; echo "fleet-sim failed:"; tail -5 "$WORK/sim.log"; }

EXPECTED=$(expected_records "$WORK/sim.json")
GOT=0
SETTLE_END=$((SECONDS + ${SETTLE_TIMEOUT_S:-600}))
while [[ $SECONDS -lt $SETTLE_END ]]; do
  GOT=$(accounted)
  [[ $GOT -ge $EXPECTED ]] && break
  sleep 0.5
done
stop_workers
ROWS=$(psql_q "SELECT (SELECT count(*) FROM telemetry_samples) + (SELECT count(*) FROM rides) + (SELECT count(*) FROM lock_events) + (SELECT count(*) FROM pack_snapshots) + (SELECT count(*) FROM device_info)")
# `ingest --gaps` exits 1 when it prints gaps: counted here, not a failure of the script.
GAPS=$({ timeout "${QUERY_TIMEOUT_S:-600}" "$FLEETGW" ingest --gaps --pg "$CONNINFO" 2>/dev/null || true; } | wc -l)
read -r CONNECTED UNACKED RESENT DROPS < <(/usr/bin/python3 -c '
import json, sys
r = json.load(open(sys.argv[1]))
print(r["connected"], r["unacknowledged"] + r["failed_processes"], r["resent"], r["disconnects"])' "$WORK/sim.json")
echo "vehicles connected          $CONNECTED of $VEHICLES, unacknowledged publishes $UNACKED, re-sent $RESENT, sessions lost $DROPS"
echo "workers SIGKILLed/restarted $KILLS (each in its own network namespace)"
[[ ${LEAVE:-0} == 1 ]] && echo "workers left/new member     $LEAVES (SIGUSR1; $LEAVE_FAILS leaves failed)"
echo "records created / in PG     $EXPECTED / $ROWS rows ($GOT accounted), gaps: $GAPS"
[[ $SIM_OK == 1 && $GAPS == 0 && $ROWS == "$EXPECTED" && $UNACKED == 0 && $LEAVE_FAILS == 0 ]] || { echo "ingest-scaleout: NOT exactly once"; exit 1; }
echo "ingest-scaleout: exactly once"
