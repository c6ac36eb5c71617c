#!/usr/bin/env bash
# GBFS vehicle_status.json for a fleet of N registered vehicles (issue 27, docs/standards.md):
# time to build it (first build: every public id created; later builds: the feed's 1 s cache
# expired), its bytes plain and gzip, and requests per second served when clients send the
# ETag they hold (304s) and when they do not (200s from the cache).
#
#   bench/gbfs-feeds.sh BUILD_DIR [VEHICLES=10000] [SECONDS=5] [CLIENTS=4]
#
# The database is a private PostgreSQL cluster (bench/ingest-lib.sh) with the ingest's schema
# (fleetgw-ingest's own migrations) filled by INSERT ... SELECT generate_series: one
# vehicle_state and status row per vehicle as the ingest writes them, 5 % low on battery, 2 %
# riding, and 20 rides each of a fifth of the fleet (the measured energy per km). Driving 10,000
# simulated gateways would measure the ingest, not the feed.
set -euo pipefail
BUILD=$(realpath "${1:?usage: bench/gbfs-feeds.sh BUILD_DIR [VEHICLES] [SECONDS] [CLIENTS]}")
N=${2:-10000}
SECS=${3:-5}
CLIENTS=${4:-4}
FLEETGW=$BUILD/bin/fleetgw-serve  # ingest-lib.sh checks it and fleetgw-ingest beside it
SERVE=$BUILD/bin/fleetgw-serve
[[ -x $SERVE ]] || { echo "gbfs bench: no $SERVE" >&2; exit 1; }
source "$(dirname "$0")/ingest-lib.sh"
start_postgres
"$BUILD/bin/fleetgw-ingest" --gaps --pg "$CONNINFO" >"$WORK/ingest-schema.log" 2>&1
PROVIDER=3c95765d-4da6-41c6-b61e-1954472ec6c9
printf 'vehicle_type_id,name,form_factor,propulsion_type,max_speed_kph,battery_capacity_wh,wh_per_km\nebike,City e-bike,bicycle,electric_assist,25,500,10\n' >"$WORK/types.csv"
"$SERVE" --pg "$CONNINFO" --import-vehicle-types "$WORK/types.csv" >/dev/null
# The console schema exists now (the import migrated it): the registry and the ingest's rows.
psql_q "
INSERT INTO registry_vehicles (vehicle_id, device_id, vehicle_type_id, provider_id, created_at_us, updated_at_us)
  SELECT 'bike-' || i, gen_random_uuid(), 'ebike', '$PROVIDER', 0, 0 FROM generate_series(1, $N) i;
INSERT INTO vehicle_state (vehicle_id, updated_at_us, online, mode, soc_pct, range_m, lat_e7, lon_e7)
  SELECT 'bike-' || i, fleet_now_us(), true,
         CASE WHEN i % 50 = 0 THEN 'VEHICLE_MODE_RIDING' ELSE 'VEHICLE_MODE_PARKED' END,
         CASE WHEN i % 20 = 0 THEN 12 ELSE 30 + i % 70 END, 20000,
         481000000 + (i * 7919) % 1000000, 115000000 + (i * 104729) % 1000000
  FROM generate_series(1, $N) i;
INSERT INTO status (vehicle_id, created_at_us, online, connection, outbox_depth, bus_state,
                    firmware_version, last_will, attention)
  SELECT 'bike-' || i, fleet_now_us(), 'ONLINE_STATE_ONLINE', 'CONNECTION_STATE_CONNECTED', 0,
         'BUS_STATE_ACTIVE', '0.1.0', false, '{}' FROM generate_series(1, $N) i;
INSERT INTO rides (vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, ride_id,
                   started_at_us, ended_at_us, distance_odo_m, energy_mwh)
  SELECT 'bike-' || i, 's', r, 0, '0.1.0', 'r' || r, 1000000 * r, 1000000 * r + 600000000,
         2000 + r * 10, 20000 + r * 150
  FROM generate_series(1, $N, 5) i, generate_series(1, 20) r;
ANALYZE;"
PORT=$(free_port)
"$SERVE" --pg "$CONNINFO" --listen "127.0.0.1:$PORT" --threads 16 --db-connections 4 \
  --provider-id "$PROVIDER" >"$WORK/serve.log" 2>&1 &
SERVE_PID=$!
PIDS+=("$SERVE_PID")
wait_port "$PORT"
URL="http://127.0.0.1:$PORT/gbfs/vehicle_status.json"

first=$(curl -s -o "$WORK/status.json" -w '%{time_total}' "$URL")
sleep 1.1
second=$(curl -s -o "$WORK/status2.json" -w '%{time_total}' "$URL")
builds=()
for _ in 1 2 3 4 5; do sleep 1.05; builds+=("$(curl -s -o /dev/null -w '%{time_total}' "$URL")"); done
listed=$(python3 -c "import json,sys; print(len(json.load(open('$WORK/status.json'))['data']['vehicles']))")
plain=$(wc -c <"$WORK/status.json")
gz=$(gzip -9 -c "$WORK/status.json" | wc -c)
etag=$(curl -s -D - -o /dev/null "$URL" | awk 'tolower($1) == "etag:" { sub(/\r$/, ""); sub(/^[^:]*: /, ""); print }')

# Requests per second: CLIENTS processes, each one keep-alive connection, for SECS seconds.
rps() {  # $1: the If-None-Match header value ("" for none)
  python3 - "$PORT" "$SECS" "$CLIENTS" "$1" <<'EOF'
import http.client, multiprocessing, sys, time
port, secs, clients, etag = int(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
def run(q):
    c = http.client.HTTPConnection("127.0.0.1", port)
    h = {"If-None-Match": etag} if etag else {}
    n = {200: 0, 304: 0, "other": 0}
    end = time.monotonic() + secs
    while time.monotonic() < end:
        c.request("GET", "/gbfs/vehicle_status.json", headers=h)
        r = c.getresponse(); r.read()
        n[r.status if r.status in n else "other"] += 1
    q.put(n)
q = multiprocessing.Queue()
ps = [multiprocessing.Process(target=run, args=(q,)) for _ in range(clients)]
for p in ps: p.start()
tot = {200: 0, 304: 0, "other": 0}
for _ in ps:
    for k, v in q.get().items(): tot[k] += v
for p in ps: p.join()
print(f"{(tot[200] + tot[304] + tot['other']) / secs:.0f} req/s (200: {tot[200]}, 304: {tot[304]}, other: {tot['other']})")
EOF
}
cpu0=$(cpu_s "$SERVE_PID"); pg0=$(pg_cpu_s)
hits=$(rps "$etag")
cpu1=$(cpu_s "$SERVE_PID"); pg1=$(pg_cpu_s)
full=$(rps "")
cpu2=$(cpu_s "$SERVE_PID"); pg2=$(pg_cpu_s)

echo "vehicle_status.json, $N registered vehicles ($listed listed: riding ones left out)"
echo "  first build (every public id created): ${first} s; next: ${second} s; later builds: ${builds[*]} s"
echo "  bytes: $plain plain, $gz gzip -9"
echo "  with the ETag (304):  $hits; serve CPU $(echo "$cpu1 - $cpu0" | bc) s, PostgreSQL CPU $(echo "$pg1 - $pg0" | bc) s over ${SECS} s"
echo "  without it (200):     $full; serve CPU $(echo "$cpu2 - $cpu1" | bc) s, PostgreSQL CPU $(echo "$pg2 - $pg1" | bc) s over ${SECS} s"
