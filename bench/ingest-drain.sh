#!/usr/bin/env bash
# What one `fleetgw ingest` worker can commit (issue 15): a backlog drained as fast as possible.
# Two workers subscribe and stop (their MQTT 5 sessions stay on the broker), `fleetgw fleet-sim`
# (VEHICLES, DURATION_S) publishes into those sessions, then the workers start again and the
# benchmark times the drain until every record the fleet-sim created is accounted for in
# PostgreSQL: messages/s and records/s committed, per worker. It also shows that mosquitto queues
# shared-subscription messages for members that are away (nothing would arrive otherwise).
# In the same run, the same rows (dumped from PostgreSQL after the drain) are written again by a
# plain COPY loader (psql \copy, one COPY per table) into a second database of the same cluster:
# the worker's rows/s and CPU per row are reported as ratios to the loader's.
# A benchmark, not a test; root. Environment: FLEETGW, VEHICLES (1000), DURATION_S (60),
# RIDING_SHARE (0.3), WORKERS (2), INGEST_ARGS (extra worker options, e.g. "--sessions 32"),
# KEEP=1.
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
RSS_PEAK=0
for _ in $(seq 6000); do
  GOT=$(accounted)
  RSS=$(workers_rss_kb)
  [[ $RSS -gt $RSS_PEAK ]] && RSS_PEAK=$RSS
  [[ $GOT -ge $EXPECTED ]] && break
  sleep 0.1
done
T1=$(date +%s%N)
I1=$(workers_cpu_s)
P1=$(pg_cpu_s)
RSS_END=$(workers_rss_kb)
PSS_END=$(workers_pss_kb)
stop_workers
S=$(echo "($T1 - $T0) / 1000000000" | bc -l)
ROWS=$(psql_q "SELECT (SELECT count(*) FROM telemetry_samples) + (SELECT count(*) FROM rides) + (SELECT count(*) FROM lock_events) + (SELECT count(*) FROM pack_snapshots) + (SELECT count(*) FROM device_info)")
echo "backlog                     $MESSAGES messages, $EXPECTED records"
echo "accounted / rows            $GOT / $ROWS (gaps: $("$FLEETGW" ingest --gaps --pg "$CONNINFO" 2>/dev/null | wc -l))"
printf 'drained in                  %.1f s (worker start-up included)\n' "$S"
printf 'committed                   %.0f messages/s, %.0f records/s (%.0f messages/s per worker)\n' \
  "$(echo "$MESSAGES / $S" | bc -l)" "$(echo "$EXPECTED / $S" | bc -l)" "$(echo "$MESSAGES / $S / $NWORKERS" | bc -l)"
printf 'CPU ingest / PostgreSQL     %.1f s / %.1f s\n' "$(echo "$I1 - $I0" | bc -l)" "$(echo "$P1 - $P0" | bc -l)"
printf 'worker RSS peak / at end     %.1f MB / %.1f MB (all its processes; PSS at end %.1f MB)\n' \
  "$(echo "$RSS_PEAK / 1024" | bc -l)" "$(echo "$RSS_END / 1024" | bc -l)" "$(echo "$PSS_END / 1024" | bc -l)"
# First to last commit, from the rows' own committed_at_us: the drain without the start-up.
COMMIT_S=$(psql_q "SELECT greatest(max(m) - min(n), 1) / 1e6 FROM (SELECT min(committed_at_us) n, max(committed_at_us) m FROM telemetry_samples UNION ALL SELECT min(committed_at_us), max(committed_at_us) FROM lock_events UNION ALL SELECT min(committed_at_us), max(committed_at_us) FROM pack_snapshots) t")
printf 'first to last commit        %.2f s: %.0f records/s\n' "$COMMIT_S" "$(echo "$EXPECTED / $COMMIT_S" | bc -l)"

# The same rows by a plain COPY loader into database "loader" of the same cluster.
LOADER_DB="${CONNINFO/dbname=postgres/dbname=loader}"
TABLES="telemetry_samples rides lock_events pack_snapshots device_info status vehicle_state"
psql_q "CREATE DATABASE loader"
pg_dump --schema-only "$CONNINFO" | psql -X -q -v ON_ERROR_STOP=1 "$LOADER_DB" >/dev/null
LOADED=0
: >"$WORK/loader.sql"
for t in $TABLES; do
  psql_q "\copy (SELECT * FROM $t) TO '$WORK/$t.copy'"
  LOADED=$((LOADED + $(wc -l <"$WORK/$t.copy")))
  echo "\copy $t FROM '$WORK/$t.copy'" >>"$WORK/loader.sql"
done
WROTE=$(psql_q "SELECT (SELECT count(*) FROM telemetry_samples) + (SELECT count(*) FROM rides) + (SELECT count(*) FROM lock_events) + (SELECT count(*) FROM pack_snapshots) + (SELECT count(*) FROM device_info) + (SELECT count(*) FROM status) + (SELECT count(*) FROM vehicle_state)")
L0=$(date +%s%N)
LP0=$(pg_cpu_s)
/usr/bin/python3 bench/cputime.py "$WORK/loader.cpu" psql -X -q -v ON_ERROR_STOP=1 -1 \
  -f "$WORK/loader.sql" "$LOADER_DB"
L1=$(date +%s%N)
LP1=$(pg_cpu_s)
LS=$(echo "($L1 - $L0) / 1000000000" | bc -l)
LC=$(awk '{ print $1 + $2 }' "$WORK/loader.cpu")
W_RATE=$(echo "$WROTE / $COMMIT_S" | bc -l)
L_RATE=$(echo "$LOADED / $LS" | bc -l)
W_CPU=$(echo "($I1 - $I0 + $P1 - $P0) * 1000000 / $WROTE" | bc -l)
L_CPU=$(echo "($LC + $LP1 - $LP0) * 1000000 / $LOADED" | bc -l)
printf 'COPY loader, same rows       %d rows in %.2f s: %.0f rows/s; CPU psql / PostgreSQL %.2f s / %.2f s\n' \
  "$LOADED" "$LS" "$L_RATE" "$LC" "$(echo "$LP1 - $LP0" | bc -l)"
printf 'worker vs COPY loader        %.0f vs %.0f rows/s (%.0f %%, worker first to last commit); CPU %.1f vs %.1f us per row (%.2fx)\n' \
  "$W_RATE" "$L_RATE" "$(echo "100 * $W_RATE / $L_RATE" | bc -l)" "$W_CPU" "$L_CPU" \
  "$(echo "$W_CPU / $L_CPU" | bc -l)"
[[ $GOT -ge $EXPECTED && $ROWS == "$EXPECTED" ]] || { echo "ingest-drain: NOT exactly once"; exit 1; }
