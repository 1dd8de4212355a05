"""Time a command and read its peak resident memory, from a small process.

    python benchmarks/measure_cmd.py REPEATS CMD [ARG ...]   -> JSON on stdout

Runs CMD once as a warm-up (when REPEATS > 1), then REPEATS times, and prints
the wall times [s] and peak RSS [MB] (the kernel's ru_maxrss of each run). It
exists because the peak RSS the kernel reports for a child includes the
memory of the process that forked it: measured from a large benchmark
process, a small command would look large.
"""

import json
import os
import subprocess
import sys
import time


def main():
    repeats = int(sys.argv[1])
    cmd = sys.argv[2:]
    walls, rss = [], []
    for i in range(repeats + 1):
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        err = proc.stderr.read().decode(errors="replace")
        proc.stderr.close()
        if os.waitstatus_to_exitcode(status) != 0:
            print(json.dumps({"error": f"{' '.join(cmd)} failed: {err}"}))
            return
        if i == 0 and repeats > 1:
            continue
        walls.append(wall)
        rss.append(usage.ru_maxrss / 1024.0)
    print(json.dumps({"walls": walls, "rss": rss}))


if __name__ == "__main__":
    main()
