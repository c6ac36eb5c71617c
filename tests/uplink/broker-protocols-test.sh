#!/usr/bin/env bash
# uplink.broker_protocols: the shipped `fleetgw run` (simulated bike, demo scenario at 5x, 6 s)
# against real brokers, each case a fresh store and broker:
#   mqtt5     mosquitto, [mqtt] protocol = "5": mosquitto logs the client as p5, a v5 subscriber
#             sees every message with content type and schema user property, outbox empty after
#             the clean stop (the drain);
#   mqtt311   mosquitto, protocol = "3.1.1": logged as p2, no properties, outbox empty;
#   aedes311  aedes (npm: a second broker implementation, MQTT 3.1.1 only), protocol = "3.1.1":
#             a 3.1.1 subscriber receives telemetry, info and status, outbox empty;
#   aedes5    aedes with protocol = "5": it cannot connect, keeps its records, and its log says
#             to set protocol = "3.1.1";
#   acl5      mosquitto whose ACL denies the vehicle's telemetry topic (MQTT 5): `fleetgw status`
#             names the refusal (0x87, the topic; exit 1, ATTENTION) while the samples stay in
#             the outbox; after the ACL is fixed (mosquitto reloads it on SIGHUP) every sample
#             arrives exactly once (`fleetgw watch` decodes them) and the outbox empties.
#   broker-protocols-test.sh BUILD_DIR OUT_DIR
# Exit 0 pass, 1 fail, 77 skipped (mosquitto missing, or npm could not fetch aedes).
set -uo pipefail
build=${1:?usage: broker-protocols-test.sh BUILD_DIR OUT_DIR}
out=${2:?usage: broker-protocols-test.sh BUILD_DIR OUT_DIR}
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
fleetgw=$build/bin/fleetgw
mosquitto=$(command -v mosquitto || echo /usr/sbin/mosquitto)
if [ ! -x "$mosquitto" ] || ! command -v mosquitto_sub >/dev/null; then
  echo "SKIP: mosquitto / mosquitto_sub not installed"
  exit 77
