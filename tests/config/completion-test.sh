#!/usr/bin/env bash
# `fleetgw completion bash`: the script the real binary prints is sourced in bash and its
# completion function called as bash calls it (COMP_WORDS, COMP_CWORD set; COMPREPLY read
# back), for subcommands, nested subcommands, options, enumerated option values (both
# `--opt VALUE` and `--opt=VALUE`) and file names. The expected words come from the CLI
# definitions in gateway/cli and gateway/decode; a completion that drifts from them fails here.
#
# Usage: completion-test.sh FLEETGW
# Exit: 0 pass, 1 fail.
set -uo pipefail
FLEETGW=$1
failures=0
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

script="$work/fleetgw.bash"
if ! "$FLEETGW" completion bash >"$script" 2>"$work/err"; then
  echo "FAIL: fleetgw completion bash exited non-zero: $(cat "$work/err")"
  exit 1
fi
bash -n "$script" || { echo "FAIL: the generated script is not valid bash"; exit 1; }
# shellcheck source=/dev/null
source "$script" || { echo "FAIL: sourcing the script failed"; exit 1; }
[ "$(complete -p fleetgw 2>/dev/null)" = "complete -F _fleetgw fleetgw" ] ||
  { echo "FAIL: fleetgw is not registered: $(complete -p fleetgw 2>&1)"; failures=$((failures + 1)); }

# expect "WORDS OFFERED" WORD... : completes the last WORD (the one under the cursor).
expect() {
  local want=$1
  shift
  COMP_WORDS=("$@")
  COMP_CWORD=$((${#COMP_WORDS[@]} - 1))
  COMPREPLY=()
  _fleetgw fleetgw "${COMP_WORDS[COMP_CWORD]}" "${COMP_WORDS[COMP_CWORD - 1]}"
  local got
  got=$(printf '%s\n' "${COMPREPLY[@]}" | sort | tr '\n' ' ')
  got=${got% }
  want=$(tr ' ' '\n' <<<"$want" | sort | tr '\n' ' ')
  want=${want% }
  if [ "$got" = "$want" ]; then
    echo "ok: [${COMP_WORDS[*]}] -> $got"
  else
    echo "FAIL: [${COMP_WORDS[*]}] -> \"$got\", expected \"$want\""
    failures=$((failures + 1))
  fi
}
# contains WORD WORD... : the completion of the last word offers WORD (among others).
contains() {
  local want=$1
  shift
  COMP_WORDS=("$@")
  COMP_CWORD=$((${#COMP_WORDS[@]} - 1))
  COMPREPLY=()
  _fleetgw fleetgw "${COMP_WORDS[COMP_CWORD]}" "${COMP_WORDS[COMP_CWORD - 1]}"
  if printf '%s\n' "${COMPREPLY[@]}" | grep -qx -- "$want"; then
    echo "ok: [${COMP_WORDS[*]}] offers $want"
  else
    echo "FAIL: [${COMP_WORDS[*]}] does not offer $want: ${COMPREPLY[*]}"
    failures=$((failures + 1))
  fi
}

expect "decode db" fleetgw d
expect "stats export summary rides faults commands alarms" fleetgw db ""
expect "jsonl csv geojson" fleetgw db export --format ""
expect "table json csv" fleetgw db summary --format ""
expect "be le auto" fleetgw decode --crc-order ""
expect "auto" fleetgw decode --crc-order a
expect "be le auto" fleetgw decode --crc-order = ""  # COMP_WORDBREAKS splits --crc-order=
expect "--crc-order=le" fleetgw decode --crc-order=l  # ... or does not
expect "table json csv" fleetgw decode --format ""
expect "table json csv" fleetgw db rides --format ""
expect "lock unlock" fleetgw command --action ""
expect "on off" fleetgw command --lights ""
expect "--crc-order" fleetgw decode --crc
expect "--since" fleetgw db faults --si
# After an option's value and a flag, still the decode options; the subcommand is still decode.
expect "--mc-current-signed --mc-fault-layout --mc-voltage-current --mc-answer-id" \
  fleetgw decode --crc-order le --errors --mc
contains "--help" fleetgw db export --
contains "--version" fleetgw --
# The hidden subcommand is not offered; the visible ones all are.
expect "campaign check-config command" fleetgw c
# Files where a file goes: the positional of decode, the value of --config.
touch "$work/ride.log"
expect "$work/ride.log" fleetgw decode "$work/ri"
expect "$work/ride.log" fleetgw decode --config "$work/r"

echo "== $failures failure(s)"
[ "$failures" -eq 0 ]
