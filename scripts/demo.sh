#!/usr/bin/env bash
# The live demo, as a story told in about a minute once fleetgw is built: a simulated MOTINOVA
# e-bike on an in-process CAN bus, the fleetgw service decoding it into SQLite and publishing to
# a private mosquitto, a subscriber decoding what reaches the broker, and an operator sending
# signed remote commands and a signed zone bundle. The bike's GNSS receiver follows the
# scenario's route through Ljubljana, read by a real gpsd. In order: the operator publishes the
# city's zones and unlocks the frame lock remotely; the bike is ridden for 23 minutes (the
# simulator runs 40x real time, so that takes 35 s), during which the operator caps its speed
# at 15 km/h (confirmed by the MC), the motor overheats and recovers, the operator's attempt to
# lock the frame lock is refused because the bike is moving, and the bike crosses the Old Town
# slow zone (10 km/h, applied along a ramp and lifted on exit, back to the operator's 15); the
# bike stops, the operator locks it, the ride ends with its GNSS track and reaches the broker;
# at night the locked bike is ridden away: a theft alarm. Every step prints one plain line as
# it happens; then `fleetgw db summary`. Then the fleet's side: a `fleetgw ingest` worker,
# subscribed before the bike starts, has written everything the bike published into a private
# PostgreSQL cluster; `fleetgw serve` (the operator console) is started on it with an operator
# account `demo`, and its API is asked what an operator sees (the bike, its position, its theft
# alarm). On a terminal the console stays up until Enter; otherwise (tests, CI) the demo ends.
#
# The script reacts to what the bike does, not to fixed sleeps: it polls `fleetgw status` (speed,
# open ride) and the store (`fleetgw db ... --format json`, read-only) for each condition.
#
# Usage: scripts/demo.sh [--build-dir DIR] [--out DIR]
#   --build-dir DIR  use the fleetgw and fleetgw-watch already built in DIR: no packages, no
#                    build, no waiting for Enter at the end (the test demo.story runs it so)
#   --out DIR        the demo's files (store, logs, configuration, key); default build/demo
#   SPEED=x          simulator acceleration (default 40)
# Exit status: 0 when every step of the story happened, 1 otherwise.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
BUILD_DIR=""
GIVEN_BUILD_DIR=0
OUT=""
BUILD_PROGRESS_ONLY=0
while [ $# -gt 0 ]; do
  case "$1" in
    --build-dir) BUILD_DIR=$(cd "$2" && pwd); GIVEN_BUILD_DIR=1; shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    -h|--help) sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    # (internal, for tests/config/demo-setup-test.sh: the progress filter alone, on stdin)
    --build-progress) BUILD_PROGRESS_ONLY=1; shift ;;
    *) echo "demo: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
SPEED=${SPEED:-40}
SCENARIO=$ROOT/config/scenarios/demo-story.toml
BUS_SECONDS=2500  # the scenario's length in bus time
ZONES_GEOJSON=$ROOT/config/demo-zones.geojson

