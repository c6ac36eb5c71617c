#!/usr/bin/env bash
# Performance of `fleetgw run` (issue 3): CPU time and peak resident memory.
#
#   1. 30-minute ride: `fleetgw sim --record` writes 1800 s of config/scenarios/ride.toml as a
#      candump -L log; `fleetgw run --replay` plays it as fast as possible under /usr/bin/time -v.
#      CPU seconds per bus-hour = (user + sys) * 3600 / 1800, i.e. the % of one core the
#      service would use at the real-time load of that ride.
#   2. Real time: the first REALTIME_S seconds of the same log replayed at recorded speed
#      (can.replay_speed = 1), measured directly (includes the event loop's timer wake-ups).
#   3. Saturated bus: the ride log's valid MOTINOVA traffic time-compressed to SAT_FPS frames/s
#      (default 2200, a 250 kbit/s bus at ~100 % load with 8-byte frames) for SAT_S seconds,
#      replayed as fast as possible: speed = bus seconds / wall seconds (target >= 100x).
#   4. Steady state with the uplink: `fleetgw run` on the simulator (config/scenarios/ride.toml)
#      at speed 1 for REALTIME_S seconds with [mqtt] enabled, over TLS to a local mosquitto
#      (certificates made with openssl for the run), so the figure includes Paho and OpenSSL:
#      CPU % of one core (user + sys / wall) and VmRSS near the end; the resident memory of each
#      mapping is listed (UPLINK=0 skips this run).
#   5. Real time against replay of the same traffic (issue 12, target <= 2x): the simulator at
#      speed 1 for REALTIME_S s, no uplink (bike simulation included, so an upper bound), and
#      the same scenario recorded for REALTIME_S s and replayed as fast as possible; also the
#      replay at recorded speed of run 2 against the same log replayed fast. CPU = user + sys of
#      the whole process (start-up included in both).
#
# The store is a temporary SQLite file, MQTT is disabled (but in run 4), log level warn.
# Environment: BUILD_DIR (default build-bench-runtime, configured like the package:
#   RelWithDebInfo, static protobuf/SQLite),
#   FLEETGW (binary; overrides BUILD_DIR), RIDE_S (1800), REALTIME_S (60), SAT_S (60),
#   SAT_FPS (2200), KEEP=1 keeps the work directory.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
RIDE_S=${RIDE_S:-1800}
REALTIME_S=${REALTIME_S:-60}
SAT_S=${SAT_S:-60}
SAT_FPS=${SAT_FPS:-2200}

if [[ -z ${FLEETGW:-} ]]; then
  BUILD_DIR=${BUILD_DIR:-build-bench-runtime}
  if [[ ! -f $BUILD_DIR/CMakeCache.txt ]]; then
    cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFLEETGW_BUILD_TESTS=OFF \
      -DFLEETGW_BUILD_BENCH=OFF >/dev/null
  fi
  cmake --build "$BUILD_DIR" --target fleetgw -j "$(nproc)" >/dev/null
  FLEETGW=$(find "$BUILD_DIR" -type f -name fleetgw -perm -u+x | head -1)
fi
[[ -x $FLEETGW ]] || { echo "bench-runtime: no fleetgw binary" >&2; exit 1; }
BUILD_TYPE=$(grep -s "^CMAKE_BUILD_TYPE:" "$(dirname "$FLEETGW")/../../CMakeCache.txt" | cut -d= -f2 || true)
BUILD_TYPE=${BUILD_TYPE:-RelWithDebInfo (project default)}

WORK=$(mktemp -d /tmp/fleetgw-bench-XXXXXX)
if [[ -z ${KEEP:-} ]]; then trap 'rm -rf "$WORK"' EXIT; fi

config() {  # file replay_speed
  mkdir -p "$WORK/db-$(basename "$1" .toml)"  # the service does not create it
  cat >"$1" <<EOF
[log]
level = "warn"
[can]
transport = "replay"
replay_speed = $2
[storage]
path = "$WORK/db-$(basename "$1" .toml)/fleetgw.db"
[mqtt]
enabled = false
EOF
}

