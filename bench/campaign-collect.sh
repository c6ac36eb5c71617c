#!/usr/bin/env bash
# Issue 29's figures, through the shipped binary (`fleetgw sim` records the worst-case log,
# `fleetgw run --replay` runs the campaigns on it, MQTT off, `fleetgw campaign sign` signs them):
#
#  1. Trigger-to-first-sample latency on the bus timeline: window campaigns (0 ms before, 2 s
#     after, every 10 ms) on a fault becoming active and on a level condition, each with the
#     tripping signal and signals of other messages. Per signal, over every window of the log:
#     the first sample at or after its (last) event minus that event (both bus times, from the
#     records' trigger_at_us and sample times).
#  2. Signals per second one gateway can collect against what a 250 kbit/s bus can carry:
#     every numeric signal of every message the log carries, sampled at each of its values
#     (period 200 ms, the log's fastest message being 5 Hz), in campaigns under the acceptance
#     bounds. The gateway's figure is samples kept / the CPU the campaigns add (best of RUNS,
#     user + sys of the whole process: bench/cputime.py, side by side with no campaign). The
#     bus's is the log's numeric values per CAN frame times the frames a saturated bus carries
#     (8-byte standard frames: 111 bits without stuffing, 135 with the worst stuffing).
#
# Environment: FLEETGW (binary, default build/bin/fleetgw), RUNS (2), DURATION (bus
#   seconds of the log, 1200), KEEP=1 keeps the work directory. Needs sqlite3, protoc, python3.
set -euo pipefail
cd "$(dirname "$0")/.."
FLEETGW=$(realpath "${FLEETGW:-build/bin/fleetgw}")
RUNS=${RUNS:-2}
DURATION=${DURATION:-1200}
[[ -x $FLEETGW ]] || { echo "campaign-collect: no binary $FLEETGW" >&2; exit 1; }
WORK=$(mktemp -d /tmp/fleetgw-collect-XXXXXX)
if [[ -z ${KEEP:-} ]]; then trap 'rm -rf "$WORK"' EXIT; fi

"$FLEETGW" keygen "$WORK/eng" >"$WORK/keygen.out"
KEY_LINE=$(grep -o 'eng = "[^"]*"' "$WORK/keygen.out")
"$FLEETGW" sim --scenario config/scenarios/worst-case.toml --duration "$DURATION" \
  --record "$WORK/worst.log" >/dev/null 2>&1
FRAMES=$(wc -l <"$WORK/worst.log")
"$FLEETGW" decode "$WORK/worst.log" >"$WORK/decoded.jsonl" 2>/dev/null
"$FLEETGW" signals --json >"$WORK/signals.json"
now_us=$(head -1 "$WORK/worst.log" | sed 's/^(\([0-9]*\)\..*/\1/')000000

config() {  # name
  printf '[log]\nlevel = "warn"\n[can]\ntransport = "replay"\n[storage]\npath = "%s/db-%s/fleetgw.db"\nmax_mb = 256\n[mqtt]\nenabled = false\n[command.trusted_keys]\n%s\n' \
    "$WORK" "$1" "$KEY_LINE" >"$WORK/$1.toml"
}

campaign() {  # file id signals(TOML list) trigger sampling budget
  cat >"$WORK/$1.toml" <<EOF
id = "$2"
version = 1
signals = [$3]
disk_budget_bytes = $6
start_us = $((now_us - 86400000000))
end_us = $((now_us + 30 * 86400000000))
[trigger]
$4
[sampling]
$5
[target]
all_vehicles = true
EOF
  "$FLEETGW" campaign sign "$WORK/$1.toml" --key "$WORK/eng.pem" --out "$WORK/$1.signed" \
    >>"$WORK/sign.out"
}

