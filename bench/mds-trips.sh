#!/usr/bin/env bash
# MDS /trips for a day of a fleet of N vehicles (issue 27, docs/standards.md): the response time
# of each hour of yesterday (UTC), as an agency pulls them.
#
#   bench/mds-trips.sh BUILD_DIR [VEHICLES=1000] [RIDES_PER_VEHICLE=10]
#
# The database is a private PostgreSQL cluster (bench/ingest-lib.sh) with the ingest's schema,
# filled by INSERT ... SELECT generate_series with ride records as the ingest stores them
# (10-minute rides spread over the day, positions and distances set) and one telemetry sample
# per 10 s of each ride (the route /mds/telemetry serves): realistic rows, without the hours a
# simulated fleet would take to ride them.
set -euo pipefail
BUILD=$(realpath "${1:?usage: bench/mds-trips.sh BUILD_DIR [VEHICLES] [RIDES_PER_VEHICLE]}")
N=${2:-1000}
R=${3:-10}
FLEETGW=$BUILD/bin/fleetgw-serve  # ingest-lib.sh checks it and fleetgw-ingest beside it
SERVE=$BUILD/bin/fleetgw-serve
[[ -x $SERVE ]] || { echo "mds bench: no $SERVE" >&2; exit 1; }
source "$(dirname "$0")/ingest-lib.sh"
start_postgres
"$BUILD/bin/fleetgw-ingest" --gaps --pg "$CONNINFO" >"$WORK/ingest-schema.log" 2>&1
PROVIDER=3c95765d-4da6-41c6-b61e-1954472ec6c9
printf 'vehicle_type_id,form_factor,propulsion_type,battery_capacity_wh,wh_per_km\nebike,bicycle,electric_assist,500,10\n' >"$WORK/types.csv"
"$SERVE" --pg "$CONNINFO" --import-vehicle-types "$WORK/types.csv" >/dev/null
TOKEN=$("$SERVE" --pg "$CONNINFO" --add-mds-agency bench-city | tail -1)
DAY_US=$(( ($(date +%s) / 86400 - 1) * 86400 * 1000000 ))
psql_q "
INSERT INTO registry_vehicles (vehicle_id, device_id, vehicle_type_id, provider_id, created_at_us, updated_at_us)
  SELECT 'bike-' || i, gen_random_uuid(), 'ebike', '$PROVIDER', 0, 0 FROM generate_series(1, $N) i;
INSERT INTO rides (vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, ride_id,
                   started_at_us, ended_at_us, distance_odo_m, energy_mwh, soc_start_pct,
                   soc_end_pct, start_lat_e7, start_lon_e7, end_lat_e7, end_lon_e7)
  SELECT 'bike-' || i, 's', r, 0, '0.1.0', 'r' || r,
         $DAY_US + ((i * 104729 + r * 7919) % 85800) * 1000000::bigint,
         $DAY_US + ((i * 104729 + r * 7919) % 85800) * 1000000::bigint + 600000000,
         2400, 24000, 90, 85, 481000000 + i, 115000000 + r, 481100000 + i, 115100000 + r
  FROM generate_series(1, $N) i, generate_series(1, $R) r;
INSERT INTO telemetry_samples (vehicle_id, store_id, sequence, created_at_us, sampled_at_us,
                               speed_dkmh, soc_pct, lat_e7, lon_e7)
  SELECT vehicle_id, 's', sequence * 100 + k, started_at_us, started_at_us + k * 10000000, 180,
         88, start_lat_e7 + k * 100, start_lon_e7 + k * 100
  FROM rides, generate_series(0, 59) k;
ANALYZE;"
rides=$(psql_q "SELECT count(*) FROM rides")
samples=$(psql_q "SELECT count(*) FROM telemetry_samples")
PORT=$(free_port)
"$SERVE" --pg "$CONNINFO" --listen "127.0.0.1:$PORT" --provider-id "$PROVIDER" >"$WORK/serve.log" 2>&1 &
SERVE_PID=$!
PIDS+=("$SERVE_PID")
wait_port "$PORT"

times=()
count=0
for h in $(seq 0 23); do
  hour=$(date -u -d "@$(( DAY_US / 1000000 + h * 3600 ))" +%Y-%m-%dT%H)
  t=$(curl -s -o "$WORK/trips-$h.json" -w '%{time_total}' \
        -H "Authorization: Bearer $TOKEN" -H 'Accept: application/vnd.mds+json;version=2.0' \
        "http://127.0.0.1:$PORT/mds/trips?end_time=$hour")
  n=$(python3 -c "import json; print(len(json.load(open('$WORK/trips-$h.json'))['trips']))")
  count=$((count + n))
  times+=("$t")
done
tel=$(curl -s -o "$WORK/telemetry.json" -w '%{time_total}' \
        -H "Authorization: Bearer $TOKEN" \
        "http://127.0.0.1:$PORT/mds/telemetry?telemetry_time=$(date -u -d "@$(( DAY_US / 1000000 + 12 * 3600 ))" +%Y-%m-%dT%H)")
echo "MDS /trips, a day of $N vehicles: $rides rides, $samples telemetry samples in the database"
echo "  24 hourly requests returned $count trips on their first pages (page size 1000)"
printf '%s\n' "${times[@]}" | sort -n | awk '{ t[NR] = $1; s += $1 } END {
  printf "  response time per hour: min %.3f s, median %.3f s, max %.3f s, all 24: %.2f s\n", t[1], t[int((NR + 1) / 2)], t[NR], s }'
echo "  /mds/telemetry for 12:00 (first page of 1000 samples): ${tel} s"
