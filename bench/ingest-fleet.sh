#!/usr/bin/env bash
# A simulated fleet through a real broker into PostgreSQL (issues 15 and 25, figures):
# fleetgw-fleet-sim (VEHICLES vehicles, each its own MQTT 5 session, the default configuration's
# traffic, RIDING_SHARE of them riding) → a local mosquitto → WORKERS `fleetgw ingest` workers
# (shared subscription) → a private PostgreSQL cluster (fsync on). Above PER_BROKER vehicles
# (18,000: one broker process holds at most about `ulimit -Hn` sessions, 20,000 here) the
# vehicles connect to ceil(VEHICLES / PER_BROKER) edge mosquittos bridged (QoS 1) to the
# workers' broker, one fleet-sim per edge. Reports:
#   whether every record landed exactly once: the fleet-sims' own count of records per store
#     (last_sequence, all acknowledged) against the rows, and the gap report;
#   honest counters: records created / rows; messages published by the fleet (each once) and
#     re-sent after a reconnect (redeliveries), sessions lost (keep-alive timeouts among them);
#     the workers' own counters (duplicates ignored, out-of-order state upserts ignored: named as
#     such, they are not duplicate records);
#   records committed per second;
#   delay from a record's created_at_us to its committed row, p50/p99: records the gateway
#     publishes at once (rides, lock events, pack statistics, device info: broker + ingest +
#     commit), and telemetry samples (the gateway's batching included by design: a riding batch
#     leaves 5 s after its first sample (mqtt.batch_max_ms), a parked one after 300 s);
#   CPU seconds (user + sys) of the broker(s), the ingest workers, PostgreSQL's processes and the
#     fleet-sim(s), and as a share of one core;
#   MQTT PUBLISH bytes per vehicle per riding hour and per parked hour (counted by fleet-sim;
#     CONNECT, pings and acknowledgements excluded).
# Every step has a timeout (the fleet-sim's run + ramp + 120 s; the settle wait SETTLE_TIMEOUT_S,
# 600; a worker's start STARTUP_TIMEOUT_S, 300, its stop STOP_TIMEOUT_S, 60; a query
# QUERY_TIMEOUT_S, 600). A benchmark, not a test. Needs root (PostgreSQL runs as `postgres`).
# From a fresh clone after scripts/install-deps.sh, one command: `sudo bench/ingest-fleet.sh`
# (the default FLEETGW is built first in build/, Release: ingest-lib.sh).
# Environment: FLEETGW (default build/bin/fleetgw; fleetgw-ingest and fleetgw-fleet-sim
#   beside it), VEHICLES (1000), DURATION_S (120; 600 is the issue's 10 minutes), RIDING_SHARE
#   (0.3), WORKERS (2), CONNECT_RATE (1000 sessions/s), PER_BROKER (18000), INGEST_ARGS, KEEP=1
#   keeps the work directory, CHURN_EVERY_S (0: off; CHURN_AWAY_S, 5, between a leaving worker's
#   stop and its --leave; LEAVE_TIMEOUT_S, 300, bounds each leave).
# Churn (CHURN_EVERY_S > 0; docs/backend.md "Scale-out"): one more worker of the group, client id
# bench-worker-churn, joins at the start; every CHURN_EVERY_S it in turn is SIGKILLed and
# restarted at once with its client id (its sessions resumed), leaves for good (SIGTERM, then
# CHURN_AWAY_S later `fleetgw ingest --leave`: what the broker queued for it meanwhile is
# committed, its sessions end), and joins again as a new member. At the fleet's end it leaves
# (nothing stays queued for it) before the settle. Its CPU is not in the workers' figure;
# joins, SIGKILLs and leaves are counted; the messages queued while it is away wait up to
# CHURN_AWAY_S (the delay lines' p99 shows it).
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=$(realpath -m "${FLEETGW:-build/bin/fleetgw}")
VEHICLES=${VEHICLES:-1000}
DURATION_S=${DURATION_S:-120}
RIDING_SHARE=${RIDING_SHARE:-0.3}
NWORKERS=${WORKERS:-2}
CONNECT_RATE=${CONNECT_RATE:-1000}
PER_BROKER=${PER_BROKER:-18000}
source bench/ingest-lib.sh
SIM=$(dirname "$FLEETGW")/fleetgw-fleet-sim
[[ -x $SIM ]] || { echo "ingest-fleet: no $SIM" >&2; exit 1; }