# measure NAME -- command...: runs under /usr/bin/time -v; sets CPU (s, microsecond resolution
# from bench/cputime.py: /usr/bin/time's 10 ms cannot compare a 60 s replay with its real-time
# run), RSS (KiB), WALL (s).
measure() {
  local name=$1
  shift 2
  python3 "$ROOT/bench/cputime.py" "$WORK/$name.cpu" /usr/bin/time -v -o "$WORK/$name.time" "$@" \
    >"$WORK/$name.out" 2>"$WORK/$name.err" || {
    echo "bench-runtime: $name failed:" >&2
    tail -20 "$WORK/$name.err" >&2
    exit 1
  }
  RSS=$(awk -F': ' '/Maximum resident set size/ {print $2}' "$WORK/$name.time")
  WALL=$(awk -F': ' '/Elapsed \(wall clock\)/ {print $2}' "$WORK/$name.time" |
    awk -F: '{ s = 0; for (i = 1; i <= NF; ++i) s = s * 60 + $i; print s }')
  CPU=$(awk '{ printf "%.6f", $1 + $2 }' "$WORK/$name.cpu")
}

echo "fleetgw: $FLEETGW ($BUILD_TYPE), $(nproc) cores, $(uname -m)"

# 1. The 30-minute ride, as fast as possible.
"$FLEETGW" sim --scenario config/scenarios/ride.toml --duration "$RIDE_S" \
  --record "$WORK/ride.log" 2>/dev/null
RIDE_FRAMES=$(wc -l <"$WORK/ride.log")
config "$WORK/fast.toml" 0
measure ride -- "$FLEETGW" run --config "$WORK/fast.toml" --replay "$WORK/ride.log"
RIDE_CPU=$CPU RIDE_RSS=$RSS RIDE_WALL=$WALL
RIDE_CPU_PER_HOUR=$(echo "$RIDE_CPU * 3600 / $RIDE_S" | bc -l)
RIDE_CORE_PCT=$(echo "$RIDE_CPU_PER_HOUR / 3600 * 100" | bc -l)

# Process baseline: the binary and its shared libraries, doing nothing.
measure baseline -- "$FLEETGW" --version
BASE_RSS=$RSS

# 2. Real time: REALTIME_S seconds of the ride at recorded speed. Besides Max RSS (which counts
#    the clean, file-backed pages of the binary and every shared library), /proc/PID/smaps_rollup
#    is sampled every second for PSS and Private_Dirty (the memory the process really owns).
head -n "$(awk -v s="$REALTIME_S" 'NR == 1 { gsub(/[()]/, "", $1); t0 = $1 }
  { gsub(/[()]/, "", $1); if ($1 - t0 > s) { print NR - 1; exit } }' "$WORK/ride.log")" \
  "$WORK/ride.log" >"$WORK/realtime.log"
config "$WORK/realtime.toml" 1.0
(
  sleep 2
  pid=$(pgrep -n -f -- "--replay $WORK/realtime.log" || true)
  while [[ -n $pid && -r /proc/$pid/smaps_rollup ]]; do
    awk '/^(Pss|Private_Dirty):/ {printf "%s %s ", $1, $2} END {print ""}' \
      "/proc/$pid/smaps_rollup" 2>/dev/null || true
    sleep 1
  done >"$WORK/realtime.smaps"
) &
SAMPLER=$!
measure realtime -- "$FLEETGW" run --config "$WORK/realtime.toml" --replay "$WORK/realtime.log"
wait "$SAMPLER" || true
RT_CPU=$CPU RT_RSS=$RSS RT_WALL=$WALL
RT_PSS=$(awk '{ for (i = 1; i < NF; i += 2) if ($i == "Pss:" && $(i + 1) > m) m = $(i + 1) } END { print m + 0 }' "$WORK/realtime.smaps")
RT_DIRTY=$(awk '{ for (i = 1; i < NF; i += 2) if ($i == "Private_Dirty:" && $(i + 1) > m) m = $(i + 1) } END { print m + 0 }' "$WORK/realtime.smaps")
RT_CORE_PCT=$(echo "$RT_CPU / $RT_WALL * 100" | bc -l)

