# Shared set-up of the ingest benchmarks (bench/ingest-fleet.sh, bench/ingest-drain.sh), sourced:
# a private PostgreSQL cluster, a local mosquitto, `fleetgw ingest` workers, CPU counters.
# Expects FLEETGW (absolute path); defines WORK (removed on exit unless KEEP=1), CONNINFO,
# BROKER, BROKER_URI, WORKERS (pids), PGPID and the functions below.
[[ -x $FLEETGW && -x $(dirname "$FLEETGW")/fleetgw-ingest ]] ||
  { echo "ingest bench: no $FLEETGW (and fleetgw-ingest beside it)" >&2; exit 1; }
PGBIN=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -1)
[[ -n $PGBIN ]] || { echo "ingest bench: PostgreSQL server binaries not installed" >&2; exit 77; }
[[ $(id -u) == 0 ]] || { echo "ingest bench: run as root (PostgreSQL runs as postgres)" >&2; exit 1; }
ulimit -n "$(ulimit -Hn)"  # a socket per vehicle in the broker and the fleet-sim

WORK=$(mktemp -d /tmp/fleetgw-ingest-bench-XXXXXX)
chmod 755 "$WORK"
PIDS=()
WORKERS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
  runuser -u postgres -- "$PGBIN/pg_ctl" -D "$WORK/pg" -m immediate stop >/dev/null 2>&1 || true
  if [[ ${KEEP:-0} == 1 ]]; then echo "work directory: $WORK"; else rm -rf "$WORK"; fi
}
trap cleanup EXIT

free_port() {
  /usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}
# user + sys seconds of a process and its reaped children (/proc/PID/stat fields 14-17).
cpu_s() {
  awk -v hz="$(getconf CLK_TCK)" '{ print ($14 + $15 + $16 + $17) / hz }' "/proc/$1/stat" 2>/dev/null || echo 0
}
# The same over the PostgreSQL server: postmaster and every child.
pg_cpu_s() {
  local total=0 pid
  for pid in $PGPID $(pgrep -P "$PGPID"); do total=$(echo "$total + $(cpu_s "$pid")" | bc -l); done
  echo "$total"
}
workers_cpu_s() {
  local total=0 w
  for w in "${WORKERS[@]}"; do total=$(echo "$total + $(cpu_s "$w")" | bc -l); done
  echo "$total"
}
psql_q() { psql -X -A -t -q -v ON_ERROR_STOP=1 "$CONNINFO" -c "$1"; }

# PostgreSQL: a private cluster on a Unix socket, fsync on (BUILD-NOTES: initdb refuses root).
start_postgres() {
  mkdir -p "$WORK/pg" "$WORK/sock"
  chown postgres "$WORK/pg" "$WORK/sock"
  local port
  port=$(free_port)
  runuser -u postgres -- "$PGBIN/initdb" -D "$WORK/pg" -A trust -U fleet -E UTF8 --locale=C >"$WORK/initdb.log"
  runuser -u postgres -- "$PGBIN/pg_ctl" -D "$WORK/pg" -l "$WORK/sock/pg.log" -w \
    -o "-k $WORK/sock -p $port -c listen_addresses=''" start >/dev/null
  PGPID=$(head -1 "$WORK/pg/postmaster.pid")
  CONNINFO="host=$WORK/sock port=$port user=fleet dbname=postgres"
}

# mosquitto: MQTT 5, no connection limit, session queues deep enough for a backlog.
start_broker() {
  local port
  port=$(free_port)
  printf 'listener %s 127.0.0.1\nallow_anonymous true\nmax_connections -1\nmax_queued_messages 1000000\nset_tcp_nodelay true\n' \
    "$port" >"$WORK/mosquitto.conf"
  mosquitto -c "$WORK/mosquitto.conf" 2>"$WORK/mosquitto.log" &
  BROKER=$!
  PIDS+=("$BROKER")
  BROKER_URI="tcp://127.0.0.1:$port"
  for _ in $(seq 50); do
    (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null && break
    sleep 0.1
  done
}

# start_workers N: N workers of group "bench" (client ids bench-worker-1..N), subscribed.
start_workers() {
  local w
  WORKERS=()
  for w in $(seq "$1"); do
    "$FLEETGW" ingest --broker "$BROKER_URI" --group bench --client-id "bench-worker-$w" \
      --pg "$CONNINFO" >>"$WORK/worker-$w.log" 2>&1 &
    WORKERS+=("$!")
    PIDS+=("$!")
  done
  for w in $(seq "$1"); do
    for _ in $(seq 300); do
      [[ $(grep -c "subscribed to" "$WORK/worker-$w.log") -ge ${2:-1} ]] && break
      sleep 0.1
    done
    [[ $(grep -c "subscribed to" "$WORK/worker-$w.log") -ge ${2:-1} ]] || { cat "$WORK/worker-$w.log"; exit 1; }
  done
}
stop_workers() {
  local w
  for w in "${WORKERS[@]}"; do kill -TERM "$w"; done
  wait "${WORKERS[@]}" 2>/dev/null || true
}

# Records the fleet-sim says it created (sum of last_sequence over its stores).
expected_records() {
  /usr/bin/python3 -c 'import json,sys; print(sum(s["last_sequence"] for s in json.load(open(sys.argv[1]))["stores"]))' "$1"
}
accounted() { psql_q "SELECT coalesce(sum(last_seq - first_seq + 1), 0) FROM sequence_ranges"; }
