#!/usr/bin/env bash
# Issue 28's first-load figure, two builds side by side in one run: the same PostgreSQL with N
# vehicles (bench/console-load.sh's rows), served in turn by fleetgw-serve from BEFORE_DIR with
# the console files of BEFORE_STATIC, and by the one of AFTER_DIR with AFTER_STATIC (default:
# the source tree's). For each: the console's first load in Debian's chromium (navigation to
# every bike drawn, bytes received, cache off; browser/console_load.mjs), then GET /api/fleet and
# GET /api/fleet?view=compact requests per second with the server's CPU
# (tests/web/fleet_list_rate.py, C keep-alive clients for S seconds). The two runs alternate
# ROUNDS times so a load change on the machine hits both alike.
#   tests/web/console_load_compare.sh BEFORE_DIR BEFORE_STATIC AFTER_DIR [N] [C] [S] [ROUNDS]
# Needs root (PostgreSQL runs as postgres) and node/npm/chromium (tests/web/browser).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
before_dir=$1
before_static=$2
after_dir=$3
n=${4:-10000}
clients=${5:-2}
seconds=${6:-10}
rounds=${7:-2}
after_static=${AFTER_STATIC:-$here/../../backend/web/static}
export FLEETGW=$after_dir/fleetgw-ingest  # ingest-lib.sh wants fleetgw-ingest beside it
source "$here/../../bench/ingest-lib.sh"
start_postgres
base=$CONNINFO
# One database per build (same rows): each server migrates its own console tables, and an
# older build refuses a newer console schema.
setup_db() {  # NAME BIN_DIR
  psql -X -q -v ON_ERROR_STOP=1 "$base" -c "CREATE DATABASE $1" >/dev/null
  CONNINFO="${base% dbname=*} dbname=$1"
  "$after_dir/fleetgw-ingest" --gaps --pg "$CONNINFO" >"$WORK/schema-$1.log" 2>&1
  psql_q "INSERT INTO vehicle_state (vehicle_id, updated_at_us, online, mode, soc_pct, range_m,
    lat_e7, lon_e7) SELECT 'bike-' || i, 1, true, 'VEHICLE_MODE_PARKED',
    CASE WHEN i % 10 = 0 THEN 12 ELSE 80 END, 20000, 481000000 + (i / 100) * 5000,
    115000000 + (i % 100) * 8000 FROM generate_series(1, $n) i"
  psql_q "INSERT INTO status (vehicle_id, created_at_us, online, connection, outbox_depth,
    bus_state, firmware_version, last_will, attention) SELECT 'bike-' || i, 1,
    CASE WHEN i % 20 = 0 THEN 'ONLINE_STATE_OFFLINE' ELSE 'ONLINE_STATE_ONLINE' END,
    'CONNECTION_STATE_CONNECTED', 0, 'BUS_STATE_ACTIVE', '0.1.0', false, '{}'
    FROM generate_series(1, $n) i"
  printf 'bench-password\n' | "$2/fleetgw-serve" --pg "$CONNINFO" --add-operator bench \
    --role viewer >/dev/null
}
setup_db before "$before_dir"
setup_db after "$after_dir"
"$here/browser/console-browser.sh" --install
echo "vehicles: $n; load $(cut -d' ' -f1-3 /proc/loadavg)"
run_one() {  # NAME BIN_DIR STATIC_DIR
  local port serve
  port=$(free_port)
  "$2/fleetgw-serve" --pg "${base% dbname=*} dbname=$1" --listen "127.0.0.1:$port" --static-dir "$3" \
    >"$WORK/serve-$1.log" 2>&1 &
  serve=$!
  PIDS+=("$serve")
  # Up to 60 s (wait_port's 10 s is short for a Debug build on a loaded machine).
  for _ in $(seq 600); do
    (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null && break
    kill -0 "$serve" 2>/dev/null || { cat "$WORK/serve-$1.log" >&2; exit 1; }
    sleep 0.1
  done
  local spec="{\"url\":\"http://127.0.0.1:$port\",\"name\":\"bench\",\"password\":\"bench-password\",\"vehicles\":$n}"
  echo "$1: first load $("$here/browser/console-browser.sh" --script console_load.mjs "$spec")"
  echo "$1: /api/fleet $(python3 "$here/fleet_list_rate.py" "$port" "$serve" "$clients" \
    "$seconds" bench bench-password)"
  echo "$1: /api/fleet?view=compact $(python3 "$here/fleet_list_rate.py" "$port" "$serve" \
    "$clients" "$seconds" bench bench-password '/api/fleet?view=compact')"
  kill "$serve"
  wait "$serve" 2>/dev/null || true
}
for ((r = 1; r <= rounds; r++)); do
  run_one before "$before_dir" "$before_static"
  run_one after "$after_dir" "$after_static"
done
