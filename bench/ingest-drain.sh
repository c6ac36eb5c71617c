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
# CPU per row is counted two ways: the client and its own PostgreSQL backend(s) only (worker +
# its connections against psql + its connection: what each side makes PostgreSQL do), and the
# client and every PostgreSQL process (background writers and autovacuum included, which run
# longer beside the slower side). The poll for completion uses one persistent psql session.
# A benchmark, not a test; root. Environment: FLEETGW, VEHICLES (1000), DURATION_S (60),
# RIDING_SHARE (0.3), WORKERS (2), INGEST_ARGS (extra worker options, e.g. "--sessions 32"),
# PERF=1 (a system-wide `perf record` of the drain and of the loader: the top functions of the
# worker and of PostgreSQL in each, written to the work directory and summarised; and
# pg_stat_statements: the server's time per statement of the drain; PERF_FREQ, 499, its sampling
# rate per CPU), KEEP=1.
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=$(realpath -m "${FLEETGW:-build/bin/fleetgw}")
VEHICLES=${VEHICLES:-1000}
DURATION_S=${DURATION_S:-60}
RIDING_SHARE=${RIDING_SHARE:-0.3}
NWORKERS=${WORKERS:-2}
[[ ${PERF:-0} == 1 ]] && PG_OPTS="${PG_OPTS:-} -c shared_preload_libraries=pg_stat_statements -c pg_stat_statements.track_utility=on"
source bench/ingest-lib.sh

start_postgres
start_poller
start_broker
start_workers "$NWORKERS"
stop_workers
echo "ingest-drain: $VEHICLES vehicles for $DURATION_S s into the sessions of $NWORKERS stopped workers"
"$FLEETGW" fleet-sim --vehicles "$VEHICLES" --broker "$BROKER_URI" --duration-s "$DURATION_S" \
  --riding-share "$RIDING_SHARE" >"$WORK/sim.json" 2>"$WORK/sim.log" ||
  { echo "fleet-sim failed:"; tail -5 "$WORK/sim.log"; exit 1; }
EXPECTED=$(expected_records "$WORK/sim.json")
MESSAGES=$(/usr/bin/python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["messages"])' "$WORK/sim.json")

# perf_start NAME / perf_stop: a system-wide profile of a window (PERF=1).
perf_start() {
  [[ ${PERF:-0} == 1 ]] || return 0
  perf record -a -F "${PERF_FREQ:-499}" -o "$WORK/perf-$1.data" >"$WORK/perf-$1.log" 2>&1 &
  PERF_PID=$!
  sleep 1
}
perf_stop() {
  [[ ${PERF:-0} == 1 ]] || return 0
  kill -INT "$PERF_PID"
  wait "$PERF_PID" 2>/dev/null || true
}
perf_summary() {  # perf_summary NAME PROGRAM: the share of samples per program, the top functions
  [[ ${PERF:-0} == 1 ]] || return 0
  # Whole reports to files first: `head` on a pipe would end perf with SIGPIPE under pipefail.
  perf report -i "$WORK/perf-$1.data" --sort comm --stdio >"$WORK/perf-$1.comm" 2>/dev/null || true
  perf report -i "$WORK/perf-$1.data" --comm "$2,postgres" --sort comm,dso,sym --stdio \
    >"$WORK/perf-$1.top" 2>/dev/null || true
  echo "perf, $1: samples per program (whole machine; $WORK/perf-$1.comm)"
  grep -v '^#' "$WORK/perf-$1.comm" | grep . | sed -n '1,8s/^/  /p'
  echo "perf, $1: top functions of $2 and postgres ($WORK/perf-$1.top)"
  grep -v '^#' "$WORK/perf-$1.top" | grep . | sed -n '1,25s/^/  /p'
}

# The completion poll, ten times a second: since migration 11 the view sequence_ranges merges the
# appended ranges on the fly (17-34 ms of server time over a drain's ~18,000 rows), so the poll
# sums the two tables' rows as they are instead (~1 ms; never less than the merged count, equal
# without overlaps) and asks the view only once that sum reaches the records expected.
if [[ $(psql_q "SELECT to_regclass('sequence_ranges_new') IS NOT NULL") == t ]]; then
  BOUND_Q="SELECT (SELECT coalesce(sum(last_seq - first_seq + 1), 0) FROM sequence_ranges_merged) + (SELECT coalesce(sum(last_seq - first_seq + 1), 0) FROM sequence_ranges_new)"
else
  BOUND_Q="SELECT coalesce(sum(last_seq - first_seq + 1), 0) FROM sequence_ranges"
fi
perf_start drain
T0=$(date +%s%N)
I0=0
P0=$(pg_cpu_s)
start_workers "$NWORKERS" 2
GOT=0
RSS_PEAK=0
for _ in $(seq 6000); do
  GOT=$(poll_q "$BOUND_Q")
  [[ $GOT -ge $EXPECTED ]] && GOT=$(accounted)
  RSS=$(workers_rss_kb)
  [[ $RSS -gt $RSS_PEAK ]] && RSS_PEAK=$RSS
  [[ $GOT -ge $EXPECTED ]] && break
  sleep 0.1
