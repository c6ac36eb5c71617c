#!/usr/bin/env bash
# A simulated fleet through a real broker into PostgreSQL (issue 15, figures): `fleetgw
# fleet-sim` (VEHICLES vehicles, each its own MQTT 5 session, the default configuration's
# traffic, RIDING_SHARE of them riding) → a local mosquitto → two `fleetgw ingest` workers
# (shared subscription) → a private PostgreSQL cluster (fsync on). Reports:
#   records committed per second, and whether every record landed exactly once (the fleet-sim's
#     own count of records per store against the rows, and the gap report);
#   delay from a record's created_at_us to its committed row, p50/p99: records the gateway
#     publishes at once (rides, lock events, pack statistics, device info: broker + ingest +
#     commit), and telemetry samples (the gateway's batching included by design: a riding batch
#     leaves 5 s after its first sample (mqtt.batch_max_ms), a parked one after 300 s);
#   CPU seconds (user + sys, from /proc) of the broker, the two ingest workers, PostgreSQL's
#     processes and the fleet-sim itself, and as a share of one core;
#   MQTT PUBLISH bytes per vehicle per riding hour and per parked hour (counted by fleet-sim;
#     CONNECT, pings and acknowledgements excluded).
# A benchmark, not a test. Needs root (PostgreSQL runs as `postgres`, ulimit -n raised).
# Environment: FLEETGW (default build/gateway/app/fleetgw), VEHICLES (1000), DURATION_S (120;
#   600 is the issue's 10 minutes), RIDING_SHARE (0.3), WORKERS (2), KEEP=1 keeps the work
#   directory.
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=$(realpath "${FLEETGW:-build/gateway/app/fleetgw}")
VEHICLES=${VEHICLES:-1000}
DURATION_S=${DURATION_S:-120}
RIDING_SHARE=${RIDING_SHARE:-0.3}
NWORKERS=${WORKERS:-2}
source bench/ingest-lib.sh

start_postgres
start_broker
start_workers "$NWORKERS"

echo "ingest-fleet: $VEHICLES vehicles ($RIDING_SHARE riding) for $DURATION_S s -> mosquitto -> $NWORKERS ingest workers -> PostgreSQL"
B0=$(cpu_s "$BROKER"); I0=$(workers_cpu_s)
P0=$(pg_cpu_s)
START_US=$(($(date +%s%N) / 1000))
/usr/bin/time -f '%U %S' -o "$WORK/sim.time" "$FLEETGW" fleet-sim --vehicles "$VEHICLES" \
  --broker "$BROKER_URI" --duration-s "$DURATION_S" --riding-share "$RIDING_SHARE" \
  >"$WORK/sim.json" 2>"$WORK/sim.log" || { echo "fleet-sim failed:"; tail -5 "$WORK/sim.log"; }

# Every record the fleet created, accounted for in PostgreSQL (or 120 s of patience).
EXPECTED=$(expected_records "$WORK/sim.json")
for _ in $(seq 1200); do
  GOT=$(accounted)
  [[ $GOT -ge $EXPECTED ]] && break
  sleep 0.1
done
END_US=$(psql_q "SELECT max(committed_at_us) FROM (SELECT max(committed_at_us) AS committed_at_us FROM telemetry_samples UNION ALL SELECT max(committed_at_us) FROM pack_snapshots) t")
B1=$(cpu_s "$BROKER"); I1=$(workers_cpu_s)
P1=$(pg_cpu_s)
stop_workers

ROWS=$(psql_q "SELECT (SELECT count(*) FROM telemetry_samples) + (SELECT count(*) FROM rides) + (SELECT count(*) FROM lock_events) + (SELECT count(*) FROM pack_snapshots) + (SELECT count(*) FROM device_info)")
GAPS=$("$FLEETGW" ingest --gaps --pg "$CONNINFO" 2>/dev/null | wc -l)
WALL_S=$(echo "($END_US - $START_US) / 1000000" | bc -l)
pct() {  # p50/p99 in ms of a delay column expression over a FROM clause
  psql_q "SELECT round((percentile_cont(0.5) WITHIN GROUP (ORDER BY d) / 1000)::numeric, 1) || ' / ' || round((percentile_cont(0.99) WITHIN GROUP (ORDER BY d) / 1000)::numeric, 1) || ' ms (n=' || count(*) || ')' FROM ($1) q"
}
RECORDS="SELECT created_at_us, committed_at_us FROM rides UNION ALL SELECT created_at_us, committed_at_us FROM lock_events UNION ALL SELECT created_at_us, committed_at_us FROM pack_snapshots UNION ALL SELECT created_at_us, committed_at_us FROM device_info"
RECORD_DELAY=$(pct "SELECT committed_at_us - created_at_us AS d FROM ($RECORDS) r")
# After the fleet's 30 s boot spread and a minute of running: the steady state.
STEADY_DELAY=$(pct "SELECT committed_at_us - created_at_us AS d FROM ($RECORDS) r WHERE created_at_us > $START_US + 60000000")
FIRST_DELAY=$(pct "SELECT committed_at_us - created_at_us AS d FROM telemetry_samples")
SIM_CPU=$(awk '{ print $1 + $2 }' "$WORK/sim.time")
read -r RIDING_N PARKED_N RIDE_B PARK_B SIM_S UNACKED CONNECTED < <(/usr/bin/python3 -c '
import json, sys
r = json.load(open(sys.argv[1]))
print(r["riding"], r["vehicles"] - r["riding"], r["riding_packet_bytes"], r["parked_packet_bytes"], r["duration_s"], r["unacknowledged"], r["connected"])' "$WORK/sim.json")
share() { echo "scale=2; 100 * ($1) / $WALL_S" | bc -l; }
per_hour() { [[ $2 -gt 0 ]] && echo "scale=0; $1 * 3600 / $2 / $SIM_S" | bc -l || echo "-"; }

echo "vehicles connected          $CONNECTED of $VEHICLES ($RIDING_N riding, $PARKED_N parked), unacknowledged publishes $UNACKED"
echo "records created / in PG     $EXPECTED / $ROWS rows ($GOT accounted), gaps: $GAPS"
printf 'records committed           %.0f /s over %.0f s (first record to last commit)\n' "$(echo "$EXPECTED / $WALL_S" | bc -l)" "$WALL_S"
echo "delay record -> row         $RECORD_DELAY (rides, locks, packs, info; whole run)"
echo "  the same after 60 s        $STEADY_DELAY"
echo "delay telemetry sample      $FIRST_DELAY (created_at_us of its batch, batching wait included)"
printf 'CPU broker                  %.1f s (%.1f %% of a core)\n' "$(echo "$B1 - $B0" | bc -l)" "$(share "$B1 - $B0")"
printf 'CPU ingest (%s workers)      %.1f s (%.1f %% of a core)\n' "$NWORKERS" "$(echo "$I1 - $I0" | bc -l)" "$(share "$I1 - $I0")"
printf 'CPU PostgreSQL              %.1f s (%.1f %% of a core)\n' "$(echo "$P1 - $P0" | bc -l)" "$(share "$P1 - $P0")"
printf 'CPU fleet-sim               %.1f s\n' "$SIM_CPU"
echo "bytes/vehicle/riding hour   $(per_hour "$RIDE_B" "$RIDING_N") B (MQTT PUBLISH packets)"
echo "bytes/vehicle/parked hour   $(per_hour "$PARK_B" "$PARKED_N") B (MQTT PUBLISH packets)"
[[ $GAPS == 0 && $ROWS == "$EXPECTED" && $UNACKED == 0 ]] || { echo "ingest-fleet: NOT exactly once"; exit 1; }