SECONDS=0
section() { echo "== $1"; }
# A build's output on stdin -> one line per 10 % of its progress (make's "[ 42%]", ninja's
# "[17/98]") with the time since the build started. Read by bash line by line as the build
# prints: awk is no use here, Debian's mawk reads a pipe in large blocks, so it saw every line
# only at the end and printed 0m00s on each.
build_progress() {
  local start=$SECONDS next=0 line p t
  local make_re='^\[ *([0-9]+)%\]' ninja_re='^\[([0-9]+)/([0-9]+)\]'
  while IFS= read -r line; do
    if [[ $line =~ $make_re ]]; then
      p=$((10#${BASH_REMATCH[1]}))
    elif [[ $line =~ $ninja_re ]] && [ "${BASH_REMATCH[2]}" -gt 0 ]; then
      p=$((100 * BASH_REMATCH[1] / BASH_REMATCH[2]))
    else
      continue
    fi
    if [ "$p" -ge "$next" ]; then
      t=$((SECONDS - start))
      printf '   build: %3d %%  (%dm%02ds)\n' "$p" $((t / 60)) $((t % 60))
      next=$((p - p % 10 + 10))
    fi
  done
}
if [ "$BUILD_PROGRESS_ONLY" = 1 ]; then
  build_progress
  exit 0
fi

if [ -z "$BUILD_DIR" ]; then
  BUILD_DIR=$ROOT/build
  FLEETGW=$BUILD_DIR/bin/fleetgw
  if [ ! -x "$FLEETGW" ]; then
    section "first run: Debian packages, then the build of fleetgw (about 8 minutes on 2 cores;"
    echo "   later runs rebuild only what changed, in seconds); then the demo itself, about a minute"
  fi
  # The demo's own set: the build and the demo's programs, not the tests' (VM, chromium, lintian,
  # clang, the cross tools: scripts/test.sh installs those).
  section "Debian packages (scripts/install-deps.sh --demo)"
  ./scripts/install-deps.sh --demo
  # Ninja for a new tree (scripts/test.sh explains why); an existing tree keeps its generator.
  if [ -z "${CMAKE_GENERATOR:-}" ] && command -v ninja >/dev/null; then export CMAKE_GENERATOR=Ninja; fi
  # The product tree of scripts/test.sh, configured the same way (Release, compiled in unity
  # batches, tests only when named), so running both does not rebuild anything.
  section "build fleetgw in build/ (Release; full log in build/demo-build.log)"
  cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DFLEETGW_WERROR=ON -DFLEETGW_UNITY=ON \
    -DFLEETGW_UNITY_TESTS=ON -DFLEETGW_TESTS_IN_ALL=OFF >/dev/null
  BUILD_LOG=$BUILD_DIR/demo-build.log
  # The build tool's own lines scroll by for minutes; show one line per 10 % instead.
  set +e
  cmake --build "$BUILD_DIR" --target fleetgw fleetgw-watch -j "$(nproc)" 2>&1 | tee "$BUILD_LOG" |
    build_progress
  rc=${PIPESTATUS[0]}
  set -e
  if [ "$rc" != 0 ]; then
    echo "demo: the build failed; its last lines (all of them in $BUILD_LOG):"
    grep -E "error|Error" "$BUILD_LOG" | tail -n 20
    exit 1
  fi
  echo "   build: done after $((SECONDS / 60))m$((SECONDS % 60))s"
fi
FLEETGW=$BUILD_DIR/bin/fleetgw
[ -x "$FLEETGW" ] || { echo "demo: no fleetgw in $BUILD_DIR/bin" >&2; exit 1; }
OUT=${OUT:-$ROOT/build/demo}
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
# Start from an empty directory, but only ever empty one this script made (its marker file, or
# the default build/demo of earlier versions).
if [ "$OUT" != "$ROOT/build/demo" ] && [ -n "$(ls -A "$OUT")" ] && [ ! -e "$OUT/.fleetgw-demo" ]; then
  echo "demo: $OUT is not empty and not a demo directory; choose another --out" >&2
  exit 2
fi
find "$OUT" -mindepth 1 -delete
touch "$OUT/.fleetgw-demo"

# --- the fleet's database: a private PostgreSQL cluster on a Unix socket, started in the
# background while the broker and the gateway start (initdb takes seconds). PostgreSQL refuses
# to run as root, so as root the cluster belongs to `postgres` (docs/backend.md); it lives in
# its own directory under /tmp, which `postgres` can reach (a clone under /root is not), and is
# removed at the end.
PGBIN=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n 1)
as_pg() { if [ "$(id -u)" = 0 ]; then runuser -u postgres -- "$@"; else "$@"; fi; }
PG_PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
PGDIR=$(mktemp -d /tmp/fleetgw-demo-pg.XXXXXX)
PG="host=$PGDIR port=$PG_PORT user=fleet dbname=postgres"
start_pg() {
  [ -x "$PGBIN/initdb" ] || { echo "no PostgreSQL (scripts/install-deps.sh --demo installs it)"; return 1; }
  if [ "$(id -u)" = 0 ]; then chown postgres "$PGDIR"; fi
  as_pg "$PGBIN/initdb" -D "$PGDIR/data" -A trust -U fleet -E UTF8 --locale=C &&
    as_pg "$PGBIN/pg_ctl" -D "$PGDIR/data" -l "$PGDIR/postgres.log" -w \
      -o "-k $PGDIR -p $PG_PORT -c listen_addresses=''" start
}
start_pg > "$OUT/postgres.log" 2>&1 &
PG_STARTER=$!

# --- set-up: private broker, configuration, operator key, subscriber --------------------------
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
cat > "$OUT/mosquitto.conf" <<CONF
listener $PORT 127.0.0.1
allow_anonymous true
persistence false
set_tcp_nodelay true
log_dest stderr
CONF
BROKER="" SUBSCRIBER="" SERVICE="" GPSD_PID="" INGEST="" SERVE=""
cleanup() {
  # The ingest first, given up to 5 s to commit its last batch before the broker and the
  # database go away.
  for pid in $SERVE $INGEST; do kill "$pid" 2>/dev/null || true; done
  for _ in $(seq 50); do { [ -n "$INGEST" ] && kill -0 "$INGEST" 2>/dev/null; } || break; sleep 0.1; done
  for pid in $SERVICE $GPSD_PID $SUBSCRIBER $BROKER; do kill "$pid" 2>/dev/null || true; done
  wait "$PG_STARTER" 2>/dev/null || true
  if [ -e "$PGDIR/data/postmaster.pid" ]; then
    as_pg "$PGBIN/pg_ctl" -D "$PGDIR/data" -m fast -w stop >/dev/null 2>&1 || true
  fi
  cp "$PGDIR/postgres.log" "$OUT/postgres-server.log" 2>/dev/null || true
  rm -rf "$PGDIR"
}
trap cleanup EXIT
MOSQUITTO=$(command -v mosquitto || echo /usr/sbin/mosquitto)
"$MOSQUITTO" -c "$OUT/mosquitto.conf" 2> "$OUT/mosquitto.log" &
BROKER=$!
for _ in $(seq 100); do  # until the broker accepts connections (at most 10 s)
  (exec 3<>"/dev/tcp/127.0.0.1/$PORT") 2>/dev/null && break
  kill -0 $BROKER 2>/dev/null || { cat "$OUT/mosquitto.log"; exit 1; }
  sleep 0.1
done

# The bike's GNSS: the simulator writes NMEA on a pty, a real gpsd reads it like a serial receiver.
GPSD=$(command -v gpsd || echo /usr/sbin/gpsd)
[ -x "$GPSD" ] || { echo "demo: gpsd is not installed (scripts/install-deps.sh installs it)" >&2; exit 1; }
GPSD_PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
PTY=$OUT/sim-gps

CONFIG=$OUT/fleetgw.toml
sed -e "s#@PORT@#$PORT#g" -e "s#@DB@#$OUT/fleetgw.db#g" -e "s#@SCENARIO@#$SCENARIO#g" \
  -e "s#@SPEED@#$SPEED#g" -e "s#@SOCKET@#$OUT/status.sock#g" -e "s#@PTY@#$PTY#g" \
  -e "s#@GPSD_PORT@#$GPSD_PORT#g" -e "s#@ZONES@#$OUT/zones.pb#g" config/demo.toml.in > "$CONFIG"
KEYLINE=$("$FLEETGW" keygen "$OUT/operator" 2>/dev/null)  # the operator's key, trusted below
printf '\n[command.trusted_keys]\n%s\n' "$KEYLINE" >> "$CONFIG"
BROKER_URI=tcp://127.0.0.1:$PORT

# The city's zones, drawn as GeoJSON, signed by the operator and published retained: every bike
# of the fleet gets them when it connects, and keeps them for when it is offline.
"$FLEETGW" zones sign "$ZONES_GEOJSON" --version 1 --key "$OUT/operator.pem" \
  --out "$OUT/zones-v1.pb" > "$OUT/zones-sign.log" 2>&1 ||
  { cat "$OUT/zones-sign.log"; exit 1; }
mosquitto_pub -h 127.0.0.1 -p "$PORT" -t fleet/v1/zones -r -f "$OUT/zones-v1.pb"
"$FLEETGW" watch --broker "$BROKER_URI" --topic 'fleet/v1/#' > "$OUT/subscriber.log" 2>&1 &
SUBSCRIBER=$!

# JSON questions answered by python3 (Debian's, always there): q.py get PATH, q.py first ...
cat > "$OUT/q.py" <<'PY'
import json, sys
def walk(doc, path):  # "a.b", "a.0", "locks.kind=frame.state"
    for part in path.split(".") if path else []:
        if isinstance(doc, list) and "=" in part:
            k, v = part.split("=", 1)
            doc = next((e for e in doc if isinstance(e, dict) and str(e.get(k)) == v), None)
        elif isinstance(doc, list):
            doc = doc[int(part)] if part.isdigit() and int(part) < len(doc) else None
        elif isinstance(doc, dict):
            doc = doc.get(part)
        if doc is None:
            return None
    return doc
DIGITS = 1
def show(v):
    if v is None: return ""
    if isinstance(v, float): return f"{v:.{DIGITS}f}"
    return str(v)
text = sys.stdin.read()
try:
    doc = json.loads(text)
except ValueError:  # JSON lines (db export), oldest first: a list, newest first
    try:
        doc = [json.loads(line) for line in text.splitlines() if line.strip()][::-1]
    except ValueError:
        sys.exit(0)
mode, args = sys.argv[1], sys.argv[2:]
if mode.endswith("-fine"):  # coordinates: five decimals (about a metre)
    mode, DIGITS = mode[:-len("-fine")], 5
if mode == "get":      # get PATH...: one value per line ('' when missing)
    for p in args: print(show(walk(doc, p)))
elif mode == "first":  # first KEY=VALUE... -- FIELD...: the newest row that matches
    cut = args.index("--")
    want = dict(a.split("=", 1) for a in args[:cut])
    for row in doc if isinstance(doc, list) else []:
        if all(str(row.get(k)) == v for k, v in want.items()):
            for f in args[cut + 1:]: print(show(row.get(f)))
            break
PY
q() { python3 "$OUT/q.py" "$@"; }
status_json() { "$FLEETGW" status --config "$CONFIG" --format json 2>/dev/null || true; }
db_json() { "$FLEETGW" db "$1" --config "$CONFIG" --format json --limit 0 2>/dev/null || echo '[]'; }
db_rows() { "$FLEETGW" db export --table "$1" --config "$CONFIG" --format jsonl 2>/dev/null || true; }

FAILED=0
T0=$SECONDS
say() { printf '  [%3d s] %s\n' $((SECONDS - T0)) "$1"; }
missed() { say "MISSED: $1"; FAILED=1; }
# Waits are written for the default 40x; a slower simulator gets proportionally longer.
SCALE=$(awk -v s="$SPEED" 'BEGIN { f = 40 / s; print (f > 1 ? int(f + 0.999) : 1) }')
# wait_for SECONDS CONDITION...: polls the condition (a shell command) every 0.2 s.
wait_for() {
  local limit=$(($1 * SCALE)); shift
  local deadline=$((SECONDS + limit))
  until "$@"; do
    [ $SECONDS -lt $deadline ] || return 1
    kill -0 "$SERVICE" 2>/dev/null || [ "${ALLOW_STOPPED:-0}" = 1 ] || return 1
    sleep 0.2
  done
}

# An operator's signed command through the broker; prints one line with the outcome.
#   command_step LABEL LOCK ACTION EXPECTED
command_step() {
  local label=$1 lock=$2 action=$3 expected=$4 out result reason rtt
  out=$("$FLEETGW" command --vehicle demo-bike-01 --lock "$lock" --action "$action" \
    --key "$OUT/operator.pem" --broker "$BROKER_URI" --timeout-s 10 2>> "$OUT/command.log" || true)
  echo "$out" >> "$OUT/commands.jsonl"
  { read -r result; read -r reason; read -r rtt; } < <(echo "$out" | q get result reason round_trip_ms) || true
  if [ -z "$result" ]; then
    missed "$label: no answer (see $OUT/command.log)"
    return
  fi
  local text="$label: $result"
  # A reason is "code: detail"; the code says it.
  [ "$result" = rejected ] && text="$label: refused (${reason%%:*})"
  [ "$result" = failed ] || [ "$result" = timeout ] && text="$label: $result (${reason%%:*})"
  say "$text in $(awk -v ms="$rtt" 'BEGIN { printf "%.2f", ms / 1000 }') s"
  [ "$result" = "$expected" ] || missed "$label: expected $expected"
}

# Conditions the story waits for.
S_SPEED="" S_SOC="" S_RIDE_KM="" S_RIDE_MIN="" S_FRAME="" S_LIMIT="" S_FIX="" S_LAT="" S_LON=""
S_ZONES_VERSION=""
read_status() {
  { read -r S_SPEED; read -r S_SOC; read -r S_RIDE_KM; read -r S_RIDE_S; read -r S_FRAME
    read -r S_BROKER; read -r S_LIMIT; read -r S_FIX; read -r S_LAT; read -r S_LON
    read -r S_ZONES_VERSION; } < <(status_json | q get vehicle.speed_kmh vehicle.soc_pct \
      vehicle.ride.distance_km vehicle.ride.duration_s locks.kind=frame.state broker.connected \
      vehicle.speed_limit_kmh gnss.fix gnss.lat gnss.lon geofence.version) || true
  S_RIDE_MIN=$(awk -v s="${S_RIDE_S:-0}" 'BEGIN { printf "%.1f", s / 60 }')
}
gateway_ready() { read_status; [ "$S_FRAME" = locked ] && [ "$S_BROKER" = True ]; }
located() { read_status; [ "$S_FIX" = True ] && [ "$S_ZONES_VERSION" = 1 ]; }
riding_fast() {
  read_status
  [ -n "$S_RIDE_KM" ] && awk -v v="${S_SPEED:-0}" 'BEGIN { exit !(v >= 12) }'
}
STILL=0
standing_after_ride() {  # two readings in a row at walking pace or less
  read_status
  if awk -v v="${S_SPEED:-99}" 'BEGIN { exit !(v < 1) }'; then STILL=$((STILL + 1)); else STILL=0; fi
  [ $STILL -ge 2 ]
}
FAULT_NODE="" FAULT_NAME="" FAULT_SEV="" FAULT_AT=""
fault_event() {  # fault_event raised|cleared [NODE]: the newest such event (of the MC by default)
  { read -r FAULT_NODE; read -r FAULT_NAME; read -r FAULT_SEV; read -r FAULT_AT; } < <(db_json faults |
    q first event="$1" node="${2:-mc}" -- node fault severity time) || true
  [ -n "$FAULT_NAME" ]
}
RIDE_ID="" RIDE_KM="" RIDE_MIN=""
ride_closed() {
  { read -r RIDE_ID; read -r RIDE_KM; read -r RIDE_MIN; } < <(db_json rides |
    q first state=closed -- ride_id distance_km duration_min) || true
  [ -n "$RIDE_ID" ]
}
ride_at_broker() { grep -q "$RIDE_ID" "$OUT/subscriber.log" && grep -F "$RIDE_ID" "$OUT/subscriber.log" | grep -q '/ride"'; }
ALARM_SPEED=""
alarm_event() {  # alarm_event raised|cleared
  local at=""  # one query for both fields: the alarm may be stored between two queries
  { read -r at; read -r ALARM_SPEED; } < <(db_json alarms |
    q first alarm=unauthorised_movement transition="$1" -- time speed_kmh) || true
  [ -n "$at" ]
}

ZONE_NAME="" ZONE_LIMIT="" ZONE_LAT="" ZONE_LON=""
zone_event() {  # zone_event enter|exit: the slow zone's newest such event in the store
  { read -r ZONE_NAME; read -r ZONE_LIMIT; read -r ZONE_LAT; read -r ZONE_LON; } < <(db_rows zone_events |
    q first-fine kind=slow transition="$1" -- zone_name speed_limit_kmh lat_deg lon_deg) || true
  [ -n "$ZONE_NAME" ]
}
limit_is() { read_status; [ "${S_LIMIT%.*}" = "$1" ]; }  # the MC's limit in force, whole km/h

# The fleet's side: one ingest worker subscribed before the bike publishes anything, so
# everything of the story lands in PostgreSQL too (docs/backend.md).
INGEST_READY=0
if wait "$PG_STARTER"; then
  "$FLEETGW" ingest --broker "$BROKER_URI" --group demo --client-id demo-ingest --pg "$PG" \
    > "$OUT/ingest.log" 2>&1 &
  INGEST=$!
  for _ in $(seq 200); do  # until it has subscribed (at most 20 s)
    grep -q "subscribed" "$OUT/ingest.log" && { INGEST_READY=1; break; }
    kill -0 $INGEST 2>/dev/null || break
    sleep 0.1
  done
fi
PG_STARTER=""

section "the story (simulator at ${SPEED}x real time; store, logs and config in $OUT)"
if [ $INGEST_READY = 1 ]; then
  say "backend: PostgreSQL up, fleetgw ingest subscribed to the broker"
else
  missed "backend: no PostgreSQL or no subscribed fleetgw ingest (see $OUT/postgres.log, $OUT/ingest.log)"
fi
"$FLEETGW" run --config "$CONFIG" --bus-duration $BUS_SECONDS --duration $((240 * SCALE)) \
  > "$OUT/fleetgw.log" 2>&1 &
SERVICE=$!
# The simulated receiver's pty exists once the simulator runs; gpsd reads it from then on.
if wait_for 10 test -L "$PTY"; then
  "$GPSD" -N -n -b -S "$GPSD_PORT" "$PTY" > "$OUT/gpsd.log" 2>&1 &
  GPSD_PID=$!
else
  missed "GNSS: the simulator made no NMEA pty at $PTY"
fi
if wait_for 20 gateway_ready; then
  say "gateway: up, bike heard on the CAN bus, frame lock locked, broker connected"
else
  missed "gateway: not ready within 20 s (see $OUT/fleetgw.log)"
fi
command_step "remote unlock (frame lock)" frame unlock succeeded
if wait_for 20 located; then
  { read -r S_LAT; read -r S_LON; } < <(status_json | q get-fine gnss.lat gnss.lon) || true
  say "GNSS: fix at $S_LAT,$S_LON through gpsd; zones: bundle v1 from fleet/v1/zones accepted and stored"
  # Until the first fix the IoT node reports its GNSS fault (bit 0x0004), as a bike does at
  # power-up: the gateway says so on the bus and in the store, and clears it with the fix.
  if wait_for 10 fault_event cleared iot; then
    say "fault: $FAULT_NODE $FAULT_NAME ($FAULT_SEV) raised until the first fix, now cleared"
  else
    missed "fault: the IoT node's gps fault was not cleared within 10 s of the fix"
  fi
else
  missed "GNSS/zones: no fix or no zone bundle in force within 20 s (gnss.fix=$S_FIX, geofence.version=$S_ZONES_VERSION)"
fi

if wait_for 30 riding_fast; then
  say "ride: started; the bike rides at ${S_SPEED} km/h (fleetgw status)"
  command_step "remote lock (frame lock) at ${S_SPEED} km/h" frame lock rejected
else
  missed "ride: the bike did not start riding within 30 s"
fi

# A city caps the speed: the MC's speed-limit setting is written and read back (the result is
# `succeeded` only once the MC reports the new limit), and the bike then rides under it.
speed_limit_step() {  # KMH
  local out result reason rtt applied
  out=$("$FLEETGW" command --vehicle demo-bike-01 --speed-limit "$1" \
    --key "$OUT/operator.pem" --broker "$BROKER_URI" --timeout-s 10 2>> "$OUT/command.log" || true)
  echo "$out" >> "$OUT/commands.jsonl"
  { read -r result; read -r reason; read -r rtt; read -r applied; } < <(echo "$out" |
    q get result reason round_trip_ms mc.speed_limit_kmh) || true
  if [ -z "$result" ]; then
    missed "remote speed limit: no answer (see $OUT/command.log)"
    return
  fi
  local text="remote speed limit $1 km/h: $result, the MC reads back ${applied:-?} km/h,"
  [ "$result" = succeeded ] || text="remote speed limit $1 km/h: $result (${reason%%:*})"
  say "$text in $(awk -v ms="$rtt" 'BEGIN { printf "%.2f", ms / 1000 }') s"
  [ "$result" = succeeded ] || missed "remote speed limit: expected succeeded"
}
under_the_cap() {  # riding, and not faster than the cap (+0.5 km/h of quantisation)
  read_status
  awk -v v="${S_SPEED:-0}" -v cap="$SPEED_CAP" 'BEGIN { exit !(v >= 5 && v <= cap + 0.5) }'
}
SPEED_CAP=15
speed_limit_step $SPEED_CAP
if wait_for 20 under_the_cap; then
  say "status: the bike rides at ${S_SPEED} km/h, under the ${SPEED_CAP} km/h cap"
else
  missed "speed limit: the bike did not slow under ${SPEED_CAP} km/h within 20 s"
fi

if wait_for 40 fault_event raised; then
  say "fault: $FAULT_NODE $FAULT_NAME raised ($FAULT_SEV) on the climb"
else
  missed "fault: nothing raised within 40 s"
fi
read_status
[ -n "$S_RIDE_KM" ] &&
  say "status: ${S_SPEED} km/h, SOC ${S_SOC} %, open ride ${S_RIDE_KM} km in ${S_RIDE_MIN} min"
if wait_for 40 fault_event cleared; then
  say "fault: $FAULT_NODE $FAULT_NAME cleared"
else
  missed "fault: not cleared within 40 s"
fi

# The Old Town slow zone on the route: the gateway lowers the MC's limit along a ramp on entry
# (each step written and read back) and writes the operator's 15 km/h back on exit.
if wait_for 40 zone_event enter; then
  say "zone: entered slow zone '$ZONE_NAME' at $ZONE_LAT,$ZONE_LON: the limit ramps down to $ZONE_LIMIT km/h"
  SPEED_CAP=$ZONE_LIMIT
  if wait_for 20 under_the_cap; then
    say "status: the bike rides at ${S_SPEED} km/h in the slow zone, the MC's limit is ${S_LIMIT%.*} km/h"
  else
    missed "slow zone: the bike did not slow under $ZONE_LIMIT km/h within 20 s"
  fi
else
  missed "slow zone: not entered within 40 s"
fi
if wait_for 40 zone_event exit; then
  if wait_for 20 limit_is 15; then
    say "zone: left '$ZONE_NAME' at $ZONE_LAT,$ZONE_LON: the MC's limit is back to 15 km/h (the operator's cap)"
  else
    missed "slow zone: the limit did not return to 15 km/h within 20 s (now ${S_LIMIT:-?})"
  fi
else
  missed "slow zone: not left within 40 s"
fi

if wait_for 40 standing_after_ride; then
  say "ride: the bike stands (${S_RIDE_KM} km so far)"
  command_step "remote lock (frame lock)" frame lock succeeded
else
  missed "ride: the bike did not stop within 40 s"
fi
if wait_for 20 ride_closed && wait_for 20 ride_at_broker; then
  say "ride: ended by the lock and reached the broker: $RIDE_KM km in $RIDE_MIN min"
  { read -r TRACK_POINTS; read -r GNSS_KM; } < <(db_rows rides | python3 -c '
import json, sys
rows = [json.loads(l) for l in sys.stdin if l.strip()]
ride = next((r for r in rows if r.get("ride_id") == sys.argv[1]), {})
track = json.loads(ride.get("track") or "[]") if isinstance(ride.get("track"), str) else ride.get("track") or []
gnss_m = ride.get("gnss_distance_m") or 0
print(len(track)); print("%.2f" % (gnss_m / 1000))' "$RIDE_ID") || true
  "$FLEETGW" db export --table rides --format geojson --config "$CONFIG" > "$OUT/rides.geojson" 2>/dev/null || true
  if [ "${TRACK_POINTS:-0}" -ge 2 ]; then
    say "ride: GNSS track of $TRACK_POINTS points, ${GNSS_KM} km (odometer $RIDE_KM km): ${OUT#"$ROOT"/}/rides.geojson"
  else
    missed "ride: no GNSS track in the ride record"
  fi
else
  missed "ride: no closed ride at the broker within 40 s"
fi

if wait_for 30 alarm_event raised; then
  say "theft alarm: the locked bike moves (${ALARM_SPEED} km/h): unauthorised_movement raised"
else
  missed "theft alarm: not raised within 30 s"
fi
ALLOW_STOPPED=1
if wait_for 30 alarm_event cleared; then
  say "theft alarm: cleared once the bike stood still"
else
  missed "theft alarm: not cleared within 30 s"
fi
wait "$SERVICE" || missed "gateway: exit status $? (see $OUT/fleetgw.log)"
SERVICE=""
say "gateway: stopped at the end of the scenario ($BUS_SECONDS s of bus time)"

section "summary (fleetgw db summary)"
"$FLEETGW" db summary --config "$CONFIG" | tee "$OUT/summary.txt"

# --- the fleet's side: what an operator sees of the story in the console (docs/console.md) ---
# (No simulated fleet beside the bike: fleetgw fleet-sim places its vehicles around Berlin, far
# from the demo's Ljubljana, so the map shows the demo bike alone.)
section "the fleet in the console (fleetgw serve over the PostgreSQL that fleetgw ingest filled)"
T0=$SECONDS
WEB_PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
WEB=http://127.0.0.1:$WEB_PORT
WEB_PASSWORD=$(python3 -c 'import secrets; print(secrets.token_urlsafe(12))')
api() { curl -sf -m 5 -b "$OUT/console.cookies" "$WEB$1" 2>/dev/null || true; }
C_LAT="" C_LON="" C_ALARMS="" C_ALARM_KINDS="" C_VEHICLES="" C_ALARM_ROWS=""
console_knows_the_bike() {  # the bike's position and its theft alarm (raised and cleared) stored
  { read -r C_VEHICLES; read -r C_LAT; read -r C_LON; read -r C_ALARMS; read -r C_ALARM_KINDS; } < <(
    api /api/fleet | python3 -c '
import json, sys
try: fleet = json.load(sys.stdin).get("vehicles", [])
except ValueError: fleet = []
bike = next((v for v in fleet if v.get("id") == "demo-bike-01"), {})
f = lambda x: "" if x is None else "%.5f" % x
print(len(fleet)); print(f(bike.get("lat"))); print(f(bike.get("lon")))
alarms = bike.get("alarms") or {}
print(alarms.get("active", "")); print(",".join(alarms.get("kinds") or []))') || true
  C_ALARM_ROWS=$(api '/api/alarms?limit=100' | python3 -c '
import json, sys
try: rows = json.load(sys.stdin).get("alarms", [])
except ValueError: rows = []
theft = [r for r in rows if r.get("vehicle_id") == "demo-bike-01" and "UNAUTHORISED" in str(r.get("kind"))]
print(" then ".join(str(r.get("transition")).rsplit("_", 1)[-1].lower() for r in reversed(theft)))') || true
  [ -n "$C_LAT" ] && [ -n "$C_LON" ] && [[ $C_ALARM_ROWS == *raised*cleared* ]]
}
if [ $INGEST_READY = 1 ] &&
  printf '%s\n' "$WEB_PASSWORD" | "$FLEETGW" serve --pg "$PG" --add-operator demo --role operator \
    > "$OUT/serve-operator.log" 2>&1; then
  "$FLEETGW" serve --pg "$PG" --listen "127.0.0.1:$WEB_PORT" > "$OUT/serve.log" 2>&1 &
  SERVE=$!
  if wait_for 20 curl -sf -m 2 -o /dev/null "$WEB/api/health" &&
    curl -sf -m 5 -c "$OUT/console.cookies" -H 'Content-Type: application/json' \
      -d "{\"name\":\"demo\",\"password\":\"$WEB_PASSWORD\"}" "$WEB/api/login" > /dev/null; then
    say "console: up at $WEB, operator demo logged in through the API"
    if wait_for 20 console_knows_the_bike; then
      say "console: the demo bike demo-bike-01 at $C_LAT,$C_LON (/api/fleet); vehicles in the fleet: $C_VEHICLES"
      say "console: its theft alarm in the alarm feed (/api/alarms): unauthorised_movement $C_ALARM_ROWS, ${C_ALARMS:-0} still active"
    else
      missed "console: /api/fleet and /api/alarms do not show the demo bike's position and theft alarm within 20 s (lat=$C_LAT lon=$C_LON alarm=$C_ALARM_ROWS; see $OUT/ingest.log)"
    fi
  else
    missed "console: fleetgw serve did not answer or refused the login (see $OUT/serve.log)"
  fi
else
  missed "console: no database to serve, or the operator account was refused (see $OUT/serve-operator.log)"
fi
F=${FLEETGW#"$ROOT"/} C=${CONFIG#"$ROOT"/}
cat <<NEXT

== where to look next (from $ROOT)
  the ride in human units:     $F db rides --config $C
  each command and its reason: $F db commands --config $C
  the faults, the alarm:       $F db faults --config $C; $F db alarms --config $C
  the ride as a picture:       $F ride plot latest --config $C --out ride.svg
  the route on any map:        ${OUT#"$ROOT"/}/rides.geojson (fleetgw db export --table rides --format geojson)
  the zone crossings:          $F db export --table zone_events --config $C
  the telemetry for a sheet:   $F db export --table telemetry --format csv --config $C
  what reached the broker:     less ${OUT#"$ROOT"/}/subscriber.log
  the gateway's health:        $F status --config $C   (while the demo runs)
  the story in real time:      SPEED=1 ./scripts/demo.sh   (42 minutes)
  the fleet's database:        psql "$PG"   (while the demo runs)
  the operator console:        $WEB   user demo, password $WEB_PASSWORD
NEXT
echo
if [ $FAILED = 0 ]; then
  echo "demo: the whole story happened, in $((SECONDS - T0)) s"
else
  echo "demo: some steps did not happen (MISSED above)"
fi
# On a terminal the console stays up to be looked at; tests and CI (--build-dir, no terminal)
# end here. Ctrl-C works too: the EXIT trap stops everything either way.
if [ -t 0 ] && [ "$GIVEN_BUILD_DIR" = 0 ] && [ -n "$SERVE" ] && kill -0 "$SERVE" 2>/dev/null; then
  echo
  echo "the console runs at $WEB (user demo, password $WEB_PASSWORD); Enter stops the demo"
  read -r _ || true
fi
exit $FAILED