fi
# aedes is fetched by npm on first use; only an unreachable npm makes this a skip.
"$root/tests/support/aedes/aedes-broker.sh" --install || exit $?
rm -rf "$out"
mkdir -p "$out"
failures=0
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done; wait 2>/dev/null; }
trap cleanup EXIT
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
free_port() {
  /usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'
}
wait_for() {  # wait_for SECONDS COMMAND...: polls the condition every 50 ms
  local until=$((SECONDS + $1))
  shift
  while ! "$@" 2>/dev/null; do
    [ "$SECONDS" -ge "$until" ] && return 1
    sleep 0.05
  done
}
port_open() { (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }
config() {  # config DIR VEHICLE PORT PROTOCOL [STATUS_SOCKET]
  cat > "$1/fleetgw.toml" <<EOF
[vehicle]
id = "$2"
[log]
level = "info"
[can]
transport = "sim"
[sim]
scenario = "$root/config/scenarios/demo.toml"
speed = 5
[storage]
path = "$1/fleetgw.db"
[status]
socket = "${5:-}"
[mqtt]
enabled = true
uri = "tcp://127.0.0.1:$3"
protocol = "$4"
telemetry_qos = 1
reconnect_min_ms = 100
reconnect_max_ms = 500
EOF
}
outbox_rows() {
  "$fleetgw" db stats --config "$1/fleetgw.toml" --format json |
    /usr/bin/python3 -c 'import json,sys; print(json.load(sys.stdin)["tables"]["outbox"])'
}
records_made() {
  "$fleetgw" db stats --config "$1/fleetgw.toml" --format json |
    /usr/bin/python3 -c 'import json,sys; print(json.load(sys.stdin)["outbox"]["next_seq"] - 1)'
}
start_mosquitto() {  # start_mosquitto DIR PORT [ACL_FILE]
  : > "$1/mosquitto.conf"
  [ -n "${3:-}" ] && echo "acl_file $3" >> "$1/mosquitto.conf"
  # As root, mosquitto would switch to the "mosquitto" user and lose access to the directory.
  [ "$(id -u)" = 0 ] && echo "user root" >> "$1/mosquitto.conf"
  cat >> "$1/mosquitto.conf" <<EOF
listener $2 127.0.0.1
allow_anonymous true
persistence false
log_dest file $1/mosquitto.log
log_type all
EOF
  "$mosquitto" -c "$1/mosquitto.conf" > "$1/mosquitto.stdout" 2>&1 &
  mosquitto_pid=$!
  pids+=($!)
  wait_for 10 port_open "$2" || fail "mosquitto did not start on $2"
}
start_aedes() {  # start_aedes DIR PORT
  "$root/tests/support/aedes/aedes-broker.sh" "$2" > "$1/aedes.log" 2>&1 &
  pids+=($!)
  wait_for 20 grep -q "^listening $2" "$1/aedes.log" || fail "aedes did not start: $(cat "$1/aedes.log")"
}
subscribe() {  # subscribe DIR PORT VERSION VEHICLE: every message as "topic|content type|user properties"
  mosquitto_sub -h 127.0.0.1 -p "$2" -V "$3" -i "sub-$4" -q 1 -t "fleet/v1/$4/#" -F '%t|%C|%P' \
    > "$1/sub.txt" 2> "$1/sub.err" &
  pids+=($!)
}
run_gateway() {  # run_gateway DIR: a clean stop after 6 s (the drain empties the outbox)
  timeout 60 "$fleetgw" run --config "$1/fleetgw.toml" --duration 6 > "$1/fleetgw.log" 2>&1
  echo "$1: fleetgw run exit $?, $(records_made "$1") records made, $(outbox_rows "$1") left"
}
has_topics() {  # has_topics FILE VEHICLE: telemetry, info and status arrived
  for leaf in telemetry info status; do grep -q "^fleet/v1/$2/$leaf|" "$1" || return 1; done
}

# ---- mosquitto, both protocols ----
for case in mqtt5 mqtt311; do
  d=$out/$case
  mkdir -p "$d"
  port=$(free_port)
  vehicle=bike-$case
  if [ "$case" = mqtt5 ]; then proto=5 sub=mqttv5 logged=p5; else proto=3.1.1 sub=mqttv311 logged=p2; fi
  start_mosquitto "$d" "$port"
  subscribe "$d" "$port" mqttv5 "$vehicle"
  wait_for 10 grep -q "Received SUBSCRIBE from sub-$vehicle" "$d/mosquitto.log" ||
    fail "$case: subscriber did not subscribe"
  config "$d" "$vehicle" "$port" "$proto"
  run_gateway "$d"
  grep -q "as $vehicle ($logged," "$d/mosquitto.log" || fail "$case: mosquitto did not log $vehicle as $logged"
  [ "$(outbox_rows "$d")" = 0 ] || fail "$case: records left in the outbox ($(outbox_rows "$d"))"
  wait_for 10 has_topics "$d/sub.txt" "$vehicle" || fail "$case: telemetry/info/status not all received"
  if [ "$case" = mqtt5 ]; then
    bad=$(grep -v "|application/x-protobuf; proto=fleetgw.v1.Envelope|schema:1\.[0-9]*$" "$d/sub.txt" | head -3)
    [ -z "$bad" ] || fail "mqtt5: messages without content type / schema property: $bad"
  else
    bad=$(grep -v "^[^|]*||$" "$d/sub.txt" | head -3)
    [ -z "$bad" ] || fail "mqtt311: a 3.1.1 publish carried properties: $bad"
  fi
  echo "$case: $(wc -l < "$d/sub.txt") messages at the subscriber"
done

# ---- aedes: 3.1.1 delivers; 5 is refused with a clear reason ----
d=$out/aedes311
mkdir -p "$d"
port=$(free_port)
start_aedes "$d" "$port"
subscribe "$d" "$port" mqttv311 bike-aedes
wait_for 10 grep -q '^subscribe "sub-bike-aedes" "fleet/v1/bike-aedes/#"' "$d/aedes.log" ||
  fail "aedes311: subscriber did not subscribe"
config "$d" bike-aedes "$port" 3.1.1
run_gateway "$d"
[ "$(outbox_rows "$d")" = 0 ] || fail "aedes311: records left in the outbox ($(outbox_rows "$d"))"
wait_for 10 has_topics "$d/sub.txt" bike-aedes || fail "aedes311: telemetry/info/status not all received"
grep -q '^publish "bike-aedes" "fleet/v1/bike-aedes/telemetry"' "$d/aedes.log" ||
  fail "aedes311: aedes saw no telemetry from bike-aedes"
echo "aedes311: $(wc -l < "$d/sub.txt") messages at the subscriber"

d=$out/aedes5
mkdir -p "$d"
config "$d" bike-aedes5 "$port" 5
run_gateway "$d"
grep -q 'set \[mqtt\] protocol = "3.1.1"' "$d/fleetgw.log" ||
  fail "aedes5: the log does not say to use protocol 3.1.1: $(grep 'cannot connect' "$d/fleetgw.log" | head -2)"
[ "$(outbox_rows "$d")" -gt 0 ] || fail "aedes5: records vanished although nothing was delivered"
grep "cannot connect" "$d/fleetgw.log" | head -1

# ---- an ACL that refuses the telemetry topic, under MQTT 5 ----
d=$out/acl5
mkdir -p "$d"
port=$(free_port)
acl() {  # acl TELEMETRY_ALLOWED
  echo "topic read fleet/v1/#"
  for leaf in status state info lock pack ride fault alarm eviction cmd/result; do
    echo "topic write fleet/v1/bike-acl/$leaf"
  done
  [ "$1" = yes ] && echo "topic write fleet/v1/bike-acl/telemetry"
}
acl no > "$d/acl"
start_mosquitto "$d" "$port" "$d/acl"
"$fleetgw" watch --broker "tcp://127.0.0.1:$port" --topic fleet/v1/bike-acl/telemetry \
  > "$d/watch.jsonl" 2> "$d/watch.err" &
pids+=($!)
wait_for 10 grep -q "Received SUBSCRIBE from" "$d/mosquitto.log" || fail "acl5: watch did not subscribe"
config "$d" bike-acl "$port" 5 "$d/status.sock"
"$fleetgw" run --config "$d/fleetgw.toml" --duration 120 > "$d/fleetgw.log" 2>&1 &
gw=$!
pids+=($gw)
refused() {  # (status exits 1 while it needs attention: only its JSON counts here)
  { "$fleetgw" status --config "$d/fleetgw.toml" --format json || true; } |
    /usr/bin/python3 -c 'import json,sys; b=json.load(sys.stdin)["broker"]; sys.exit(0 if b.get("last_publish_refusal","").startswith("0x87") else 1)'
}
accepted() {
  { "$fleetgw" status --config "$d/fleetgw.toml" --format json || true; } |
    /usr/bin/python3 -c 'import json,sys; j=json.load(sys.stdin); b=j["broker"]; sys.exit(0 if b.get("last_publish_refusal") == "" and b.get("publish_refusals",0) > 0 else 1)'
}
if wait_for 30 refused; then
  "$fleetgw" status --config "$d/fleetgw.toml" > "$d/status.txt" 2>&1
  rc=$?
  cat "$d/status.txt"
  [ "$rc" = 1 ] || fail "acl5: fleetgw status exit $rc while publishes are refused (want 1)"
  grep -q "publishes REFUSED: 0x87 Not authorized (fleet/v1/bike-acl/telemetry)" "$d/status.txt" ||
    fail "acl5: fleetgw status does not name the refusal"
  grep -q "ATTENTION: broker refuses publishes: 0x87" "$d/status.txt" ||
    fail "acl5: no attention line for the refusal"
  [ "$(grep -c 'the broker refused a publish: 0x87' "$d/fleetgw.log")" = 1 ] ||
    fail "acl5: the refusal is not logged exactly once"
else
  fail "acl5: fleetgw status never named a refusal"
fi
acl yes > "$d/acl"
kill -HUP "$mosquitto_pid"  # mosquitto reloads its configuration, the ACL with it
wait_for 30 accepted || fail "acl5: the refusal did not clear after the ACL was fixed"
kill -TERM "$gw"
wait "$gw" 2>/dev/null
[ "$(outbox_rows "$d")" = 0 ] || fail "acl5: records left in the outbox ($(outbox_rows "$d"))"
made=$("$fleetgw" db stats --config "$d/fleetgw.toml" --format json |
  /usr/bin/python3 -c 'import json,sys; print(json.load(sys.stdin)["tables"]["telemetry"])')
count_samples() {  # prints "received unique" telemetry sample sequences seen by watch
  /usr/bin/python3 -c '
import json, sys
seqs = []
for line in open(sys.argv[1]):
    try:
        env = json.loads(line)
    except ValueError:
        continue
    body = env.get("telemetry") or env.get("envelope", {}).get("telemetry") or {}
    seqs += [int(s["sequence"]) for s in body.get("samples", [])]
print(len(seqs), len(set(seqs)))' "$d/watch.jsonl"
}
has_all() { read -r n u < <(count_samples); [ "$u" -ge "$made" ]; }
wait_for 10 has_all || true
read -r received unique < <(count_samples)
echo "acl5: $made samples made, $received received, $unique distinct"
[ "$made" -gt 0 ] && [ "$received" = "$made" ] && [ "$unique" = "$made" ] ||
  fail "acl5: want each of the $made samples exactly once, got $received ($unique distinct)"

echo "== $failures failure(s)"
[ "$failures" -eq 0 ]