done
T1=$(date +%s%N)
I1=$(workers_cpu_s)
P1=$(pg_cpu_s)
PB1=$(pg_backends_cpu_s)  # the workers' connections (started after T0)
perf_stop
RSS_END=$(workers_rss_kb)
PSS_END=$(workers_pss_kb)
stop_workers
S=$(echo "($T1 - $T0) / 1000000000" | bc -l)
# Since migration 11 a batch appends its sequence ranges and the worker merges them later, in a
# compaction every 20,000 ranges or 30 s (after this drain, mostly): that merge is the drain's
# cost too. Measured here over the ranges the drain appended (the backend's CPU around the one
# statement) and added to the worker's side of both CPU ratios below. 0 for a worker without it.
COMPACT_S=0
if [[ $(psql_q "SELECT to_regproc('fleet_compact_sequence_ranges') IS NOT NULL") == t ]]; then
  APPENDED=$(psql_q "SELECT count(*) FROM sequence_ranges_new")
  HZ=$(getconf CLK_TCK)
  psql -X -A -t -q -v ON_ERROR_STOP=1 "$CONNINFO" >"$WORK/compact.out" <<SQL
SELECT pg_backend_pid() AS compact_pid \gset
\setenv COMPACT_PID :compact_pid
\! cat /proc/\$COMPACT_PID/stat >$WORK/compact-before.stat
SELECT fleet_compact_sequence_ranges();
\! cat /proc/\$COMPACT_PID/stat >$WORK/compact-after.stat
SQL
  COMPACT_S=$(echo "$(awk -v hz="$HZ" '{ print ($14 + $15) / hz }' "$WORK/compact-after.stat") - $(awk -v hz="$HZ" '{ print ($14 + $15) / hz }' "$WORK/compact-before.stat")" | bc -l)
  printf 'range compaction            %d appended ranges -> %d merged: %.2f s of its backend'"'"'s CPU (%.2f us per row; in the worker'"'"'s CPU below)\n' \
    "$APPENDED" "$(psql_q "SELECT count(*) FROM sequence_ranges_merged")" "$COMPACT_S" "$(echo "$COMPACT_S * 1000000 / $EXPECTED" | bc -l)"
fi
ROWS=$(psql_q "SELECT (SELECT count(*) FROM telemetry_samples) + (SELECT count(*) FROM rides) + (SELECT count(*) FROM lock_events) + (SELECT count(*) FROM pack_snapshots) + (SELECT count(*) FROM device_info)")
echo "backlog                     $MESSAGES messages, $EXPECTED records"
echo "accounted / rows            $GOT / $ROWS (gaps: $("$FLEETGW" ingest --gaps --pg "$CONNINFO" 2>/dev/null | wc -l))"
printf 'drained in                  %.1f s (worker start-up included)\n' "$S"
printf 'committed                   %.0f messages/s, %.0f records/s (%.0f messages/s per worker)\n' \
  "$(echo "$MESSAGES / $S" | bc -l)" "$(echo "$EXPECTED / $S" | bc -l)" "$(echo "$MESSAGES / $S / $NWORKERS" | bc -l)"
printf 'CPU ingest / PostgreSQL     %.1f s / %.1f s (its connections %.1f s)\n' "$(echo "$I1 - $I0" | bc -l)" "$(echo "$P1 - $P0" | bc -l)" "$PB1"
printf 'worker RSS peak / at end     %.1f MB / %.1f MB (all its processes; PSS at end %.1f MB)\n' \
  "$(echo "$RSS_PEAK / 1024" | bc -l)" "$(echo "$RSS_END / 1024" | bc -l)" "$(echo "$PSS_END / 1024" | bc -l)"
# First commit to the poll that saw the last one: the drain without the worker's start-up. The
# start is the rows' own committed_at_us (the database's clock as a batch is written, the same
# host clock as `date`), the end this script's clock when every record was accounted for (up to
# one 0.1 s poll late: against the worker).
COMMIT_S=$(psql_q "SELECT greatest($T1 / 1000 - min(n), 1) / 1e6 FROM (SELECT min(committed_at_us) n FROM telemetry_samples UNION ALL SELECT min(committed_at_us) FROM lock_events UNION ALL SELECT min(committed_at_us) FROM pack_snapshots) t")
printf 'first to last commit        %.2f s: %.0f records/s\n' "$COMMIT_S" "$(echo "$EXPECTED / $COMMIT_S" | bc -l)"

