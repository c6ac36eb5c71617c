#!/usr/bin/env python3
# Issue 28's click-to-succeeded figure, split: reads the JSON line that
# browser/console_command_test.mjs prints (through web.WebBrowser.OperatorLocksARealBike...,
# FLEETGW_CONSOLE_CLICKS=N, FLEETGW_CONSOLE_LOCK_KIND=seat for one lock instead of the whole
# vehicle) and prints p50/p90/p99/max of each part:
#   click to "succeeded" on screen; click to the server's signing; signing to the result stored
#   (broker, the gateway, the simulated lock(s), broker); the bike's own receipt-to-result time;
#   stored to shown (live event, fetch, render).
# Usage: console_click_split.py LOG
import json, sys
line = json.loads(next(l for l in open(sys.argv[1]) if l.startswith('{"click_to_result_ms"')))
def pct(t, p):
    return t[min(len(t) - 1, max(0, int(round(p / 100 * len(t) + 0.5)) - 1))]
def show(name, values):
    t = sorted(values)
    print(f'{name}: p50 {pct(t, 50)} ms, p90 {pct(t, 90)} ms, p99 {pct(t, 99)} ms, max {t[-1]} ms')
print(f'{len(line["click_to_result_ms"])} clicks ({line.get("lock_kind", "whole vehicle")}, unlock/lock alternating)')
show('click to "succeeded" on screen', line['click_to_result_ms'])
show('  click to signed (browser, POST, server)', line['click_to_issued_ms'])
show('  signed to result stored (broker, gateway, lock, broker)', line['issued_to_stored_ms'])
show('    of which the bike (receipt to result)', line['bike_duration_ms'])
show('  stored to shown (live event, fetch, render)', line['stored_to_shown_ms'])
rest = [c - b for c, b in zip(line['click_to_result_ms'], line['bike_duration_ms'])]
show('click to shown minus the bike', rest)
