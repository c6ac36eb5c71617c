# Shared set-up of the ingest benchmarks (bench/ingest-fleet.sh, bench/ingest-drain.sh), sourced:
# a private PostgreSQL cluster, a local mosquitto, `fleetgw ingest` workers, CPU counters.
# Expects FLEETGW (absolute path); defines WORK (removed on exit unless KEEP=1), CONNINFO,
# BROKER, BROKER_URI, WORKERS (pids), PGPID and the functions below.
# From a fresh clone (scripts/install-deps.sh run): the default FLEETGW is built first, a Release
# tree in build/ with the three programs the benchmarks run (BUILD=0 skips this).
if [[ ${BUILD:-1} == 1 && $FLEETGW == "$PWD/build/bin/fleetgw" &&
  ! ( -x $FLEETGW && -x build/bin/fleetgw-ingest && -x build/bin/fleetgw-fleet-sim ) ]]; then
  echo "ingest bench: building fleetgw, fleetgw-ingest and fleetgw-fleet-sim in build/ (Release)"
  cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DFLEETGW_BUILD_BENCH=OFF >"${TMPDIR:-/tmp}/fleetgw-bench-build.log" 2>&1 &&
    cmake --build build -j"$(nproc)" --target fleetgw fleetgw-ingest fleetgw-fleet-sim >>"${TMPDIR:-/tmp}/fleetgw-bench-build.log" 2>&1 ||
    { echo "ingest bench: the build failed (${TMPDIR:-/tmp}/fleetgw-bench-build.log)" >&2; exit 1; }
fi
[[ -x $FLEETGW && -x $(dirname "$FLEETGW")/fleetgw-ingest ]] ||
  { echo "ingest bench: no $FLEETGW (and fleetgw-ingest beside it)" >&2; exit 1; }
PGBIN=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -1)
[[ -n $PGBIN ]] || { echo "ingest bench: PostgreSQL server binaries not installed" >&2; exit 77; }
[[ $(id -u) == 0 ]] || { echo "ingest bench: run as root (PostgreSQL runs as postgres)" >&2; exit 1; }
# A socket per vehicle in the broker, three in the fleet-sim (libmosquitto's socket pair). Only
# the soft limit can be raised without CAP_SYS_RESOURCE: a broker then holds at most about the
# hard limit of sessions (20,000 on the development container), so bigger fleets go through
# edge brokers bridged to the workers' broker (start_edge_brokers).
ulimit -n "$(ulimit -Hn)"

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
# The same over a process and its descendants (a worker, or a program and the processes it starts).
tree_cpu_s() {
  local total c
  total=$(cpu_s "$1")
  for c in $(pgrep -P "$1"); do total=$(echo "$total + $(tree_cpu_s "$c")" | bc -l); done
  echo "$total"
}
# Resident memory (kB) of a process and its descendants.
tree_rss_kb() {
  local total c
  total=$(awk '/^VmRSS:/ { print $2 }' "/proc/$1/status" 2>/dev/null || echo 0)
  for c in $(pgrep -P "$1"); do total=$((total + $(tree_rss_kb "$c"))); done
  echo "$total"
}
# Proportional set size (kB) of a process and its descendants: shared pages counted once.
tree_pss_kb() {
  local total c
  total=$(awk '/^Pss:/ { print $2 }' "/proc/$1/smaps_rollup" 2>/dev/null || echo 0)
  for c in $(pgrep -P "$1"); do total=$((total + $(tree_pss_kb "$c"))); done
  echo "$total"
}
workers_pss_kb() {
  local total=0 w
  for w in "${WORKERS[@]}"; do total=$((total + $(tree_pss_kb "$w"))); done
  echo "$total"
}
workers_cpu_s() {
  local total=0 w
  for w in "${WORKERS[@]}"; do total=$(echo "$total + $(tree_cpu_s "$w")" | bc -l); done
  echo "$total"
}
workers_rss_kb() {
  local total=0 w
  for w in "${WORKERS[@]}"; do total=$((total + $(tree_rss_kb "$w"))); done
  echo "$total"
}
psql_q() { timeout "${QUERY_TIMEOUT_S:-600}" psql -X -A -t -q -v ON_ERROR_STOP=1 "$CONNINFO" -c "$1"; }

