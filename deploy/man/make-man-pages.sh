#!/usr/bin/env bash
# Writes the manual pages of fleetgw from its own --help (help2man): fleetgw(1), one
# fleetgw-<subcommand>(1) per subcommand and fleetgw-watch(1), gzip -9n (reproducible), into
# OUT_DIR. The pages are generated from the CLI definitions, so they cannot drift from them.
#
# Usage: make-man-pages.sh FLEETGW FLEETGW_WATCH VERSION OUT_DIR
set -euo pipefail
fleetgw=$1 watch=$2 version=$3 out=$4
mkdir -p "$out"
# Run the programs by name, so the usage lines say "fleetgw", not the build path.
PATH="$(cd "$(dirname "$fleetgw")" && pwd):$(cd "$(dirname "$watch")" && pwd):$PATH"
fleetgw=$(basename "$fleetgw") watch=$(basename "$watch")
# `fleetgw watch` runs fleetgw-watch with the same options: its page is fleetgw-watch(1).
subcommands=(run decode check-config status command keygen db ride sim)
see_also=$(printf 'fleetgw-%s(1), ' "${subcommands[@]}" watch)
include=$(mktemp)
trap 'rm -f "$include"' EXIT
printf '[SEE ALSO]\n%s\n.PP\n/usr/share/doc/fleetgw/deployment.md\n' "${see_also%, }" >"$include"

page() {  # NAME DESCRIPTION COMMAND...
  local name=$1 description=$2
  shift 2
  help2man --no-info --no-discard-stderr --version-string="fleetgw $version" \
    --name="$description" --include="$include" --output="$out/$name.1" "$*"
  # help2man names the page after the program it ran; the subcommand pages say what they are.
  sed -i "0,/^\.TH /s/^\.TH [^ ]* /.TH ${name^^} /" "$out/$name.1"
  gzip -9nf "$out/$name.1"
}

page fleetgw "MOTINOVA e-bike fleet telemetry gateway" "$fleetgw"
for sub in "${subcommands[@]}"; do
  # Each subcommand's first help line is its one-line description.
  description=$("$fleetgw" "$sub" --help 2>&1 | head -1)
  page "fleetgw-$sub" "${description:-fleetgw $sub}" "$fleetgw $sub"
done
page fleetgw-watch "print the Envelopes a broker receives, as JSON lines" "$watch"
