#!/usr/bin/env bash
# What positions and tracks add to the wire (issue 14, figures): bytes per riding hour of the
# shipped `fleetgw run` with and without GNSS, side by side on the same simulated ride at speed 1
# (real time: the uplink's batching and status timers run on the wall clock), each to a private
# mosquitto of its own:
#   gnss     config/scenarios/city-route.toml with its [[route]] served as NMEA on a pty
#            ([sim] nmea_pty), a real gpsd reading it, [gnss] enabled: positions in telemetry,
#            state and lock events, the ride's track and GNSS distance in its record;
#   no-gnss  the same bike and ride without [gnss].
# Bytes are the broker's $SYS/broker/bytes/received (MQTT framing and pings included); per-hour
# figures are scaled by 60 / MINUTES. The ride record (with its track) is sent once the ride
# ends: MINUTES >= 16 includes it (the scenario's ride ends at 15.8 min), fewer leave it out.
# CPU is user + sys of each process. A benchmark, not a test.
# Environment: FLEETGW (default build/bin/fleetgw), MINUTES (default 17, 1-17),
#   KEEP=1 keeps the work directory.
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=$(realpath "${FLEETGW:-build/bin/fleetgw}")
MINUTES=${MINUTES:-17}
[[ -x $FLEETGW ]] || { echo "gnss-bytes: no binary $FLEETGW" >&2; exit 1; }
command -v mosquitto_sub >/dev/null || { echo "gnss-bytes: needs mosquitto-clients" >&2; exit 1; }
GPSD=$(command -v gpsd || echo /usr/sbin/gpsd)
[[ -x $GPSD ]] || { echo "gnss-bytes: needs gpsd (scripts/install-deps.sh)" >&2; exit 1; }
(( MINUTES >= 1 && MINUTES <= 17 )) || { echo "gnss-bytes: MINUTES must be 1-17" >&2; exit 2; }

# shellcheck source=bench/lib-brokers.sh
source bench/lib-brokers.sh
bench_workdir fleetgw-gnss-bytes

GPSD_PORT=$(free_port)
write_config() {  # name with-gnss
  cat >"$WORK/$1.toml" <<TOML
[vehicle]
id = "bench-$1"
[log]
level = "warn"
[can]
transport = "sim"
[sim]
scenario = "$PWD/config/scenarios/city-route.toml"
speed = 1
$([[ $2 == true ]] && echo "nmea_pty = \"$WORK/sim-gps\"")
[storage]
path = "$WORK/$1.db"
[mqtt]
enabled = true
uri = "tcp://127.0.0.1:${PORT[$1]}"
$([[ $2 == true ]] && printf '[gnss]\nenabled = true\ngpsd = "127.0.0.1:%s"\nreconnect_max_ms = 1000\n' "$GPSD_PORT")
TOML
}

NAMES=(gnss no-gnss)
for n in "${NAMES[@]}"; do start_broker "$n"; done
write_config gnss true
write_config no-gnss false
declare -A BASE
for n in "${NAMES[@]}"; do BASE[$n]=$(broker_stat "$n" bytes/received); done

echo "gnss-bytes: two services for $MINUTES min at speed 1 ($FLEETGW)"
start_services "$MINUTES" "${NAMES[@]}"
for _ in $(seq 100); do [[ -L $WORK/sim-gps ]] && break; sleep 0.1; done
[[ -L $WORK/sim-gps ]] || { echo "gnss-bytes: the simulator made no NMEA pty" >&2; exit 1; }
"$GPSD" -N -n -b -S "$GPSD_PORT" "$WORK/sim-gps" >"$WORK/gpsd.log" 2>&1 &
PIDS+=($!)
wait_services gnss-bytes

printf '%-8s %10s %14s %12s %14s\n' run "CPU s" "CPU s / hour" "bytes" "bytes / hour"
declare -A PER_HOUR
for n in "${NAMES[@]}"; do
  cpu=$(awk '{ print $1 + $2 }' "$WORK/$n.time")
  bytes=$(( $(broker_stat "$n" bytes/received) - BASE[$n] ))
  PER_HOUR[$n]=$(( bytes * 60 / MINUTES ))
  awk -v n="$n" -v c="$cpu" -v b="$bytes" -v m="$MINUTES" 'BEGIN {
    printf "%-8s %10.2f %14.1f %12d %14d\n", n, c, c * 60 / m, b, b * 60 / m }'
done
added=$(( PER_HOUR[gnss] - PER_HOUR[no-gnss] ))
awk -v a="$added" -v b="${PER_HOUR[no-gnss]}" 'BEGIN {
  printf "positions and tracks add %d bytes per riding hour (%+.1f %%)\n", a, 100 * a / b }'
track=$(sqlite3 "$WORK/gnss.db" "SELECT coalesce(length(track), 0) || ' bytes, ' ||
  coalesce(round(gnss_distance_m), 0) || ' m' FROM rides ORDER BY id DESC LIMIT 1" 2>/dev/null || true)
echo "the ride's stored track: ${track:-none (the ride had not ended)}"