# PostgreSQL: a private cluster on a Unix socket, fsync on (BUILD-NOTES: initdb refuses root).
start_postgres() {
  mkdir -p "$WORK/pg" "$WORK/sock"
  chown postgres "$WORK/pg" "$WORK/sock"
  local port
  port=$(free_port)
  runuser -u postgres -- "$PGBIN/initdb" -D "$WORK/pg" -A trust -U fleet -E UTF8 --locale=C >"$WORK/initdb.log"
  # PG_LISTEN (e.g. 10.99.0.1): TCP for workers in other network namespaces (PG_HBA_NET trusted)
  [[ -n ${PG_LISTEN:-} ]] && echo "host all fleet ${PG_HBA_NET:-10.99.0.0/16} trust" >>"$WORK/pg/pg_hba.conf"
  # PG_OPTS: more server settings (ingest-drain.sh turns autovacuum off: see there).
  runuser -u postgres -- "$PGBIN/pg_ctl" -D "$WORK/pg" -l "$WORK/sock/pg.log" -w \
    -o "-k $WORK/sock -p $port -c listen_addresses='${PG_LISTEN:-}' ${PG_OPTS:-}" start >/dev/null
  PGPID=$(head -1 "$WORK/pg/postmaster.pid")
  CONNINFO="host=$WORK/sock port=$port user=fleet dbname=postgres"
}

