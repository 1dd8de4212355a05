"""Time commands and read their peak resident memory, from a small process.

    python -m benchmarks.measure_cmd SPEC_JSON   -> JSON on stdout

SPEC_JSON is ``{"repeats": N, "warmup": true, "cmds": [[CMD, ARG, ...], ...],
"outputs": [PATH or null, ...]}``. The commands run in rotation (A B C A B C
...), ``repeats`` rounds, after one warm-up round when ``warmup`` is true, so
that the machine's drift during the measurement touches every command alike.
Before each run (not timed) the command's output file, if given, is deleted and
the file systems are synced, so that every run writes a new file and no run
pays for the disk write-back of the one before (a 10 h output is 720 MB).
Prints, for each command, the wall times [s], peak RSS [MB] (the kernel's
ru_maxrss of each run) and CPU times [s] (user + system of the process and the threads
it waited for: less moved by other jobs on a shared machine than the wall time).

It exists because the peak RSS the kernel reports for a child includes the
memory of the process that forked it: measured from a large benchmark process,
a small command would look large.
"""

import json
import os
import subprocess
import sys
import time


def run_once(cmd):
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    cpu = usage.ru_utime + usage.ru_stime
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {err}")
    return wall, usage.ru_maxrss / 1024.0, cpu


def main():
    spec = json.loads(sys.argv[1])
    cmds = spec["cmds"]
    outputs = spec.get("outputs") or [None] * len(cmds)
    out = [{"walls": [], "rss": [], "cpus": []} for _ in cmds]
    try:
        rounds = int(spec["repeats"]) + (1 if spec.get("warmup", True) else 0)
        for r in range(rounds):
            for cmd, output, res in zip(cmds, outputs, out):
                if output and os.path.exists(output):
                    os.remove(output)
                if hasattr(os, "sync"):
                    os.sync()
                wall, rss, cpu = run_once(cmd)
                if spec.get("warmup", True) and r == 0:
                    continue
                res["walls"].append(wall)
                res["rss"].append(rss)
                res["cpus"].append(cpu)
    except RuntimeError as exc:
        print(json.dumps({"error": str(exc)}))
        return
    print(json.dumps({"results": out}))


if __name__ == "__main__":
    main()
