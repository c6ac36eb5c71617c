#!/usr/bin/env python3
"""The broker's CPU while an ingest worker runs, beside bench/ingest-drain.sh (issue 25).

Runs the command given (e.g. bench/ingest-drain.sh with its environment), passes its output
through, and samples every 50 ms the benchmark's mosquitto (its child) and its `fleetgw-ingest` workers (client id
bench-worker-N). For each lifetime of the worker processes it prints the broker's CPU seconds
(user + system) over it: in ingest-drain.sh the first lifetime only subscribes, the second is the
drain (start-up and shutdown included). Why a separate script: ingest-drain.sh reports the
worker's and PostgreSQL's CPU, not the broker's, and fewer TCP segments from the worker should
cost the broker less too.
Usage: sudo FLEETGW=<dir>/fleetgw BUILD=0 WORKERS=1 ... bench/drain-broker-cpu.py bench/ingest-drain.sh
"""
import os
import subprocess
import sys
import threading
import time

HZ = os.sysconf("SC_CLK_TCK")


def cmdline(pid):
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


def cpu_us(pid):
    """(user, system) seconds of a process (fields 14, 15 of /proc/PID/stat), or None."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return int(fields[11]) / HZ, int(fields[12]) / HZ
    except (OSError, IndexError, ValueError):
        return None


def cpu_s(pid):
    us = cpu_us(pid)
    return None if us is None else us[0] + us[1]


def tcp_out_segs():
    """The host's TCP segments sent (loopback included): /proc/net/snmp Tcp OutSegs."""
    with open("/proc/net/snmp") as f:
        rows = [line.split() for line in f if line.startswith("Tcp:")]
    return int(rows[1][rows[0].index("OutSegs")])


def ppid(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[1]
    except (OSError, IndexError):
        return None


def find(root):
    """The broker and the workers among the descendants of `root` (the benchmark): other
    benchmarks may run on the machine at the same time, with brokers and workers of the same
    names."""
    parent = {d: ppid(d) for d in os.listdir("/proc") if d.isdigit()}

    def mine(pid):
        for _ in range(64):
            if pid is None:
                return False
            if pid == root:
                return True
            pid = parent.get(pid)
        return False

    broker, workers = None, []
    for d in parent:
        if not mine(d):
            continue
        c = cmdline(d)
        if c.startswith("mosquitto "):
            broker = d
        elif "fleetgw-ingest" in c and "bench-worker-" in c and "strace" not in c.split()[0]:
            workers.append(d)
    return broker, workers


def watch(stop, out, root):
    life = None  # the current lifetime: broker CPU and segments at its start, last samples
    broker = None
    absent = 0  # samples without a worker: a lifetime ends after a second of them
    while not stop.is_set():
        b, workers = find(root)
        broker = b or broker
        bc = cpu_s(broker) if broker else None
        if workers and bc is not None:
            if life is None:
                life = {"b0": bc, "s0": tcp_out_segs(), "w": {}}
            life["b1"] = bc
            life["s1"] = tcp_out_segs()
            for w in workers:  # the worker's own last reading (user, system)
                us = cpu_us(w)
                if us is not None:
                    life["w"][w] = us
            absent = 0
        elif life is not None and not workers:
            absent += 1
            if absent >= 20:
                out.append(life)
                life = None
        time.sleep(0.05)
    if life is not None:
        out.append(life)


def main():
    stop = threading.Event()
    lifetimes = []
    bench = subprocess.Popen(sys.argv[1:])
    t = threading.Thread(target=watch, args=(stop, lifetimes, str(bench.pid)))
    t.start()
    rc = bench.wait()
    stop.set()
    t.join()
    for i, life in enumerate(lifetimes, 1):
        user = sum(u for u, _ in life["w"].values())
        system = sum(s for _, s in life["w"].values())
        print(f"while the workers ran ({i}): broker CPU {life['b1'] - life['b0']:.2f} s, "
              f"TCP segments sent {life['s1'] - life['s0']}, workers user/system "
              f"{user:.2f} / {system:.2f} s (last seen)")
    return rc


if __name__ == "__main__":
    sys.exit(main())