# Stores the named signed campaigns in a fresh store's meta table, as the gateway keeps them.
prepare() {  # config-name campaign-files...
  local name=$1
  shift
  rm -rf "$WORK/db-$name" && mkdir -p "$WORK/db-$name"
  head -1 "$WORK/worst.log" >"$WORK/one.log"
  "$FLEETGW" run --config "$WORK/$name.toml" --replay "$WORK/one.log" >/dev/null 2>&1
  local index=""
  for f in "$@"; do
    local id
    id=$(sed -n 's/^id = "\(.*\)"/\1/p' "$WORK/$f.toml")
    sqlite3 "$WORK/db-$name/fleetgw.db" \
      "INSERT OR REPLACE INTO meta VALUES ('campaign.$id', '$(base64 -w0 "$WORK/$f.signed")')"
    index="$index $id"
  done
  [[ -n $index ]] && sqlite3 "$WORK/db-$name/fleetgw.db" \
    "INSERT OR REPLACE INTO meta VALUES ('campaign.index', '${index# }')"
  return 0
}

replay() {  # config-name campaign-files... ; sets CPU (best of RUNS)
  local name=$1
  shift
  CPU=""
  for ((r = 0; r < RUNS; r++)); do
    prepare "$name" "$@"
    python3 bench/cputime.py "$WORK/$name.time" "$FLEETGW" run --config "$WORK/$name.toml" \
      --replay "$WORK/worst.log" >/dev/null 2>"$WORK/$name.err" || {
      echo "campaign-collect: $name failed" >&2
      tail -20 "$WORK/$name.err" >&2
      exit 1
    }
    local c
    c=$(awk '{ print $1 + $2 }' "$WORK/$name.time")
    if [[ -z $CPU ]] || awk -v a="$c" -v b="$CPU" 'BEGIN { exit !(a < b) }'; then CPU=$c; fi
  done
}

# Every campaign record of a store as one JSON line {trigger_at_us, samples: [[signal, t_us]]}.
records() {  # db
  sqlite3 "$1" "SELECT hex(payload) FROM outbox WHERE kind = 'campaign' ORDER BY seq" |
    python3 -c '
import json, subprocess, sys
for line in sys.stdin:
    text = subprocess.run(
        ["protoc", "--decode=fleetgw.v1.CampaignSamples", "-Iproto", "proto/fleetgw/v1/campaign.proto"],
        input=bytes.fromhex(line.strip()), capture_output=True, check=True).stdout.decode()
    names, base, trigger, samples, cur, cid = [], 0, None, [], {}, ""
    for raw in text.splitlines():
        l = raw.strip()
        if l.startswith("campaign_id:"): cid = json.loads(l.split(":", 1)[1])
        elif l.startswith("signals:"): names.append(json.loads(l.split(":", 1)[1]))
        elif l.startswith("base_us:"): base = int(l.split(":")[1])
        elif l.startswith("trigger_at_us:"): trigger = int(l.split(":")[1])
        elif l == "samples {": cur = {"signal": 0, "offset_us": 0}
        elif l.startswith("signal:"): cur["signal"] = int(l.split(":")[1])
        elif l.startswith("offset_us:"): cur["offset_us"] = int(l.split(":")[1])
        elif l == "}": samples.append([names[cur["signal"]], base + cur["offset_us"]])
    print(json.dumps({"campaign": cid, "trigger_at_us": trigger, "samples": samples}))
'
}

# --- 1. trigger-to-first-sample latency -------------------------------------------------------
# Two window campaigns (0 ms before, 2 s after, every 10 ms) on what this log makes happen: the
# MC's over-heat protection becoming active (an event) and its power rising over 100 W (a level
# condition's start). Each collects the tripping signal and signals of other messages.
config latency
others='"mc.status.motor_temp_c", "bms.status.temp_c", "bms.cells.cells_mv[0]", "mc.odometer.odo_km"'
window='kind = "window"
period_ms = 10
before_ms = 0
after_ms = 2000'
campaign lat1 fault-latency "\"mc.faults.over_heat_protect\", $others" \
  'kind = "condition"
condition = { kind = "fault_active", signal = "mc.faults.over_heat_protect" }' "$window" 8388608
campaign lat2 power-latency "\"mc.status.power_w\", \"mc.status.speed_kmh\", $others" \
  'kind = "condition"
condition = { kind = "above", signal = "mc.status.power_w", threshold = 100, hysteresis = 20 }' \
  "$window" 8388608
RUNS_SAVED=$RUNS
RUNS=1
replay latency lat1 lat2
RUNS=$RUNS_SAVED
records "$WORK/db-latency/fleetgw.db" >"$WORK/latency.jsonl"

