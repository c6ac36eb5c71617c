#!/bin/bash
# The configuration snippets of the deployment docs pass `fleetgw check-config` (issue 24: the
# broker README showed `[uplink] broker_uri` and `vehicle_id`, which check-config rejects).
#
# Every TOML block between `<!-- check-config: begin -->` and `<!-- check-config: end -->` in the
# files below is checked as a configuration of its own. What only a deployed bike has is
# supplied, nothing else is changed: the paths below /etc/fleetgw/certs/ point at readable
# scratch files, and the database goes to a scratch directory unless the snippet names one.
# A file without a marked snippet fails the test (the markers must not silently disappear).
# Usage: doc-snippets-test.sh SOURCE_DIR FLEETGW_BINARY
set -euo pipefail
src=$1
fleetgw=$2
files=(deploy/mosquitto/README.md docs/deployment.md)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/certs" "$work/db"
for f in ca.pem bike-0042.pem bike-0042.crt bike-0042.key; do
  printf 'scratch\n' > "$work/certs/$f"
done

failed=0
for doc in "${files[@]}"; do
  n=0
  # Split the marked blocks into snippet-1.toml, snippet-2.toml... (without the ``` fences).
  rm -f "$work"/snippet-*.toml
  awk -v out="$work/snippet-" '
    /<!-- check-config: begin -->/ { inside = 1; n++; next }
    /<!-- check-config: end -->/ { inside = 0; next }
    inside && /^```/ { next }
    inside { print > (out n ".toml") }
  ' "$src/$doc"
  for snippet in "$work"/snippet-*.toml; do
    [ -e "$snippet" ] || continue
    n=$((n + 1))
    sed -i "s#/etc/fleetgw/certs/#$work/certs/#g" "$snippet"
    grep -q '^\[storage\]' "$snippet" || printf '\n[storage]\npath = "%s/db/fleetgw.db"\n' "$work" >> "$snippet"
    if out=$("$fleetgw" check-config "$snippet" 2>&1); then
      echo "ok: $doc snippet $n"
    else
      echo "FAIL: $doc snippet $n does not pass fleetgw check-config:"
      echo "$out" | sed 's/^/    /'
      failed=1
    fi
  done
  if [ "$n" -eq 0 ]; then
    echo "FAIL: $doc has no <!-- check-config: begin --> ... end --> snippet"
    failed=1
  fi
done
exit $failed