# mosquitto: MQTT 5, no connection limit, session queues deep enough for a backlog, no log line
# per connection (50,000 of them at a fleet's start); BROKER_BIND (default 127.0.0.1) is where
# it listens (0.0.0.0 for workers in other network namespaces).
# max_inflight_messages: the receive maximum a broker grants its clients, an edge's bridge among
# them (at mosquitto's default of 20 in flight a bridge is bound by its round trip).
BROKER_SETTINGS='allow_anonymous true\nmax_connections -1\nmax_queued_messages 1000000\nmax_inflight_messages 1000\nset_tcp_nodelay true\nconnection_messages false\n'
start_broker() {
  local port
  port=$(free_port)
  printf "listener %s ${BROKER_BIND:-127.0.0.1}\n$BROKER_SETTINGS" "$port" >"$WORK/mosquitto.conf"
  mosquitto -c "$WORK/mosquitto.conf" 2>"$WORK/mosquitto.log" &
  BROKER=$!
  PIDS+=("$BROKER")
  BROKER_URI="tcp://127.0.0.1:$port"
  BROKER_PORT=$port
  wait_port "$port"
}
wait_port() {  # until 127.0.0.1:PORT accepts a connection (10 s)
  for _ in $(seq 100); do
    (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null && return 0
    sleep 0.1
  done
  echo "ingest bench: nothing listens on 127.0.0.1:$1 after 10 s" >&2
  exit 1
}
# start_edge_brokers N: N more mosquittos (EDGE_URIS, EDGE_PIDS) that the vehicles connect to,
# each bridging fleet/v1/# (QoS 1, a persistent bridge session, MQTT 5) to the workers' broker:
# the way past one broker process's descriptor limit on this machine.
start_edge_brokers() {
  local e port
  EDGE_URIS=()
  EDGE_PIDS=()
  for e in $(seq "$1"); do
    port=$(free_port)
    printf "listener %s 127.0.0.1\n$BROKER_SETTINGS" "$port" >"$WORK/edge-$e.conf"
    printf 'connection central\naddress 127.0.0.1:%s\nbridge_protocol_version mqttv50\nremote_clientid edge-%s\ncleansession false\ntopic fleet/v1/# out 1\n' \
      "$BROKER_PORT" "$e" >>"$WORK/edge-$e.conf"
    mosquitto -c "$WORK/edge-$e.conf" 2>"$WORK/edge-$e.log" &
    EDGE_PIDS+=("$!")
    PIDS+=("$!")
    EDGE_URIS+=("tcp://127.0.0.1:$port")
    wait_port "$port"
  done
}

# start_workers N: N workers of group "bench" (client ids bench-worker-1..N), subscribed.
start_workers() {
  local w
  WORKERS=()
  for w in $(seq "$1"); do
    touch "$WORK/worker-$w.log"
    # fleetgw-ingest itself (what `fleetgw ingest` execs): a worker built apart from the
    # gateway's fleetgw (FLEETGW's directory) takes options that fleetgw may not know yet.
    # INGEST_WRAP: a command the worker runs under (e.g. "strace -c -f -o FILE" to count its
    # system calls; its CPU is then counted with the worker's).
    # shellcheck disable=SC2086 # INGEST_ARGS, INGEST_WRAP: word-split on purpose
    ${INGEST_WRAP:-} "$(dirname "$FLEETGW")/fleetgw-ingest" --broker "$BROKER_URI" --group bench --client-id "bench-worker-$w" \
      --pg "$CONNINFO" ${INGEST_ARGS:-} >>"$WORK/worker-$w.log" 2>&1 &
    WORKERS+=("$!")
    PIDS+=("$!")
  done
  # Waits for the condition (each worker's "subscribed to" line), not a fixed budget: with a big
  # backlog a worker subscribes late. STARTUP_TIMEOUT_S (300) only bounds a worker that never does.
  local deadline=$((SECONDS + ${STARTUP_TIMEOUT_S:-300}))
  for w in $(seq "$1"); do
    until [[ $(grep -c "subscribed to" "$WORK/worker-$w.log") -ge ${2:-1} ]]; do
      [[ $SECONDS -lt $deadline ]] || { echo "worker $w: not subscribed after ${STARTUP_TIMEOUT_S:-300} s"; cat "$WORK/worker-$w.log"; exit 1; }
      kill -0 "${WORKERS[$((w - 1))]}" 2>/dev/null || { echo "worker $w exited"; cat "$WORK/worker-$w.log"; exit 1; }
      sleep 0.1
    done
  done
}
stop_workers() {  # SIGTERM; SIGKILL after STOP_TIMEOUT_S (60) for a worker that does not stop
  local w
  for w in "${WORKERS[@]}"; do kill -TERM "$w" 2>/dev/null || true; done
  for _ in $(seq $((${STOP_TIMEOUT_S:-60} * 10))); do
    kill -0 "${WORKERS[@]}" 2>/dev/null || break
    sleep 0.1
  done
  for w in "${WORKERS[@]}"; do
    kill -0 "$w" 2>/dev/null && { echo "worker $w did not stop in ${STOP_TIMEOUT_S:-60} s: killed"; kill -KILL "$w"; }
  done
  wait "${WORKERS[@]}" 2>/dev/null || true
}

# Records the fleet-sim says it created (sum of last_sequence over its stores).
expected_records() {
  /usr/bin/python3 -c 'import json,sys; print(sum(s["last_sequence"] for s in json.load(open(sys.argv[1]))["stores"]))' "$1"
}
accounted() {
  local q="SELECT coalesce(sum(last_seq - first_seq + 1), 0) FROM sequence_ranges"
  if [[ -n ${POLLER_PID:-} ]]; then poll_q "$q"; else psql_q "$q"; fi
}

# A persistent psql session for polling (start_poller; poll_q QUERY prints the one-line answer).
# A connection per poll would cost PostgreSQL a backend's start-up (milliseconds of CPU) ten
# times a second, charged to whatever the benchmark measures at the time.
start_poller() {
  coproc POLLER { exec psql -X -A -t -q -v ON_ERROR_STOP=1 "$CONNINFO" 2>&1; }
  PIDS+=("$POLLER_PID")
  POLLER_BACKEND=$(poll_q "SELECT pg_backend_pid()")
}
poll_q() {
  local line
  echo "$1;" >&"${POLLER[1]}"
  IFS= read -r -t "${QUERY_TIMEOUT_S:-600}" line <&"${POLLER[0]}" || { echo "ingest bench: poll query failed" >&2; exit 1; }
  echo "$line"
}
# CPU seconds of PostgreSQL's client backends (the sessions of clients, not the server's own
# background processes), the poller's excepted.
pg_backends_cpu_s() {
  local total=0 pid
  for pid in $(poll_q "SELECT string_agg(pid::text, ' ') FROM pg_stat_activity WHERE backend_type = 'client backend' AND pid <> pg_backend_pid()"); do
    total=$(echo "$total + $(cpu_s "$pid")" | bc -l)
  done
  echo "$total"
}
