#!/usr/bin/env bash
# The per-batch vehicle_state upsert alone (issue 25): PostgreSQL backend CPU of ROUNDS batches
# of 1,000 upserts over 2,000 vehicles, the statement as the worker prepares it (text[] columns
# cast, ON CONFLICT ... DO UPDATE ... WHERE newer), into the ingest's schema (migrated by
# fleetgw-ingest) at the table's fillfactor (migration 10: 70) and at PostgreSQL's default 100.
# Backend CPU from /proc around the executes only (the arrays are built first); 10 ms ticks.
# A benchmark, not a test; root. Environment: FLEETGW (build/bin/fleetgw: fleetgw-ingest beside
# it), ROUNDS (40), REPEAT (2: each fillfactor this many times, alternating).
set -euo pipefail
cd "$(dirname "$0")/.."
INGEST=$(dirname "$(realpath -m "${FLEETGW:-build/bin/fleetgw}")")/fleetgw-ingest
[[ -x $INGEST ]] || { echo "no $INGEST" >&2; exit 1; }
ROUNDS=${ROUNDS:-40}
PGBIN=$(ls -d /usr/lib/postgresql/*/bin | sort -V | tail -1)
W=$(mktemp -d /tmp/fleetgw-upsert-XXXXXX)
chmod 755 "$W"
mkdir "$W/pg" "$W/sock"
chown postgres "$W/pg" "$W/sock"
runuser -u postgres -- "$PGBIN/initdb" -D "$W/pg" -A trust -U fleet -E UTF8 --locale=C >/dev/null
PORT=$(/usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
runuser -u postgres -- "$PGBIN/pg_ctl" -D "$W/pg" -l "$W/sock/pg.log" -w \
  -o "-k $W/sock -p $PORT -c listen_addresses=''" start >/dev/null
trap 'runuser -u postgres -- "$PGBIN/pg_ctl" -D "$W/pg" -m immediate stop >/dev/null; rm -rf "$W"' EXIT
C="host=$W/sock port=$PORT user=fleet"
COLS="vehicle_id, updated_at_us, online, mode, soc_pct, range_m, odo_m, lat_e7, lon_e7, locks, faults, active_alarms, speed_limit_dkmh, assist, assist_name, bus_state, position_fixed_at_us, horizontal_error_dm, heading_ddeg"
TYPES="text, bigint, boolean, text, integer, integer, bigint, integer, integer, jsonb, jsonb, text[], integer, integer, text, text, bigint, integer, integer"
IFS=', ' read -r -a T <<<"$(echo "$TYPES" | tr -d ',')"
SEL=""; FROM=""; NAMES=""; SETS="received_at_us = fleet_now_us()"
i=0
for col in ${COLS//,/}; do
  SEL+="${SEL:+, }u.c$i::${T[$i]}"; FROM+="${FROM:+, }\$$((i + 1))::text[]"; NAMES+="${NAMES:+, }c$i"
  [[ $col == vehicle_id ]] || SETS+=", $col = EXCLUDED.$col"
  i=$((i + 1))
done
STMT="INSERT INTO vehicle_state ($COLS) SELECT $SEL FROM unnest($FROM) AS u($NAMES) ON CONFLICT (vehicle_id) DO UPDATE SET $SETS WHERE EXCLUDED.updated_at_us >= vehicle_state.updated_at_us OR vehicle_state.updated_at_us > fleet_now_us() + 600000000"
script() {  # the SQL of one measurement
  echo "CREATE FUNCTION src(r int) RETURNS TABLE (c0 text[], c1 text[], c2 text[], c3 text[], c4 text[], c5 text[], c6 text[], c7 text[], c8 text[], c9 text[], c10 text[], c11 text[], c12 text[], c13 text[], c14 text[], c15 text[], c16 text[], c17 text[], c18 text[]) LANGUAGE sql AS \$\$
  SELECT array_agg('b-' || lpad(i::text, 5, '0') || '-0123456789abcdef'), array_agg((r * 10000000 + i)::text), array_agg('true'::text), array_agg('VEHICLE_MODE_RIDING'::text),
    array_agg((50 + r)::text), array_agg('12000'::text), array_agg((100000 + r * 50 + i)::text), array_agg((520000000 + r * 100 + i)::text), array_agg((134000000 + r * 100)::text),
    array_agg('[{\"node\": \"iot\", \"state\": \"LOCK_STATE_UNLOCKED\", \"state_name\": \"unlocked\"}]'::text), array_agg('[]'::text), array_agg('{}'::text), array_agg('250'::text), array_agg('2'::text), array_agg('eco'::text), array_agg('BUS_STATE_ACTIVE'::text),
    array_agg((r * 10000000)::text), array_agg('35'::text), array_agg('900'::text)
  FROM generate_series(1, 2000) i WHERE r = 0 OR (i + r) % 2 = 0 \$\$;"
  echo "PREPARE s($(printf 'text[],%.0s' $(seq 18))text[]) AS $STMT;"
  for r in $(seq 0 "$ROUNDS"); do
    echo "SELECT $(for c in $(seq 0 18); do printf '%sc%s a%s_%s' "$([[ $c == 0 ]] || echo ', ')" "$c" "$c" "$r"; done) FROM src($r) \\gset"
  done
  args() { for c in $(seq 0 18); do printf "%s:'a%s_%s'" "$([[ $c == 0 ]] || echo ', ')" "$c" "$1"; done; }
  echo "EXECUTE s($(args 0));"  # every vehicle's first state
  echo "SELECT pg_backend_pid() AS pid \\gset"
  echo "\\setenv PID :pid"
  echo "\\! awk '{ print \$14 + \$15 }' /proc/\$PID/stat >$W/cpu0"
  for r in $(seq 1 "$ROUNDS"); do echo "BEGIN; EXECUTE s($(args "$r")); COMMIT;"; done
  echo "\\! awk -v t0=\$(cat $W/cpu0) -v hz=$(getconf CLK_TCK) -v n=$((ROUNDS * 1000)) '{ printf \"%.1f us of backend CPU per upsert\\n\", (\$14 + \$15 - t0) / hz * 1e6 / n }' /proc/\$PID/stat"
}
script >"$W/upsert.sql"
for rep in $(seq "${REPEAT:-2}"); do
  for ff in 70 100; do
    db="u${ff}_$rep"
    psql -X -q "$C dbname=postgres" -c "CREATE DATABASE $db"
    "$INGEST" --gaps --pg "$C dbname=$db" >/dev/null 2>&1 || true  # migrates (no gaps to print)
    psql -X -q "$C dbname=$db" -c "ALTER TABLE vehicle_state SET (fillfactor = $ff)"
    printf 'fillfactor %3s: ' "$ff"
    psql -X -q -v ON_ERROR_STOP=1 "$C dbname=$db" -f "$W/upsert.sql"
  done
done
