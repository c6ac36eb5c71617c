#!/usr/bin/env bash
# Writes the manual pages of fleetgw from its own --help (help2man), gzip -9n (reproducible), into
# OUT_DIR: fleetgw(1), one fleetgw-<subcommand>(1) per subcommand that `fleetgw --help` lists,
# fleetgw-watch(1) and, when FLEETGW_INGEST is given, fleetgw-ingest(1). Both the pages and the
# list of subcommands come from the CLI definitions, so a new subcommand gets its page without
# an edit here.
#
# Usage: make-man-pages.sh FLEETGW FLEETGW_WATCH VERSION OUT_DIR [FLEETGW_INGEST]
set -euo pipefail
fleetgw=$1 watch=$2 version=$3 out=$4 ingest=${5:-}
mkdir -p "$out"
# The pages of subcommands that no longer exist must not be installed.
rm -f "$out"/*.1 "$out"/*.1.gz
# Run the programs by name, so the usage lines say "fleetgw", not the build path.
for program in "$fleetgw" "$watch" ${ingest:+"$ingest"}; do
  PATH="$(cd "$(dirname "$program")" && pwd):$PATH"
done
fleetgw=$(basename "$fleetgw") watch=$(basename "$watch") ingest=${ingest:+$(basename "$ingest")}

# The "Subcommands:" section of `fleetgw --help` (CLI11): "  name   description", or the name
# alone with the description on the next, further indented line when the name is long.
declare -A descriptions=()
subcommands=()
section=0 last=
while IFS= read -r line; do
  if [[ $line == Subcommands:* ]]; then
    section=1
  elif ((section)); then
    if [[ $line =~ ^\ \ ([a-z][a-z0-9-]*)(\ +(.*))?$ ]]; then
      last=${BASH_REMATCH[1]}
      subcommands+=("$last")
      descriptions[$last]=${BASH_REMATCH[3]}
    elif [[ -n $last && -z ${descriptions[$last]} && $line =~ ^\ +([^ ].*)$ ]]; then
      descriptions[$last]=${BASH_REMATCH[1]}
    elif [[ -z $line || $line != \ * ]]; then
      section=0
    fi
  fi
done < <("$fleetgw" --help)
if [ ${#subcommands[@]} -eq 0 ]; then
  echo "make-man-pages.sh: no \"Subcommands:\" in the output of $fleetgw --help" >&2
  exit 1
fi

see_also=$(printf 'fleetgw-%s(1), ' "${subcommands[@]}")
include=$(mktemp) include_ingest=$(mktemp)
trap 'rm -f "$include" "$include_ingest"' EXIT
printf '[SEE ALSO]\n%s\n.PP\n/usr/share/doc/fleetgw/deployment.md\n' "${see_also%, }" >"$include"
# fleetgw-ingest is installed on a backend host, from its own package.
printf '[FILES]\n%s\n.PP\n%s\n[SEE ALSO]\n%s\n.PP\n%s\n' \
  "/etc/fleetgw-ingest/ingest.env: the service's settings, FLEETGW_INGEST_<OPTION>=value" \
  /lib/systemd/system/fleetgw-ingest.service "fleetgw(1), fleetgw-fleet-sim(1)" \
  /usr/share/doc/fleetgw-ingest/backend.md >"$include_ingest"

page() {  # INCLUDE NAME DESCRIPTION COMMAND...
  local include=$1 name=$2 description=$3
  shift 3
  help2man --no-info --no-discard-stderr --version-string="fleetgw $version" \
    --name="$description" --include="$include" --output="$out/$name.1" "$*"
  # help2man names the page after the program it ran; the subcommand pages say what they are,
  # in the title and in NAME (what whatis and apropos index).
  sed -i -e "0,/^\.TH /s/^\.TH [^ ]* /.TH ${name^^} /" \
    -e "/^\.SH NAME/{n;s/^[^ ]* \\\\-/${name//-/\\\\-} \\\\-/}" "$out/$name.1"
  gzip -9nf "$out/$name.1"
}

page "$include" fleetgw "MOTINOVA e-bike fleet telemetry gateway" "$fleetgw"
for sub in "${subcommands[@]}"; do
  case $sub in
    # `fleetgw watch` and `fleetgw ingest` run the programs of the same name with the same
    # options: their pages are those programs'.
    watch) page "$include" fleetgw-watch "${descriptions[$sub]}" "$watch" ;;
    ingest)
      [ -z "$ingest" ] || page "$include_ingest" fleetgw-ingest "${descriptions[$sub]}" "$ingest"
      ;;
    *) page "$include" "fleetgw-$sub" "${descriptions[$sub]:-fleetgw $sub}" "$fleetgw $sub" ;;
  esac
done
