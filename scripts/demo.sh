#!/usr/bin/env bash
# The live demo: a simulated MOTINOVA e-bike on an in-process CAN bus, the fleetgw service
# decoding it, storing rides/faults/telemetry in SQLite and publishing them to a local mosquitto,
# and a subscriber decoding what reaches the broker.
#   DURATION=seconds (default 40), SPEED=time acceleration (default 1: real time, so that
#   command expiry is judged on a real clock), SCENARIO=file
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
DURATION=${DURATION:-40}
SPEED=${SPEED:-1}
SCENARIO=${SCENARIO:-config/scenarios/demo.toml}

SECONDS=0
step() { echo "== [$1/6 $((SECONDS / 60))m$((SECONDS % 60))s] $2"; }

FLEETGW=build/gateway/app/fleetgw
if [ ! -x "$FLEETGW" ]; then
  echo "fleetgw demo: the first run installs the Debian packages it lacks and compiles fleetgw"
  echo "  (about 90 C++ files: roughly 5-8 minutes on 2 cores, seconds on later runs);"
  echo "  then the demo itself takes ${DURATION} s."
fi
step 1 "Debian packages (scripts/install-deps.sh)"
./scripts/install-deps.sh
# Same build directory and type as scripts/test.sh, so running both builds once.
step 2 "build fleetgw (build/, RelWithDebInfo; make's progress below)"
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build --target fleetgw fleetgw-watch -j "$(nproc)"

step 3 "private mosquitto, configuration, operator key"
DEMO=$ROOT/build/demo
rm -rf "$DEMO"
mkdir -p "$DEMO"

# A private mosquitto on a free loopback port.
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
cat > "$DEMO/mosquitto.conf" <<CONF
listener $PORT 127.0.0.1
allow_anonymous true
persistence false
set_tcp_nodelay true
log_dest stderr
CONF
mosquitto -c "$DEMO/mosquitto.conf" 2> "$DEMO/mosquitto.log" &
BROKER=$!
SUBSCRIBER=""
trap 'kill $BROKER 2>/dev/null || true; [ -z "$SUBSCRIBER" ] || kill $SUBSCRIBER 2>/dev/null || true' EXIT
# Wait until the broker accepts connections (at most 10 s), not a fixed time.
for _ in $(seq 100); do
  (exec 3<>"/dev/tcp/127.0.0.1/$PORT") 2>/dev/null && break
  kill -0 $BROKER 2>/dev/null || { cat "$DEMO/mosquitto.log"; exit 1; }
  sleep 0.1
done

sed -e "s#@PORT@#$PORT#g" -e "s#@DB@#$DEMO/fleetgw.db#g" -e "s#@SCENARIO@#$SCENARIO#g" \
  -e "s#@SPEED@#$SPEED#g" config/demo.toml.in > "$DEMO/fleetgw.toml"

# The operator's signing key, trusted by this gateway.
KEYLINE=$($FLEETGW keygen "$DEMO/operator" 2>/dev/null)
printf '\n[command.trusted_keys]\n%s\n' "$KEYLINE" >> "$DEMO/fleetgw.toml"

step 4 "subscriber: broker on 127.0.0.1:$PORT, output in $DEMO/subscriber.log"
$FLEETGW watch --broker "tcp://127.0.0.1:$PORT" --topic 'fleet/v1/#' > "$DEMO/subscriber.log" 2>&1 &
SUBSCRIBER=$!

# An operator unlocks and re-locks the seat lock remotely while the bike is parked, and tries
# to engage the frame lock while it rides (refused by the interlock).
operator() {
  sleep "$1"
  echo "== operator: $2 $3"
  $FLEETGW command --vehicle demo-bike-01 --lock "$2" --action "$3" --key "$DEMO/operator.pem" \
    --broker "tcp://127.0.0.1:$PORT" --timeout-s 10 || true
}
( operator 3 seat unlock; operator 2 seat lock; operator 3 frame lock ) &
OPERATOR=$!

step 5 "fleetgw run (simulated bike, ${SPEED}x time, ${DURATION}s)"
$FLEETGW run --config "$DEMO/fleetgw.toml" --live --duration "$DURATION"
wait $OPERATOR 2>/dev/null || true

step 6 "results"
# The subscriber may still be printing the last messages: wait until its log stops growing.
last=-1
for _ in $(seq 30); do
  size=$(stat -c %s "$DEMO/subscriber.log" 2>/dev/null || echo 0)
  [ "$size" = "$last" ] && break
  last=$size
  sleep 0.2
done
echo "== what reached the broker (decoded fleetgw.v1.Envelope messages)"
tail -n 15 "$DEMO/subscriber.log" || true
echo
echo "== the SQLite store"
$FLEETGW db stats --config "$DEMO/fleetgw.toml" || true
