#!/usr/bin/env bash
# Disk-full soak (issue 11, figures): the shipped `fleetgw run` for DURATION seconds at sim speed
# SPEED with the store on a small tmpfs, the uplink on to a local mosquitto, the file system kept
# full by a filler from FILL_AFTER seconds on, a signed command sent every CMD_EVERY seconds with
# the real `fleetgw command`, and the space freed FREE_BEFORE_END seconds before the end.
# A benchmark, not a test. It prints:
#   exit status of the service (must be 0), commands sent / answered with a definite result
#   (must be 100 %), seconds from the first storage failure (status storage.failing_since_us) to
#   the status showing storage.failing, seconds from freeing the space to status OK, and the
#   service's CPU time (user + sys).
# Needs root (mount -t tmpfs); prints "SKIPPED" and exits 0 otherwise.
# Environment: FLEETGW (binary, default build/bin/fleetgw), DURATION (600), SPEED (100),
#   CMD_EVERY (5), FILL_AFTER (10), FREE_BEFORE_END (60), KEEP=1 keeps the work directory.
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=$(realpath "${FLEETGW:-build/bin/fleetgw}")
DURATION=${DURATION:-600}
SPEED=${SPEED:-100}
CMD_EVERY=${CMD_EVERY:-5}
FILL_AFTER=${FILL_AFTER:-10}
FREE_BEFORE_END=${FREE_BEFORE_END:-60}
VEHICLE=soak-bike
[[ -x $FLEETGW ]] || { echo "disk-full-soak: no binary $FLEETGW" >&2; exit 1; }
if [[ $(id -u) -ne 0 ]]; then
  echo "disk-full-soak: SKIPPED: needs root to mount a tmpfs"
  exit 0
fi
if ((DURATION < FILL_AFTER + FREE_BEFORE_END + 30)); then
  echo "disk-full-soak: DURATION must leave >= 30 s of full disk" >&2
  exit 2
fi

WORK=$(mktemp -d /tmp/fleetgw-soak-XXXXXX)
DISK=$WORK/disk
mkdir -p "$DISK"
BROKER_PID="" FILL_PID="" SERVICE_PID=""
cleanup() {
  touch "$WORK/stop-fill"
  # Only the processes this script started, by their id.
  for p in $FILL_PID $SERVICE_PID $BROKER_PID; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  umount "$DISK" 2>/dev/null || true
  if [[ -z ${KEEP:-} ]]; then rm -rf "$WORK"; else echo "disk-full-soak: kept $WORK"; fi
}
trap cleanup EXIT
if ! mount -t tmpfs -o size=8m tmpfs "$DISK"; then
  echo "disk-full-soak: SKIPPED: cannot mount a tmpfs here"
  exit 0
fi

now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", b - a }'; }

