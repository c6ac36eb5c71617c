#!/usr/bin/env bash
# Issue 28's console figures with N vehicles in the database (default 10,000): the console's
# first load in Debian's chromium (time from navigation to every bike drawn on the map, bytes
# received, cache off), and GET /api/fleet requests per second one fleetgw serve sustains with
# its CPU time (tests/web/fleet_list_rate.py, C keep-alive clients for S seconds).
#   FLEETGW=$PWD/build/bin/fleetgw bench/console-load.sh [N] [C] [S]
# Needs root (PostgreSQL runs as postgres), node/npm/chromium (tests/web/browser).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
FLEETGW=${FLEETGW:-$here/../build/bin/fleetgw}
n=${1:-10000}
clients=${2:-2}
seconds=${3:-10}
source "$here/ingest-lib.sh"
start_postgres
bin=$(dirname "$FLEETGW")
"$bin/fleetgw-ingest" --gaps --pg "$CONNINFO" >"$WORK/schema.log" 2>&1
# N parked bikes on a 100 x N/100 grid around Munich, each with its retained status; 1 in 10
# low on battery, 1 in 20 offline.
psql_q "INSERT INTO vehicle_state (vehicle_id, updated_at_us, online, mode, soc_pct, range_m,
  lat_e7, lon_e7) SELECT 'bike-' || i, 1, true, 'VEHICLE_MODE_PARKED',
  CASE WHEN i % 10 = 0 THEN 12 ELSE 80 END, 20000, 481000000 + (i / 100) * 5000,
  115000000 + (i % 100) * 8000 FROM generate_series(1, $n) i"
psql_q "INSERT INTO status (vehicle_id, created_at_us, online, connection, outbox_depth,
  bus_state, firmware_version, last_will, attention) SELECT 'bike-' || i, 1,
  CASE WHEN i % 20 = 0 THEN 'ONLINE_STATE_OFFLINE' ELSE 'ONLINE_STATE_ONLINE' END,
  'CONNECTION_STATE_CONNECTED', 0, 'BUS_STATE_ACTIVE', '0.1.0', false, '{}'
  FROM generate_series(1, $n) i"
port=$(free_port)
printf 'bench-password\n' | "$bin/fleetgw-serve" --pg "$CONNINFO" --add-operator bench --role viewer >/dev/null
"$bin/fleetgw-serve" --pg "$CONNINFO" --listen "127.0.0.1:$port" >"$WORK/serve.log" 2>&1 &
serve=$!
PIDS+=("$serve")
wait_port "$port"
echo "vehicles: $n; fleetgw-serve $(file -b "$bin/fleetgw-serve" | grep -o 'not stripped\|stripped' | head -1), load $(cut -d' ' -f1-3 /proc/loadavg)"
spec="{\"url\":\"http://127.0.0.1:$port\",\"name\":\"bench\",\"password\":\"bench-password\",\"vehicles\":$n}"
"$here/../tests/web/browser/console-browser.sh" --script console_load.mjs "$spec"
python3 "$here/../tests/web/fleet_list_rate.py" "$port" "$serve" "$clients" "$seconds" bench bench-password