# 3. Saturated bus: the ride's traffic (every frame valid) re-timed to SAT_FPS frames/s, the
#    ride log repeated with a time offset when it is shorter than SAT_S * SAT_FPS frames.
NEED=$((SAT_S * SAT_FPS))
awk -v need="$NEED" -v fps="$SAT_FPS" '
  { lines[NR] = $0 }
  END {
    n = 0; t0 = 1717228800
    while (n < need) {
      for (i = 1; i <= NR && n < need; ++i) {
        split(lines[i], f, " ")
        us = int(n * 1000000 / fps)
        printf "(%d.%06d) %s %s\n", t0 + int(us / 1000000), us % 1000000, f[2], f[3]
        ++n
      }
    }
  }' "$WORK/ride.log" >"$WORK/saturated.log"
SAT_FRAMES=$(wc -l <"$WORK/saturated.log")
measure saturated -- "$FLEETGW" run --config "$WORK/fast.toml" --replay "$WORK/saturated.log"
SAT_CPU=$CPU SAT_RSS=$RSS SAT_WALL=$WALL
SAT_SPEED=$(echo "$SAT_S / $SAT_WALL" | bc -l)
SAT_CHECK=$("$FLEETGW" decode "$WORK/saturated.log" 2>&1 >/dev/null | tail -1)

