#!/usr/bin/env bash
# Parked against riding (issue 13, figures): CPU and bytes on the wire per hour of the shipped
# `fleetgw run` on the simulator at speed 1 (real time: the uplink's batching and status timers
# run on the wall clock, so an accelerated simulation would squeeze an hour of them into a
# minute), uplink on to a local mosquitto. Three services run side by side for MINUTES each:
#   parked      config/scenarios/parked.toml (locked, still), parked mode on (the default);
#   parked-off  the same bike with [parked] enabled = false: what parked mode saves;
#   riding      config/scenarios/ride.toml (a ride from the first seconds).
# Each has its own broker, so the broker's $SYS/broker/bytes/received is what that gateway sent
# (MQTT framing, pings and reconnects included; the counter's own subscriber adds one CONNECT
# and one SUBSCRIBE, < 100 bytes). CPU is user + sys of the process (start-up included). Per-hour
# figures are the measured ones scaled by 60 / MINUTES. A benchmark, not a test.
# Environment: FLEETGW (binary, default build/bin/fleetgw), MINUTES (10: the parked
#   scenario lasts 10 minutes), KEEP=1 keeps the work directory.
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=$(realpath "${FLEETGW:-build/bin/fleetgw}")
MINUTES=${MINUTES:-10}
[[ -x $FLEETGW ]] || { echo "parked-vs-riding: no binary $FLEETGW" >&2; exit 1; }
command -v mosquitto_sub >/dev/null || { echo "parked-vs-riding: needs mosquitto-clients" >&2; exit 1; }
(( MINUTES >= 1 && MINUTES <= 10 )) || { echo "parked-vs-riding: MINUTES must be 1-10" >&2; exit 2; }

# shellcheck source=bench/lib-brokers.sh
source bench/lib-brokers.sh
bench_workdir fleetgw-parked

write_config() {  # name scenario parked-enabled
  cat >"$WORK/$1.toml" <<TOML
[vehicle]
id = "bench-$1"
[log]
level = "warn"
[can]
transport = "sim"
[sim]
scenario = "$PWD/config/scenarios/$2.toml"
speed = 1
[storage]
path = "$WORK/$1.db"
[mqtt]
enabled = true
uri = "tcp://127.0.0.1:${PORT[$1]}"
[parked]
enabled = $3
TOML
}

NAMES=(parked parked-off riding)
for n in "${NAMES[@]}"; do start_broker "$n"; done
write_config parked parked true
write_config parked-off parked false
write_config riding ride true
declare -A BASE
for n in "${NAMES[@]}"; do BASE[$n]=$(broker_stat "$n" bytes/received); done

echo "parked-vs-riding: three services for $MINUTES min at speed 1 ($FLEETGW)"
start_services "$MINUTES" "${NAMES[@]}"
wait_services parked-vs-riding

printf '%-11s %12s %16s %14s %16s\n' run "CPU s" "CPU s / hour" "bytes" "bytes / hour"
for n in "${NAMES[@]}"; do
  cpu=$(awk '{ print $1 + $2 }' "$WORK/$n.time")
  bytes=$(( $(broker_stat "$n" bytes/received) - BASE[$n] ))
  awk -v n="$n" -v c="$cpu" -v b="$bytes" -v m="$MINUTES" 'BEGIN {
    printf "%-11s %12.2f %16.1f %14d %16d\n", n, c, c * 60 / m, b, b * 60 / m }'
done
