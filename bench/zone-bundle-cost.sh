#!/usr/bin/env bash
# zone-bundle-cost.sh [BUILD_DIR] [SIZES...]: what judging a zone bundle costs (issue 24), through
# the shipped `fleetgw zones check` -- the gateway's own ZoneAuthority::offer(): parse, Ed25519,
# validation, the band index of every zone.
#
# For each size (default 1000 10000 100000 vertices) it draws the worst shape for the index, one
# zone zig-zagging between two latitudes 3 km apart (every edge spans the zone's whole height),
# signs it with `fleetgw zones sign` and judges it with `fleetgw zones check`, five times, and
# prints the median CPU time (user + sys, wait4's rusage) and peak resident memory (ru_maxrss),
# each also over a 4-vertex bundle judged the same way (process start, configuration, libraries),
# and the peak RSS per vertex. The bound the figures are held to is zone_bundle.h's
# judging_bytes_bound() (docs/location.md "Bounded cost").
#
#   cmake -S . -B build-rel -G Ninja -DCMAKE_BUILD_TYPE=Release && cmake --build build-rel --target fleetgw
#   bench/zone-bundle-cost.sh build-rel
set -euo pipefail

build=${1:-build}
shift || true
sizes=("$@")
[[ ${#sizes[@]} -gt 0 ]] || sizes=(1000 10000 100000)
bin=$build/bin/fleetgw
[[ -x $bin ]] || bin=$(find "$build" -name fleetgw -type f -perm -u+x | head -1)
[[ -x $bin ]] || { echo "zone-bundle-cost.sh: no fleetgw binary under $build" >&2; exit 1; }

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$bin" keygen "$work/ops" >"$work/keygen.out" 2>&1
grep '^ops = ' "$work/keygen.out" | sed '1i [command.trusted_keys]' >"$work/fleetgw.toml"

# zigzag N FILE: one slow zone of N vertices as a GeoJSON FeatureCollection (N=4: a square).
zigzag() {
  python3 - "$1" "$2" <<'EOF'
import json, sys
n, out = int(sys.argv[1]), sys.argv[2]
lat0, lon0, dlat = 52.50, 13.30, 3000 / 111195.0
if n == 4:
    ring = [[lon0, lat0], [lon0 + 0.001, lat0], [lon0 + 0.001, lat0 + 0.001], [lon0, lat0 + 0.001]]
else:
    step = 0.5 / 67700.0  # 0.5 m of longitude at 52.5 N
    ring = [[lon0 + i * step, lat0 + (dlat if i % 2 else 0)] for i in range(n - 2)]
    ring += [[lon0 + (n - 3) * step, lat0 - 0.0001], [lon0, lat0 - 0.0001]]
ring = [[round(x, 7), round(y, 7)] for x, y in ring]
feature = {"type": "Feature", "properties": {"id": "zig-zag", "kind": "slow", "speed_limit_kmh": 12},
           "geometry": {"type": "Polygon", "coordinates": [ring]}}
json.dump({"type": "FeatureCollection", "features": [feature]}, open(out, "w"))
EOF
}

# measure OUT COMMAND...: runs COMMAND five times; writes "median_cpu_s median_peak_rss_kb" to OUT.
measure() {
  python3 - "$@" <<'EOF'
import os, statistics, sys
out, cmd = sys.argv[1], sys.argv[2:]
cpu, rss = [], []
for _ in range(5):
    pid = os.fork()
    if pid == 0:
        fd = os.open(os.devnull, os.O_WRONLY)
        os.dup2(fd, 1)
        os.execv(cmd[0], cmd)
    _, status, ru = os.wait4(pid, 0)
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit(f"{' '.join(cmd)} failed ({status})")
    cpu.append(ru.ru_utime + ru.ru_stime)
    rss.append(ru.ru_maxrss)
open(out, "w").write(f"{statistics.median(cpu):.4f} {int(statistics.median(rss))}\n")
EOF
}

echo "fleetgw: $bin ($(file -b "$bin" | cut -d, -f1-2))"
zigzag 4 "$work/z4.geojson"
"$bin" zones sign "$work/z4.geojson" --version 1 --key "$work/ops.pem" --out "$work/z4.pb" >/dev/null
measure "$work/m4" "$bin" zones check "$work/z4.pb" --config "$work/fleetgw.toml"
read -r base_cpu base_rss <"$work/m4"
printf '%-9s %9s %12s %12s %14s %12s\n' vertices bundle_B cpu_ms cpu_over_ms peak_rss_kB rss_over_B/v
printf '%-9s %9s %12.1f %12s %14s %12s\n' 4 "$(stat -c %s "$work/z4.pb")" \
  "$(echo "$base_cpu * 1000" | bc -l)" - "$base_rss" -
for n in "${sizes[@]}"; do
  zigzag "$n" "$work/z$n.geojson"
  "$bin" zones sign "$work/z$n.geojson" --version 1 --key "$work/ops.pem" \
    --out "$work/z$n.pb" >/dev/null
  measure "$work/m$n" "$bin" zones check "$work/z$n.pb" --config "$work/fleetgw.toml"
  read -r cpu rss <"$work/m$n"
  printf '%-9s %9s %12.1f %12.1f %14s %12.1f\n' "$n" "$(stat -c %s "$work/z$n.pb")" \
    "$(echo "$cpu * 1000" | bc -l)" "$(echo "($cpu - $base_cpu) * 1000" | bc -l)" "$rss" \
    "$(echo "($rss - $base_rss) * 1024 / $n" | bc -l)"
done
