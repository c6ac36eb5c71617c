#!/usr/bin/env bash
# What MQTT 5 costs on the wire and in CPU (issue 15, figures): two shipped `fleetgw run` side by
# side on the simulator's ride (config/scenarios/ride.toml) at speed 1 (real time: batching and
# status timers run on the wall clock), uplink on, one with [mqtt] protocol = "5" (content type,
# schema user property on every message, session expiry, will delay) and one with "3.1.1", each
# to its own mosquitto, so the broker's $SYS/broker/bytes/received is what that gateway sent
# (MQTT framing, pings included) and $SYS/broker/publish/messages/received its publishes. CPU is
# user + sys of the process (start-up included). Per-hour figures are the measured ones scaled
# by 60 / MINUTES. A benchmark, not a test.
# Environment: FLEETGW (binary, default build/bin/fleetgw), MINUTES (default 5, 1-20),
#   KEEP=1 keeps the work directory.
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=$(realpath "${FLEETGW:-build/bin/fleetgw}")
MINUTES=${MINUTES:-5}
[[ -x $FLEETGW ]] || { echo "mqtt5-overhead: no binary $FLEETGW" >&2; exit 1; }
command -v mosquitto_sub >/dev/null || { echo "mqtt5-overhead: needs mosquitto-clients" >&2; exit 1; }
(( MINUTES >= 1 && MINUTES <= 20 )) || { echo "mqtt5-overhead: MINUTES must be 1-20" >&2; exit 2; }

# shellcheck source=bench/lib-brokers.sh
source bench/lib-brokers.sh
bench_workdir fleetgw-mqtt5

write_config() {  # name protocol
  cat >"$WORK/$1.toml" <<TOML
[vehicle]
id = "bench-$1"
[log]
level = "warn"
[can]
transport = "sim"
[sim]
scenario = "$PWD/config/scenarios/ride.toml"
speed = 1
[storage]
path = "$WORK/$1.db"
[mqtt]
enabled = true
uri = "tcp://127.0.0.1:${PORT[$1]}"
protocol = "$2"
TOML
}

NAMES=(mqtt5 mqtt311)
for n in "${NAMES[@]}"; do start_broker "$n"; done
write_config mqtt5 5
write_config mqtt311 3.1.1
declare -A BASE_BYTES BASE_MSGS
for n in "${NAMES[@]}"; do
  BASE_BYTES[$n]=$(broker_stat "$n" bytes/received)
  BASE_MSGS[$n]=$(broker_stat "$n" publish/messages/received)
done

echo "mqtt5-overhead: two riding services for $MINUTES min at speed 1 ($FLEETGW)"
start_services "$MINUTES" "${NAMES[@]}"
wait_services mqtt5-overhead

printf '%-8s %10s %14s %10s %14s %12s %12s\n' run "CPU s" "CPU s / hour" bytes "bytes / hour" publishes "B / publish"
for n in "${NAMES[@]}"; do
  cpu=$(awk '{ print $1 + $2 }' "$WORK/$n.time")
  bytes=$(( $(broker_stat "$n" bytes/received) - BASE_BYTES[$n] ))
  msgs=$(( $(broker_stat "$n" publish/messages/received) - BASE_MSGS[$n] ))
  awk -v n="$n" -v c="$cpu" -v b="$bytes" -v p="$msgs" -v m="$MINUTES" 'BEGIN {
    printf "%-8s %10.2f %14.1f %10d %14d %12d %12.1f\n", n, c, c * 60 / m, b, b * 60 / m, p,
      (p > 0 ? b / p : 0) }'
done
