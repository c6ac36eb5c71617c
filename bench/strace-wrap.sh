#!/usr/bin/env bash
# A worker under `strace -c -f` for the ingest benches' INGEST_WRAP (issue 25): the system calls
# of one worker, counted into $STRACE_DIR/strace-<time>.txt (default /tmp). strace itself does
# not pass the bench's SIGTERM on to the traced worker (it was SIGKILLed after 60 s, without a
# summary): this forwards it, so the worker stops as usual and strace writes its counts.
# Usage: sudo INGEST_WRAP=bench/strace-wrap.sh FLEETGW=... bench/ingest-drain.sh
strace -c -f -o "${STRACE_DIR:-/tmp}/strace-$(date +%s%N).txt" "$@" &
st=$!
# shellcheck disable=SC2046 # the traced worker: strace's child
trap 'kill -TERM $(pgrep -P "$st") 2>/dev/null' TERM
wait "$st"
wait "$st"
