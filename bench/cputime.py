#!/usr/bin/env python3
"""cputime.py OUT COMMAND...: runs COMMAND and writes its CPU time to OUT as "USER SYS" seconds.

The bench scripts' figures are CPU time of short runs (0.01-0.5 s). /usr/bin/time prints it with
10 ms resolution; the kernel's rusage for a waited-for child (wait4, which counts the child and
everything it waited for) has microseconds. Standard input, output and error pass through, and
the exit status is the command's (128 + N when a signal N ended it)."""
import os
import sys

if len(sys.argv) < 3:
    sys.exit("usage: cputime.py OUT COMMAND [ARG...]")
out, command = sys.argv[1], sys.argv[2:]
try:
    pid = os.fork()
except OSError as e:
    sys.exit(f"cputime.py: cannot fork: {e}")
if pid == 0:
    try:
        os.execvp(command[0], command)
    except OSError as e:
        print(f"cputime.py: cannot run {command[0]}: {e}", file=sys.stderr)
        os._exit(127)
_, status, usage = os.wait4(pid, 0)
with open(out, "w", encoding="ascii") as f:
    f.write(f"{usage.ru_utime:.6f} {usage.ru_stime:.6f}\n")
sys.exit(os.waitstatus_to_exitcode(status) if os.WIFEXITED(status) else 128 + os.WTERMSIG(status))