# The same rows by a plain COPY loader into database "loader" of the same cluster.
LOADER_DB="${CONNINFO/dbname=postgres/dbname=loader}"
TABLES="telemetry_samples rides lock_events pack_snapshots device_info status vehicle_state"
psql_q "CREATE DATABASE loader"
pg_dump --schema-only "$CONNINFO" | psql -X -q -v ON_ERROR_STOP=1 "$LOADER_DB" >/dev/null
LOADED=0
: >"$WORK/loader.sql"
# One transaction; the loader's own backend's CPU is read from /proc before psql ends.
printf 'SELECT pg_backend_pid() AS loader_pid \\gset\n\\setenv LOADER_PID :loader_pid\nBEGIN;\n' >>"$WORK/loader.sql"
for t in $TABLES; do
  psql_q "\copy (SELECT * FROM $t) TO '$WORK/$t.copy'"
  LOADED=$((LOADED + $(wc -l <"$WORK/$t.copy")))
  echo "\copy $t FROM '$WORK/$t.copy'" >>"$WORK/loader.sql"
done
WROTE=$(psql_q "SELECT (SELECT count(*) FROM telemetry_samples) + (SELECT count(*) FROM rides) + (SELECT count(*) FROM lock_events) + (SELECT count(*) FROM pack_snapshots) + (SELECT count(*) FROM device_info) + (SELECT count(*) FROM status) + (SELECT count(*) FROM vehicle_state)")
printf 'COMMIT;\n\\! cat /proc/$LOADER_PID/stat >%s\n' "$WORK/loader-backend.stat" >>"$WORK/loader.sql"
perf_start loader
L0=$(date +%s%N)
LP0=$(pg_cpu_s)
/usr/bin/python3 bench/cputime.py "$WORK/loader.cpu" psql -X -q -v ON_ERROR_STOP=1 \
  -f "$WORK/loader.sql" "$LOADER_DB"
L1=$(date +%s%N)
LP1=$(pg_cpu_s)
perf_stop
LB=$(awk -v hz="$(getconf CLK_TCK)" '{ print ($14 + $15) / hz }' "$WORK/loader-backend.stat")
LS=$(echo "($L1 - $L0) / 1000000000" | bc -l)
LC=$(awk '{ print $1 + $2 }' "$WORK/loader.cpu")
W_RATE=$(echo "$WROTE / $COMMIT_S" | bc -l)
L_RATE=$(echo "$LOADED / $LS" | bc -l)
W_CPU=$(echo "($I1 - $I0 + $P1 - $P0 + $COMPACT_S) * 1000000 / $WROTE" | bc -l)
L_CPU=$(echo "($LC + $LP1 - $LP0) * 1000000 / $LOADED" | bc -l)
printf 'COPY loader, same rows       %d rows in %.2f s: %.0f rows/s; CPU psql / PostgreSQL %.2f s / %.2f s\n' \
  "$LOADED" "$LS" "$L_RATE" "$LC" "$(echo "$LP1 - $LP0" | bc -l)"
W_OWN=$(echo "($I1 - $I0 + $PB1 + $COMPACT_S) * 1000000 / $WROTE" | bc -l)
L_OWN=$(echo "($LC + $LB) * 1000000 / $LOADED" | bc -l)
printf 'worker vs COPY loader        %.0f vs %.0f rows/s (%.0f %%, worker first to last commit); CPU %.1f vs %.1f us per row (%.2fx)\n' \
  "$W_RATE" "$L_RATE" "$(echo "100 * $W_RATE / $L_RATE" | bc -l)" "$W_CPU" "$L_CPU" \
  "$(echo "$W_CPU / $L_CPU" | bc -l)"
printf 'CPU per row, own backends    worker %.1f (process %.1f + PostgreSQL %.1f) vs loader %.1f (psql %.1f + PostgreSQL %.1f) us per row (%.2fx)\n' \
  "$W_OWN" "$(echo "($I1 - $I0) * 1000000 / $WROTE" | bc -l)" "$(echo "($PB1 + $COMPACT_S) * 1000000 / $WROTE" | bc -l)" \
  "$L_OWN" "$(echo "$LC * 1000000 / $LOADED" | bc -l)" "$(echo "$LB * 1000000 / $LOADED" | bc -l)" \
  "$(echo "$W_OWN / $L_OWN" | bc -l)"
if [[ ${PERF:-0} == 1 ]]; then
  echo "pg_stat_statements, drain (server time per statement kind, all databases)"
  psql_q "CREATE EXTENSION IF NOT EXISTS pg_stat_statements"
  psql -X -q -v ON_ERROR_STOP=1 "$CONNINFO" -c "SELECT round(total_exec_time::numeric, 0) AS ms, calls, rows, round((1000 * total_exec_time / greatest(rows, 1))::numeric, 2) AS us_per_row, left(regexp_replace(query, '\s+', ' ', 'g'), 70) AS statement FROM pg_stat_statements ORDER BY total_exec_time DESC LIMIT 14" | sed 's/^/  /'
fi
perf_summary drain fleetgw-ingest
perf_summary loader psql
[[ $GOT -ge $EXPECTED && $ROWS == "$EXPECTED" ]] || { echo "ingest-drain: NOT exactly once"; exit 1; }