start_postgres
start_broker
EDGES=$(((VEHICLES + PER_BROKER - 1) / PER_BROKER))
SIM_URIS=("$BROKER_URI")
BROKER_PIDS=("$BROKER")
if [[ $EDGES -gt 1 ]]; then
  start_edge_brokers "$EDGES"
  SIM_URIS=("${EDGE_URIS[@]}")
  BROKER_PIDS+=("${EDGE_PIDS[@]}")
fi
start_workers "$NWORKERS"

# The churning worker (CHURN_EVERY_S): a background loop; its events go to $WORK/churn-events.
CHURN_EVERY_S=${CHURN_EVERY_S:-0}
INGEST_BIN=$(dirname "$FLEETGW")/fleetgw-ingest
churn_start() {  # joins (a restart with the same client id resumes its sessions); waits for it
  # shellcheck disable=SC2086 # INGEST_ARGS: word-split on purpose
  "$INGEST_BIN" --broker "$BROKER_URI" --group bench --client-id bench-worker-churn \
    --pg "$CONNINFO" ${INGEST_ARGS:-} >>"$WORK/churn.log" 2>&1 &
  CHURN_PID=$!
  echo "$CHURN_PID" >"$WORK/churn.pid"
  local n=$1 deadline=$((SECONDS + ${STARTUP_TIMEOUT_S:-300}))
  until [[ $(grep -c "subscribed to" "$WORK/churn.log") -ge $n ]]; do
    if [[ $SECONDS -ge $deadline ]] || ! kill -0 "$CHURN_PID" 2>/dev/null; then
      echo "churn worker: not subscribed"
      tail -5 "$WORK/churn.log"
      return 1
    fi
    sleep 0.1
  done
  echo join >>"$WORK/churn-events"
}
churn_leave() {  # SIGTERM (a clean stop: the sessions stay), away a while, the leave for good
  kill -TERM "$CHURN_PID" || true
  wait "$CHURN_PID" || true
  # Away CHURN_AWAY_S (unless the fleet ended): the broker queues the worker's share meanwhile,
  # the backlog the leave must drain.
  local back=$((SECONDS + ${CHURN_AWAY_S:-5}))
  while [[ $SECONDS -lt $back && ! -e $WORK/churn-stop ]]; do sleep 0.2; done
  # shellcheck disable=SC2086
  timeout -k 10 "${LEAVE_TIMEOUT_S:-300}" "$INGEST_BIN" --leave --broker "$BROKER_URI" --group bench \
    --client-id bench-worker-churn --pg "$CONNINFO" ${INGEST_ARGS:-} >>"$WORK/churn.log" 2>&1 ||
    echo "churn worker: the leave failed (exit $?)"
  echo leave >>"$WORK/churn-events"
}
churn_loop() {
  local joined=1 up=1 step=0
  churn_start "$joined" || return 1
  while :; do
    local until=$((SECONDS + CHURN_EVERY_S))
    while [[ $SECONDS -lt $until && ! -e $WORK/churn-stop ]]; do sleep 0.2; done
    [[ -e $WORK/churn-stop ]] && break
    if [[ $up == 0 ]]; then  # joins again, a new member (its sessions were forgotten)
      churn_start $((++joined)) || return 1
      up=1
    elif [[ $((step++ % 2)) == 0 ]]; then  # SIGKILL, restarted at once on its sessions
      kill -KILL "$CHURN_PID" || true
      wait "$CHURN_PID" 2>/dev/null || true
      echo sigkill >>"$WORK/churn-events"
      churn_start $((++joined)) || return 1
    else
      churn_leave
      up=0
    fi
  done
  if [[ $up == 1 ]]; then churn_leave; fi
}
if [[ $CHURN_EVERY_S != 0 ]]; then
  churn_cleanup() {  # (a failing command here would end the trap before cleanup: set -e)
    if [[ -f $WORK/churn.pid ]]; then kill -KILL "$(cat "$WORK/churn.pid")" 2>/dev/null || true; fi
    cleanup
  }
  trap churn_cleanup EXIT
  : >"$WORK/churn-events"
  churn_loop &
  CHURN_LOOP=$!