# 4. Real time with the uplink over TLS.
UP_RSS=0
if [[ ${UPLINK:-1} != 0 ]] && command -v mosquitto >/dev/null && command -v openssl >/dev/null; then
  TLS=$WORK/tls
  mkdir -p "$TLS"
  chmod 755 "$WORK" "$TLS"
  openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 2 \
    -subj /CN=bench-ca -keyout "$TLS/ca.key" -out "$TLS/ca.crt" 2>/dev/null
  openssl req -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -subj /CN=localhost \
    -keyout "$TLS/broker.key" -out "$TLS/broker.csr" 2>/dev/null
  printf 'subjectAltName=DNS:localhost,IP:127.0.0.1\n' >"$TLS/san.ext"
  openssl x509 -req -in "$TLS/broker.csr" -CA "$TLS/ca.crt" -CAkey "$TLS/ca.key" \
    -CAcreateserial -days 2 -extfile "$TLS/san.ext" -out "$TLS/broker.crt" 2>/dev/null
  chmod 644 "$TLS"/*
  PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
  {
    [[ $(id -u) == 0 ]] && echo "user root"
    echo "listener $PORT 127.0.0.1"
    echo "allow_anonymous true"
    echo "set_tcp_nodelay true"
    echo "cafile $TLS/ca.crt"
    echo "certfile $TLS/broker.crt"
    echo "keyfile $TLS/broker.key"
  } >"$TLS/mosquitto.conf"
  mosquitto -c "$TLS/mosquitto.conf" 2>"$TLS/mosquitto.log" &
  BROKER=$!
  sleep 0.5
  config "$WORK/uplink.toml" 1.0
  sed -i '/^\[mqtt\]/,$d; s/^transport = .*/transport = "sim"/; /^replay_speed/d' "$WORK/uplink.toml"
  printf '[mqtt]\nenabled = true\nuri = "ssl://localhost:%s"\nca_file = "%s"\n[vehicle]\nid = "bench-bike"\n[sim]\nscenario = "%s"\nspeed = 1.0\n' \
    "$PORT" "$TLS/ca.crt" "$ROOT/config/scenarios/ride.toml" >>"$WORK/uplink.toml"
  (
    sleep $((REALTIME_S - 5))
    pid=$(pgrep -n -f -- "--config $WORK/uplink.toml" || true)
    [[ -n $pid ]] && awk '/^[0-9a-f]+-[0-9a-f]+ / { name = ($6 == "" ? "[anon]" : $6) }
      /^Rss:/ { rss[name] += $2 }
      END { for (n in rss) if (rss[n] >= 100) { m = n; sub(/.*\//, "", m); printf "%6d KB  %s\n", rss[n], m } }' \
      "/proc/$pid/smaps" | sort -rn >"$WORK/uplink.maps"
    [[ -n $pid ]] && awk '/^VmRSS/ { print $2 }' "/proc/$pid/status" >"$WORK/uplink.vmrss"
    # Wake-ups by thread (the event loop, Paho's send and receive threads): who costs the CPU.
    for t in /proc/"$pid"/task/*; do
      printf '%-16s %s wake-ups\n' "$(cat "$t/comm")" \
        "$(awk '/^voluntary_ctxt_switches/ { print $2 }' "$t/status")"
    done >"$WORK/uplink.threads" 2>/dev/null || true
  ) &
  SAMPLER=$!
  measure uplink -- "$FLEETGW" run --config "$WORK/uplink.toml" --duration "$REALTIME_S"
  wait "$SAMPLER" || true
  UP_VMRSS=$(cat "$WORK/uplink.vmrss" 2>/dev/null || echo 0)
  kill "$BROKER" 2>/dev/null || true
  UP_RSS=$RSS UP_CPU=$CPU UP_WALL=$WALL
  grep -q "connected from .* as bench-bike" "$TLS/mosquitto.log" ||
    echo "bench-runtime: warning: the uplink never connected (see $WORK/tls/mosquitto.log)" >&2
fi

# 5. Real time against replay of the same traffic.
sed 's/^transport = .*/transport = "sim"/; /^replay_speed/d' "$WORK/realtime.toml" >"$WORK/sim1.toml"
sed -i "s|db-realtime|db-sim1|" "$WORK/sim1.toml"
mkdir -p "$WORK/db-sim1"
printf '[sim]\nscenario = "%s"\nspeed = 1.0\n' "$ROOT/config/scenarios/ride.toml" >>"$WORK/sim1.toml"
measure sim1 -- "$FLEETGW" run --config "$WORK/sim1.toml" --duration "$REALTIME_S"
SIM1_CPU=$CPU SIM1_WALL=$WALL
"$FLEETGW" sim --scenario config/scenarios/ride.toml --duration "$REALTIME_S" \
  --record "$WORK/sim1.log" 2>/dev/null
config "$WORK/sim1fast.toml" 0
measure sim1fast -- "$FLEETGW" run --config "$WORK/sim1fast.toml" --replay "$WORK/sim1.log"
SIM1FAST_CPU=$CPU
config "$WORK/rtfast.toml" 0
measure rtfast -- "$FLEETGW" run --config "$WORK/rtfast.toml" --replay "$WORK/realtime.log"
RTFAST_CPU=$CPU
# The service's own start and stop (store opened and closed, nothing to replay): both runs above
# pay it once, whatever their length.
: >"$WORK/empty.log"
config "$WORK/startup.toml" 0
measure startup -- "$FLEETGW" run --config "$WORK/startup.toml" --replay "$WORK/empty.log"
STARTUP_CPU=$CPU

printf '\n%-44s %12s %12s %12s %12s\n' "run" "bus time" "wall" "CPU (u+s)" "max RSS"
printf '%-44s %10ss %10.2fs %10.2fs %9.1f MB\n' \
  "30-min ride ($RIDE_FRAMES frames), as fast as possible" "$RIDE_S" "$RIDE_WALL" "$RIDE_CPU" \
  "$(echo "$RIDE_RSS / 1024" | bc -l)"
printf '%-44s %10ss %10.2fs %10.2fs %9.1f MB\n' \
  "ride at recorded speed (real time)" "$REALTIME_S" "$RT_WALL" "$RT_CPU" \
  "$(echo "$RT_RSS / 1024" | bc -l)"
if [[ $UP_RSS != 0 ]]; then
  printf '%-44s %10ss %10.2fs %10.2fs %9.1f MB\n' \
    "sim at speed 1 + uplink (MQTT over TLS)" "$REALTIME_S" "$UP_WALL" "$UP_CPU" \
    "$(echo "$UP_RSS / 1024" | bc -l)"
fi
printf '%-44s %10s %10s %10s %9.1f MB\n' \
  "process baseline (fleetgw --version)" "-" "-" "-" "$(echo "$BASE_RSS / 1024" | bc -l)"
printf '%-44s %10ss %10.2fs %10.2fs %9.1f MB\n' \
  "saturated bus, $SAT_FPS frames/s ($SAT_FRAMES frames)" "$SAT_S" "$SAT_WALL" "$SAT_CPU" \
  "$(echo "$SAT_RSS / 1024" | bc -l)"
echo
printf 'CPU per hour of riding (from the 30-min replay): %.2f s/h = %.3f %% of one core (target < 0.5 %%)\n' \
  "$RIDE_CPU_PER_HOUR" "$RIDE_CORE_PCT"
printf 'CPU at real time, measured:                      %.3f %% of one core (target < 0.5 %%)\n' \
  "$RT_CORE_PCT"
printf 'Peak RSS at real-time load:                      %.1f MB (target < 10 MB); PSS %.1f MB, private dirty %.1f MB\n' \
  "$(echo "$RT_RSS / 1024" | bc -l)" "$(echo "$RT_PSS / 1024" | bc -l)" "$(echo "$RT_DIRTY / 1024" | bc -l)"
printf 'Saturated 250 kbit/s bus replay speed:           %.0fx real time (target >= 100x)\n' \
  "$SAT_SPEED"
echo "Saturated log check (fleetgw decode):           $SAT_CHECK"
printf 'Real time / replay, same traffic (sim at speed 1 / its recording replayed fast): %.3f s / %.3f s CPU = %.1fx (target <= 2x)\n' \
  "$SIM1_CPU" "$SIM1FAST_CPU" "$(echo "$SIM1_CPU / $SIM1FAST_CPU" | bc -l)"
printf 'Real time / replay, same log (replay at 1x / as fast as possible):              %.3f s / %.3f s CPU = %.1fx\n' \
  "$RT_CPU" "$RTFAST_CPU" "$(echo "$RT_CPU / $RTFAST_CPU" | bc -l)"
printf 'Per bus-second beyond start-up (%.3f s): real time %.1f ms, replay %.2f ms, %.0fx; the real-time run wakes ~6 times a second for the spec'"'"'s 1 s fault word and BMS poll\n' \
  "$STARTUP_CPU" "$(echo "($SIM1_CPU - $STARTUP_CPU) * 1000 / $REALTIME_S" | bc -l)" \
  "$(echo "($SIM1FAST_CPU - $STARTUP_CPU) * 1000 / $REALTIME_S" | bc -l)" \
  "$(echo "($SIM1_CPU - $STARTUP_CPU) / ($SIM1FAST_CPU - $STARTUP_CPU + 0.000001)" | bc -l)"
if [[ $UP_RSS != 0 ]]; then
  printf 'Steady state, sim at speed 1 + TLS uplink, %s s: %.3f %% of one core (target <= 0.25 %%), VmRSS %.1f MB near the end, peak RSS %.1f MB (target <= 10 MB)\n' \
    "$REALTIME_S" "$(echo "$UP_CPU / $UP_WALL * 100" | bc -l)" "$(echo "$UP_VMRSS / 1024" | bc -l)" \
    "$(echo "$UP_RSS / 1024" | bc -l)"
  echo "  wake-ups (voluntary context switches) by thread, $((REALTIME_S - 5)) s into the run:"
  sed 's/^/    /' "$WORK/uplink.threads"
  echo "  resident by mapping near the end:"
  sed 's/^/    /' "$WORK/uplink.maps"
fi