# --- broker -------------------------------------------------------------------------------------
PORT=$(/usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
# Logs to stderr: as root, mosquitto drops to its own user, which cannot write into $WORK.
printf 'listener %s 127.0.0.1\nallow_anonymous true\npersistence false\nlog_dest stderr\n' \
  "$PORT" >"$WORK/mosquitto.conf"
mosquitto -c "$WORK/mosquitto.conf" 2>"$WORK/mosquitto.log" &
BROKER_PID=$!
BROKER=tcp://127.0.0.1:$PORT

# --- operator key, scenario, config ------------------------------------------------------------
"$FLEETGW" keygen "$WORK/operator" >"$WORK/keygen.out" 2>"$WORK/keygen.err"
TRUSTED=$(grep '^operator = ' "$WORK/keygen.out")
BUS_S=$(awk -v d="$DURATION" -v s="$SPEED" 'BEGIN { printf "%d", d * s + 600 }')
{
  printf '[scenario]\nname = "disk-full-soak"\nduration_s = %s\nstart_utc = 2024-07-01T08:00:00Z\n' "$BUS_S"
  printf '[bike]\nseed = 77\nsoc_pct = 90\n[[ride]]\nduration_s = %s\nspeed_kmh = 21\n' "$BUS_S"
  # An MC over-heat raised and cleared every 10 minutes of bus time (fault records).
  for ((t = 60; t < BUS_S; t += 600)); do
    printf '[[event]]\nat_s = %d\naction = "fault"\nnode = "mc"\nfault = "over_heat_protect"\n' "$t"
    printf '[[event]]\nat_s = %d\naction = "clear"\nnode = "mc"\nfault = "over_heat_protect"\n' $((t + 300))
  done
} >"$WORK/soak.toml"
cat >"$WORK/fleetgw.toml" <<EOF
[vehicle]
id = "$VEHICLE"
[log]
level = "info"
[can]
transport = "sim"
[sim]
scenario = "$WORK/soak.toml"
speed = $SPEED
[storage]
path = "$DISK/fleetgw.db"
max_mb = 4
[status]
socket = "$WORK/status.sock"
[mqtt]
enabled = true
uri = "$BROKER"
telemetry_qos = 1
reconnect_min_ms = 100
reconnect_max_ms = 500
[command.trusted_keys]
$TRUSTED
EOF

# --- the service -------------------------------------------------------------------------------
/usr/bin/time -f '%U %S %e' -o "$WORK/run.time" \
  "$FLEETGW" run --config "$WORK/fleetgw.toml" --duration "$DURATION" >"$WORK/run.log" 2>&1 &
SERVICE_PID=$!
START=$(now)
for _ in $(seq 100); do [[ -S $WORK/status.sock ]] && break; sleep 0.1; done
[[ -S $WORK/status.sock ]] || { echo "disk-full-soak: the service did not start" >&2; cat "$WORK/run.log" >&2; exit 1; }

status_json() { "$FLEETGW" status --json --socket "$WORK/status.sock" 2>/dev/null || true; }
failing() { status_json | jq -r '.storage.failing' 2>/dev/null || echo unknown; }

fill() {  # keeps the tmpfs full: takes every byte that is freed, until told to stop
  while [[ ! -e $WORK/stop-fill ]]; do
    cat /dev/zero >>"$DISK/filler" 2>/dev/null || true
    sleep 0.05
  done
}

CMD_PIDS=()
SENT=0 NEXT_CMD=$(awk -v s="$START" 'BEGIN { printf "%.2f", s + 5 }')
FILLED_AT="" ATTENTION_AT="" FIRST_FAILURE_US="" FREED_AT="" OK_AT=""
END_FILL=$(awk -v s="$START" -v d="$DURATION" -v f="$FREE_BEFORE_END" 'BEGIN { printf "%.2f", s + d - f }')
LAST_CMD=$(awk -v s="$START" -v d="$DURATION" 'BEGIN { printf "%.2f", s + d - 25 }')
while kill -0 "$SERVICE_PID" 2>/dev/null; do
  T=$(now)
  since=$(elapsed "$START" "$T")
  if [[ -z $FILLED_AT ]] && awk -v a="$since" -v b="$FILL_AFTER" 'BEGIN { exit !(a >= b) }'; then
    fill &
    FILL_PID=$!
    FILLED_AT=$T
  fi
  if [[ -n $FILLED_AT && -z $ATTENTION_AT ]]; then
    doc=$(status_json)
    if [[ $(jq -r '.storage.failing' <<<"$doc" 2>/dev/null) == true ]]; then
      ATTENTION_AT=$(now)
      FIRST_FAILURE_US=$(jq -r '.storage.failing_since_us' <<<"$doc")
    fi
  fi
  if [[ -n $FILLED_AT && -z $FREED_AT ]] && awk -v a="$T" -v b="$END_FILL" 'BEGIN { exit !(a >= b) }'; then
    touch "$WORK/stop-fill"
    wait "$FILL_PID" || true
    FILL_PID=""
    rm -f "$DISK/filler"
    FREED_AT=$(now)
  fi
  if [[ -n $FREED_AT && -z $OK_AT && $(failing) == false ]]; then OK_AT=$(now); fi
  if awk -v a="$T" -v b="$NEXT_CMD" -v l="$LAST_CMD" 'BEGIN { exit !(a >= b && a < l) }'; then
    SENT=$((SENT + 1))
    action=$([[ $((SENT % 2)) -eq 1 ]] && echo unlock || echo lock)
    (
      rc=0
      "$FLEETGW" command --vehicle "$VEHICLE" --lock seat --action "$action" \
        --key "$WORK/operator.pem" --key-id operator --broker "$BROKER" --timeout-s 20 \
        >"$WORK/cmd-$SENT.out" 2>"$WORK/cmd-$SENT.err" || rc=$?
      echo "$rc" >"$WORK/cmd-$SENT.rc"
    ) &
    CMD_PIDS+=($!)
    NEXT_CMD=$(awk -v n="$NEXT_CMD" -v e="$CMD_EVERY" 'BEGIN { printf "%.2f", n + e }')
  fi
  sleep 0.2
done
RC=0
wait "$SERVICE_PID" || RC=$?
SERVICE_PID=""
for p in "${CMD_PIDS[@]}"; do wait "$p" || true; done  # tools still waiting for an answer

ANSWERED=0 UNSTORED=0 STORED=0 NO_ANSWER=0
for ((i = 1; i <= SENT; i++)); do
  rc=$(cat "$WORK/cmd-$i.rc" 2>/dev/null || echo 3)
  if [[ $rc == 0 || $rc == 1 ]]; then
    ANSWERED=$((ANSWERED + 1))
    if [[ $(head -1 "$WORK/cmd-$i.out" | jq -r '.stored') == false ]]; then
      UNSTORED=$((UNSTORED + 1))
    else
      STORED=$((STORED + 1))
    fi
  else
    NO_ANSWER=$((NO_ANSWER + 1))
  fi
done
RESULTS=$(cat "$WORK"/cmd-*.out 2>/dev/null | jq -r '"\(.result) \(.reason | split(":")[0] // "")"' 2>/dev/null | sort | uniq -c | sed 's/^ */    /')

echo "disk-full soak: ${DURATION} s at sim speed ${SPEED}x, 8 MB tmpfs (budget 4 MB), uplink on (mosquitto)"
echo "  service exit status:          $RC"
echo "  commands sent / answered:     $SENT / $ANSWERED ($(awk -v a="$ANSWERED" -v s="$SENT" 'BEGIN { printf "%.1f", s ? 100 * a / s : 0 }') %); $UNSTORED answered unstored (disk full), $STORED stored, $NO_ANSWER without answer"
echo "  results:"
echo "$RESULTS"
if [[ -n $ATTENTION_AT && -n $FIRST_FAILURE_US && $FIRST_FAILURE_US != null ]]; then
  echo "  first failure -> status attention: $(awk -v a="$ATTENTION_AT" -v f="$FIRST_FAILURE_US" 'BEGIN { printf "%.2f", a - f / 1e6 }') s (disk filled at +$(elapsed "$START" "$FILLED_AT") s)"
else
  echo "  first failure -> status attention: never"
fi
if [[ -n $OK_AT ]]; then
  echo "  space freed -> status OK:     $(elapsed "$FREED_AT" "$OK_AT") s"
else
  echo "  space freed -> status OK:     never"
fi
echo "  full disk for:                $(elapsed "$FILLED_AT" "${FREED_AT:-$(now)}") s"
echo "  service CPU (user + sys):     $(awk '{ printf "%.1f s of %.0f s wall", $1 + $2, $3 }' "$WORK/run.time")"
echo "  'storage: write failed' lines: $(grep -c 'storage: write failed' "$WORK/run.log" || true) (error lines in all: $(grep -c ' error ' "$WORK/run.log" || true))"
[[ $RC -eq 0 && $ANSWERED -eq $SENT && -n $OK_AT ]]