fi
brokers_cpu_s() {
  local total=0 b
  for b in "${BROKER_PIDS[@]}"; do total=$(echo "$total + $(cpu_s "$b")" | bc -l); done
  echo "$total"
}

echo "ingest-fleet: $VEHICLES vehicles ($RIDING_SHARE riding) for $DURATION_S s -> ${#SIM_URIS[@]} mosquitto(s)$([[ $EDGES -gt 1 ]] && echo " bridged to one") -> $NWORKERS ingest workers -> PostgreSQL"
B0=$(brokers_cpu_s); I0=$(workers_cpu_s)
P0=$(pg_cpu_s)
START_US=$(($(date +%s%N) / 1000))
# CPU of this shell's reaped children (`times`' second line, run in this shell, not a
# subshell): around the fleet-sims' wait it is theirs (timeout waits for fleet-sim, which waits
# for its shard processes).
children_cpu_s() {
  times >"$WORK/times"
  tail -1 "$WORK/times" | /usr/bin/python3 -c '
import re, sys
print(sum(int(m) * 60 + float(s) for m, s in re.findall(r"(\d+)m([\d.]+)s", sys.stdin.read())))'
}
children_cpu_s >"$WORK/sim-cpu-0"
# One fleet-sim per broker, each its slice of the fleet (vehicle ids stay sim-bike-0..N-1).
SIM_PIDS=()
N_SIMS=${#SIM_URIS[@]}
SIM_TIMEOUT=$((DURATION_S + VEHICLES / CONNECT_RATE + 120))
for k in $(seq 0 $((N_SIMS - 1))); do
  first=$((VEHICLES * k / N_SIMS))
  count=$((VEHICLES * (k + 1) / N_SIMS - first))
  timeout -k 10 "$SIM_TIMEOUT" "$SIM" --vehicles "$count" --first-index "$first" --broker "${SIM_URIS[$k]}" \
    --duration-s "$DURATION_S" --riding-share "$RIDING_SHARE" \
    --connect-rate "$(echo "$CONNECT_RATE / $N_SIMS" | bc -l)" --report "$WORK/sim-$k.json" \
    2>"$WORK/sim-$k.log" &
  SIM_PIDS+=("$!")
  PIDS+=("$!")  # timeout passes a SIGTERM on to the fleet-sim (no /usr/bin/time between them)
done
SIM_OK=1
for k in "${!SIM_PIDS[@]}"; do
  rc=0
  wait "${SIM_PIDS[$k]}" || rc=$?
  [[ $rc == 0 ]] || { SIM_OK=0; echo "fleet-sim $k: exit $rc"; tail -1 "$WORK/sim-$k.log"; }
done
children_cpu_s >"$WORK/sim-cpu-1"
if [[ $CHURN_EVERY_S != 0 ]]; then
  # The fleet ended: the churn worker leaves (if it is in the group) before the settle.
  touch "$WORK/churn-stop"
  wait "$CHURN_LOOP" || echo "churn worker: the loop failed (exit $?)"
fi
SIM_CPU=$(echo "$(cat "$WORK/sim-cpu-1") - $(cat "$WORK/sim-cpu-0")" | bc -l)
# The fleet's report: the sims' reports merged (sums; stores concatenated).
/usr/bin/python3 - "$WORK" "$N_SIMS" >"$WORK/sim.json" <<'EOF'
import json, sys
work, n = sys.argv[1], int(sys.argv[2])
total = {"stores": []}
for k in range(n):
    try:
        r = json.load(open(f"{work}/sim-{k}.json"))
    except (OSError, ValueError):
        total["failed_sims"] = total.get("failed_sims", 0) + 1
        continue
    for key, v in r.items():
        if key == "stores":
            total["stores"] += v
        elif isinstance(v, (int, float)) and key not in ("duration_s", "last_connack_s"):
            total[key] = total.get(key, 0) + v
        else:
            total[key] = max(total.get(key, 0), v)
json.dump(total, sys.stdout)
EOF

# Every record the fleet created, accounted for in PostgreSQL (or SETTLE_TIMEOUT_S of patience).
EXPECTED=$(expected_records "$WORK/sim.json")
GOT=0
SETTLE_END=$((SECONDS + ${SETTLE_TIMEOUT_S:-600}))
while [[ $SECONDS -lt $SETTLE_END ]]; do
  GOT=$(accounted)
  [[ $GOT -ge $EXPECTED ]] && break
  sleep 0.5
done
END_US=$(psql_q "SELECT max(committed_at_us) FROM (SELECT max(committed_at_us) AS committed_at_us FROM telemetry_samples UNION ALL SELECT max(committed_at_us) FROM pack_snapshots) t")
B1=$(brokers_cpu_s); I1=$(workers_cpu_s)
P1=$(pg_cpu_s)
stop_workers

ROWS=$(psql_q "SELECT (SELECT count(*) FROM telemetry_samples) + (SELECT count(*) FROM rides) + (SELECT count(*) FROM lock_events) + (SELECT count(*) FROM pack_snapshots) + (SELECT count(*) FROM device_info)")
# `ingest --gaps` exits 1 when it prints gaps: counted here, not a failure of the script.
GAPS=$({ timeout "${QUERY_TIMEOUT_S:-600}" "$FLEETGW" ingest --gaps --pg "$CONNINFO" 2>/dev/null || true; } | wc -l)
WALL_S=$(echo "($END_US - $START_US) / 1000000" | bc -l)
pct() {  # p50/p99 in ms of a delay column expression over a FROM clause
  psql_q "SELECT round((percentile_cont(0.5) WITHIN GROUP (ORDER BY d) / 1000)::numeric, 1) || ' / ' || round((percentile_cont(0.99) WITHIN GROUP (ORDER BY d) / 1000)::numeric, 1) || ' ms (n=' || count(*) || ')' FROM ($1) q"
}
RECORDS="SELECT created_at_us, committed_at_us FROM rides UNION ALL SELECT created_at_us, committed_at_us FROM lock_events UNION ALL SELECT created_at_us, committed_at_us FROM pack_snapshots UNION ALL SELECT created_at_us, committed_at_us FROM device_info"
RECORD_DELAY=$(pct "SELECT committed_at_us - created_at_us AS d FROM ($RECORDS) r")
# After the connect ramp, the fleet's 30 s boot spread and a minute of running: the steady state.
STEADY_FROM=$((START_US + (VEHICLES / CONNECT_RATE + 60) * 1000000))
STEADY_DELAY=$(pct "SELECT committed_at_us - created_at_us AS d FROM ($RECORDS) r WHERE created_at_us > $STEADY_FROM")
FIRST_DELAY=$(pct "SELECT committed_at_us - created_at_us AS d FROM telemetry_samples")
read -r RIDING_N PARKED_N RIDE_B PARK_B SIM_S UNACKED CONNECTED MESSAGES RESENT DROPS CONNECT_FAILS LAST_CONNACK < <(/usr/bin/python3 -c '
import json, sys
r = json.load(open(sys.argv[1]))
g = lambda k: r.get(k, 0)
print(g("riding"), g("vehicles") - g("riding"), g("riding_packet_bytes"), g("parked_packet_bytes"), g("duration_s"), g("unacknowledged") + g("failed_processes") + g("failed_sims"), g("connected"), g("messages"), g("resent"), g("disconnects"), g("connect_failures"), g("last_connack_s"))' "$WORK/sim.json")
# The workers' own counters: their last "ingest: N messages, ..." line each, summed by field.
WORKER_COUNTS=$(for f in "$WORK"/worker-*.log; do grep -o 'ingest: [0-9]* messages, .*' "$f" | tail -1; done | /usr/bin/python3 -c '
import re, sys
sums = {}
for line in sys.stdin:
    for n, name in re.findall(r"(\d+) ([a-z][a-z -]*[a-z])", line):
        sums[name] = sums.get(name, 0) + int(n)
print(", ".join(f"{v} {k}" for k, v in sums.items()) or "-")')
share() { echo "scale=2; 100 * ($1) / $WALL_S" | bc -l; }
per_hour() { [[ $2 -gt 0 ]] && echo "scale=0; $1 * 3600 / $2 / $SIM_S" | bc -l || echo "-"; }

echo "vehicles connected          $CONNECTED of $VEHICLES ($RIDING_N riding, $PARKED_N parked), unacknowledged publishes $UNACKED"
echo "connects                    last CONNACK $LAST_CONNACK s after the start, $CONNECT_FAILS connect attempts failed"
echo "records created / in PG     $EXPECTED / $ROWS rows ($GOT accounted), gaps: $GAPS"
echo "messages published          $MESSAGES (each once), re-sent after a reconnect $RESENT, sessions lost $DROPS"
echo "workers' counters           $WORKER_COUNTS"
if [[ $CHURN_EVERY_S != 0 ]]; then
  CHURN_DRAINED=$({ grep -o '[0-9]* message(s) drained' "$WORK/churn.log" || true; } | awk '{ n += $1 } END { print n + 0 }')
  printf '%-28s%s joins, %s SIGKILLs, %s leaves (%s completed, %s messages drained by them)\n' \
    "churn (every $CHURN_EVERY_S s)" "$(grep -c '^join$' "$WORK/churn-events")" \
    "$(grep -c '^sigkill$' "$WORK/churn-events")" "$(grep -c '^leave$' "$WORK/churn-events")" \
    "$(grep -c 'left group bench for good' "$WORK/churn.log")" "$CHURN_DRAINED"
fi
printf 'records committed           %.0f /s over %.0f s (first record to last commit)\n' "$(echo "$EXPECTED / $WALL_S" | bc -l)" "$WALL_S"
echo "delay record -> row         $RECORD_DELAY (rides, locks, packs, info; whole run)"
echo "  after the ramp + 60 s     $STEADY_DELAY"
echo "delay telemetry sample      $FIRST_DELAY (created_at_us of its batch, batching wait included)"
printf 'CPU broker(s)               %.1f s (%.1f %% of a core)\n' "$(echo "$B1 - $B0" | bc -l)" "$(share "$B1 - $B0")"
printf 'CPU ingest (%s workers)      %.1f s (%.1f %% of a core)\n' "$NWORKERS" "$(echo "$I1 - $I0" | bc -l)" "$(share "$I1 - $I0")"
printf 'CPU PostgreSQL              %.1f s (%.1f %% of a core)\n' "$(echo "$P1 - $P0" | bc -l)" "$(share "$P1 - $P0")"
printf 'CPU fleet-sim               %.1f s (%.1f %% of a core)\n' "$SIM_CPU" "$(share "$SIM_CPU")"
echo "bytes/vehicle/riding hour   $(per_hour "$RIDE_B" "$RIDING_N") B (MQTT PUBLISH packets)"
echo "bytes/vehicle/parked hour   $(per_hour "$PARK_B" "$PARKED_N") B (MQTT PUBLISH packets)"
[[ $SIM_OK == 1 && $GAPS == 0 && $ROWS == "$EXPECTED" && $UNACKED == 0 ]] || { echo "ingest-fleet: NOT exactly once"; exit 1; }
