# Sourced by the bench scripts that run shipped `fleetgw run` processes side by side, each to a
# private mosquitto of its own (bench/parked-vs-riding.sh, bench/mqtt5-overhead.sh).
#   bench_workdir PREFIX   creates WORK=/tmp/PREFIX-XXXXXX; on exit every process in PIDS is
#                          killed and WORK removed (kept, and named, when KEEP=1)
#   start_broker NAME      a mosquitto on a free loopback port ($SYS every second, TCP_NODELAY),
#                          waited for until it accepts a connection; its port in PORT[NAME]
#   broker_stat NAME STAT  one $SYS/broker/STAT counter of that broker (e.g. bytes/received)
#   start_services MINUTES NAME...  `$FLEETGW run --config $WORK/NAME.toml` for MINUTES each,
#                          side by side, CPU (user sys) into $WORK/NAME.time, log $WORK/NAME.log
#   wait_services LABEL    waits for them (a failed one: its log's tail, exit 1), then for the
#                          brokers' next $SYS publication
PIDS=()
declare -A PORT
bench_cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
  [[ ${KEEP:-0} == 1 ]] && echo "work directory: $WORK" || rm -rf "$WORK"
}
bench_workdir() {
  WORK=$(mktemp -d "/tmp/$1-XXXXXX")
  trap bench_cleanup EXIT
}

free_port() {
  /usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

start_broker() {  # name
  local port
  port=$(free_port)
  printf 'listener %s 127.0.0.1\nallow_anonymous true\nsys_interval 1\nset_tcp_nodelay true\n' \
    "$port" >"$WORK/$1-mosquitto.conf"
  mosquitto -c "$WORK/$1-mosquitto.conf" 2>"$WORK/$1-mosquitto.log" &
  PIDS+=($!)
  for _ in $(seq 100); do  # until the broker accepts a connection
    mosquitto_sub -h 127.0.0.1 -p "$port" -t '$SYS/broker/version' -C 1 -W 1 >/dev/null 2>&1 && break
    sleep 0.05
  done
  PORT[$1]=$port
}

broker_stat() {  # name stat
  mosquitto_sub -h 127.0.0.1 -p "${PORT[$1]}" -t "\$SYS/broker/$2" -C 1 -W 5
}

SERVICE_PIDS=()
SERVICE_NAMES=()
start_services() {  # minutes name...
  local minutes=$1 n
  shift
  for n in "$@"; do
    /usr/bin/time -f '%U %S' -o "$WORK/$n.time" \
      "$FLEETGW" run --config "$WORK/$n.toml" --duration $((minutes * 60)) >"$WORK/$n.log" 2>&1 &
    SERVICE_PIDS+=($!)
    SERVICE_NAMES+=("$n")
  done
}

wait_services() {  # label
  local i
  for i in "${!SERVICE_PIDS[@]}"; do
    wait "${SERVICE_PIDS[$i]}" || {
      echo "$1: ${SERVICE_NAMES[$i]} failed" >&2
      tail -20 "$WORK/${SERVICE_NAMES[$i]}.log" >&2
      exit 1
    }
  done
  sleep 2  # $SYS counters are published every second (sys_interval 1)
}
