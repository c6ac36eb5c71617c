#!/usr/bin/env bash
# What one `fleetgw ingest` worker can commit (issue 15): a backlog drained as fast as possible.
# Two workers subscribe and stop (their MQTT 5 sessions stay on the broker), `fleetgw fleet-sim`
# (VEHICLES, DURATION_S) publishes into those sessions, then the workers start again and the
# benchmark times the drain until every record the fleet-sim created is accounted for in
# PostgreSQL: messages/s and records/s committed, per worker. It also shows that mosquitto queues
# shared-subscription messages for members that are away (nothing would arrive otherwise).
# A benchmark, not a test; root. Environment: FLEETGW, VEHICLES (1000), DURATION_S (60),
# RIDING_SHARE (0.3), WORKERS (2), KEEP=1.
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=$(realpath "${FLEETGW:-build/gateway/app/fleetgw}")
VEHICLES=${VEHICLES:-1000}
DURATION_S=${DURATION_S:-60}
RIDING_SHARE=${RIDING_SHARE:-0.3}
NWORKERS=${WORKERS:-2}
source bench/ingest-lib.sh

start_postgres
start_broker
start_workers "$NWORKERS"
stop_workers
echo "ingest-drain: $VEHICLES vehicles for $DURATION_S s into the sessions of $NWORKERS stopped workers"
"$FLEETGW" fleet-sim --vehicles "$VEHICLES" --broker "$BROKER_URI" --duration-s "$DURATION_S" \
  --riding-share "$RIDING_SHARE" >"$WORK/sim.json" 2>"$WORK/sim.log" ||
  { echo "fleet-sim failed:"; tail -5 "$WORK/sim.log"; exit 1; }
EXPECTED=$(expected_records "$WORK/sim.json")
MESSAGES=$(/usr/bin/python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["messages"])' "$WORK/sim.json")

T0=$(date +%s%N)
I0=0
P0=$(pg_cpu_s)
start_workers "$NWORKERS" 2
GOT=0
for _ in $(seq 6000); do
  GOT=$(accounted)
  [[ $GOT -ge $EXPECTED ]] && break
  sleep 0.1
done
T1=$(date +%s%N)
I1=$(workers_cpu_s)
P1=$(pg_cpu_s)
stop_workers
S=$(echo "($T1 - $T0) / 1000000000" | bc -l)
ROWS=$(psql_q "SELECT (SELECT count(*) FROM telemetry_samples) + (SELECT count(*) FROM rides) + (SELECT count(*) FROM lock_events) + (SELECT count(*) FROM pack_snapshots) + (SELECT count(*) FROM device_info)")
echo "backlog                     $MESSAGES messages, $EXPECTED records"
echo "accounted / rows            $GOT / $ROWS (gaps: $("$FLEETGW" ingest --gaps --pg "$CONNINFO" 2>/dev/null | wc -l))"
printf 'drained in                  %.1f s (worker start-up included)\n' "$S"
printf 'committed                   %.0f messages/s, %.0f records/s (%.0f messages/s per worker)\n' \
  "$(echo "$MESSAGES / $S" | bc -l)" "$(echo "$EXPECTED / $S" | bc -l)" "$(echo "$MESSAGES / $S / $NWORKERS" | bc -l)"
printf 'CPU ingest / PostgreSQL     %.1f s / %.1f s\n' "$(echo "$I1 - $I0" | bc -l)" "$(echo "$P1 - $P0" | bc -l)"
[[ $GOT -ge $EXPECTED && $ROWS == "$EXPECTED" ]] || { echo "ingest-drain: NOT exactly once"; exit 1; }