# --- 2. signals per second --------------------------------------------------------------------
# Every numeric signal of the messages the log carries, at most 64 per campaign.
python3 - "$WORK" >"$WORK/collect.lists" <<'EOF'
import json, sys
work = sys.argv[1]
seen = set()
for line in open(f"{work}/decoded.jsonl"):
    d = json.loads(line)
    seen.add((d["can_id"].upper().replace("0X", "0x"), d["message"]))
names = [s["name"] for s in json.load(open(f"{work}/signals.json"))
         if (s["can_id"].upper().replace("0X", "0x"), s["message"]) in seen
         and s["type"] in ("number", "bool", "enum", "flags")]
for i in range(0, len(names), 64):
    print(", ".join(f'"{n}"' for n in names[i:i + 64]))
EOF
config none
config all
ALL=()
i=0
while IFS= read -r list; do
  i=$((i + 1))
  campaign "all$i" "all-$i" "$list" 'kind = "always"' 'kind = "every"
period_ms = 200' 12582912
  ALL+=("all$i")
done <"$WORK/collect.lists"
SIGNALS=$(tr ',' '\n' <"$WORK/collect.lists" | grep -c '"')
replay none
NONE_CPU=$CPU
replay all "${ALL[@]}"
ALL_CPU=$CPU
KEPT=$(records "$WORK/db-all/fleetgw.db" | python3 -c 'import json, sys; print(sum(len(json.loads(l)["samples"]) for l in sys.stdin))')

python3 - "$WORK" "$FRAMES" "$DURATION" "$NONE_CPU" "$ALL_CPU" "$KEPT" "$SIGNALS" "$FLEETGW" <<'EOF'
import collections, json, statistics, sys
work, frames, duration, none_cpu, all_cpu, kept, signals, binary = sys.argv[1:]
frames, duration, kept, signals = int(frames), int(duration), int(kept), int(signals)
none_cpu, all_cpu = float(none_cpu), float(all_cpu)
lat = collections.defaultdict(list)
events = 0
for line in open(f"{work}/latency.jsonl"):
    r = json.loads(line)
    t = r["trigger_at_us"]
    if t is None: continue
    events += 1
    first = {}
    for name, at in r["samples"]:
        if at >= t and name not in first: first[name] = at - t
    for name, d in first.items(): lat[(r["campaign"], name)].append(d / 1000)
print(f"fleetgw: {binary}; worst-case log: {frames} CAN frames in {duration} bus-seconds")
print(f"1. trigger-to-first-sample latency (bus timeline), {events} windows:")
for (cid, name), v in sorted(lat.items()):
    print(f"   {cid:14s} {name:28s} median {statistics.median(v):6.1f} ms  max {max(v):6.1f} ms  ({len(v)} windows)")
values = 0
per = collections.defaultdict(int)
for s in json.load(open(f"{work}/signals.json")):
    if s["type"] in ("number", "bool", "enum", "flags"):
        per[(s["can_id"].lower(), s["message"])] += 1
for line in open(f"{work}/decoded.jsonl"):
    d = json.loads(line)
    values += per[(d["can_id"].lower(), d["message"])]
per_frame = values / frames
bus_lo, bus_hi = 250000 / 135 * per_frame, 250000 / 111 * per_frame
added = all_cpu - none_cpu
print(f"2. signals per second: {signals} numeric signals of the log's messages, {values / duration:.0f} values/s on this bus ({per_frame:.2f} per frame)")
print(f"   no campaign: {none_cpu:.2f} s CPU; all signals collected: {all_cpu:.2f} s CPU; {kept} samples kept ({kept / duration:.0f}/s of bus time)")
print(f"   gateway: {added / kept * 1e6:.2f} us CPU per sample kept -> {kept / added:,.0f} samples per CPU-second")
print(f"   a saturated 250 kbit/s bus with this frame mix: {bus_lo:,.0f} .. {bus_hi:,.0f} values/s")
print(f"   acceptance bound (256 MiB/h of 27-byte samples, all campaigns): {256 * 2**20 / 27 / 3600:,.0f} samples/s")
EOF
