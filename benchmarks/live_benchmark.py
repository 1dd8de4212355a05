"""``phri live`` round trip at 1 kHz: samples lost, latency, phri's CPU (benchmarks/LIVE.md).

    python -m benchmarks.live_benchmark --source lsl   --seconds 600   # the issue's 10 minutes
    python -m benchmarks.live_benchmark --source netft --seconds 600

``lsl``: a test outlet of six channels pushes the example log's wrenches at
1 kHz, each stamped with ``local_clock()`` at its push; ``phri live --source
lsl:... --lsl-out ...`` runs in its own process; a test inlet takes the
results. Latency = arrival at the test inlet - the input sample's stamp
(carried through by phri), one machine, one clock.

``netft``: the RDT emulator of ``tests/support/netft_emulator.py`` streams the same
wrenches at 1 kHz over loopback UDP; phri stamps each record with its
reception time, so the latency is reception by phri -> arrival at the test
inlet (the UDP hop on loopback, a few microseconds, is not in it).

CPU = phri's user + system time (``/proc/PID/stat``) over the streaming time,
in % of one core. Needs the live extra (pylsl). Prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import numpy as np

from benchmarks.common import ROOT as REPO


def _wrenches(n: int) -> np.ndarray:
    lines = [ln for ln in (REPO / "examples" / "wrench_log.csv").read_text().splitlines()
             if ln and not ln.startswith("#")][1:]
    w = np.array([[float(x) for x in ln.split(",")[1:]] for ln in lines])
    return w[np.arange(n) % len(w)]


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--source", choices=("lsl", "netft"), default="lsl")
    ap.add_argument("--seconds", type=float, default=600.0)
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--arm", default="compliant")
    args = ap.parse_args(argv)

    import pylsl

    pylsl.set_config_content("[log]\nlevel = -3\n")
    n = int(args.seconds * args.rate)
    w = _wrenches(n)
    tag = uuid.uuid4().hex[:8]
    config = REPO / "configs" / "harmony_upper_arm.yaml"
    cmd = [sys.executable, "-m", "phri_cli.main", "live", str(config), "--arm", args.arm,
           "--lsl-out", f"bench-out-{tag}", "--max-samples", str(n), "-q"]
    emu = outlet = None
    if args.source == "lsl":
        info = pylsl.StreamInfo(f"bench-in-{tag}", "Force", 6, args.rate, "double64", tag)
        outlet = pylsl.StreamOutlet(info)
        cmd += ["--source", f"lsl:bench-in-{tag}"]
    else:
        from tests.support.netft_emulator import NetFtEmulator

        emu = NetFtEmulator(np.round(w * 1e6).astype(np.int64), rate_hz=args.rate)
        cmd += ["--source", f"netft:127.0.0.1:{emu.port}"]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE)
    found = pylsl.resolve_byprop("name", f"bench-out-{tag}", timeout=60)
    if not found:
        proc.kill()
        raise SystemExit(f"phri live did not open its outlet: {proc.stderr.read().decode()}")
    inlet = pylsl.StreamInlet(found[0], max_buflen=360)
    inlet.open_stream(timeout=10)
    if outlet is not None:
        while not outlet.have_consumers():
            time.sleep(0.01)

    def push():
        t_next = time.perf_counter()
        period = 1.0 / args.rate
        for i in range(n):
            outlet.push_sample(w[i].tolist(), pylsl.local_clock())
            t_next += period
            delay = t_next - time.perf_counter()
            if delay > 0:
                time.sleep(delay)

    cpu0 = _cpu_seconds(proc.pid)
    wall0 = time.monotonic()
    if emu is not None:
        emu.__enter__()
        pusher = None
    else:
        pusher = threading.Thread(target=push, daemon=True)
        pusher.start()
    latency = np.empty(n)
    got = 0
    deadline = time.monotonic() + args.seconds * 1.5 + 30
    while got < n and time.monotonic() < deadline:
        sample, stamp = inlet.pull_sample(timeout=1.0)
        if sample is None:
            continue
        latency[got] = pylsl.local_clock() - stamp
        got += 1
    wall = time.monotonic() - wall0
    cpu = _cpu_seconds(proc.pid) - cpu0 if proc.poll() is None else float("nan")
    proc.wait(timeout=60)
    if emu is not None:
        emu.__exit__(None, None, None)
    lat = latency[:got] * 1e3
    out = {"source": args.source, "arm": args.arm, "rate_hz": args.rate, "samples_sent": n,
           "samples_received": got, "lost": n - got,
           "latency_ms": {q: round(float(np.percentile(lat, p)), 3) for q, p in
                          (("p50", 50), ("p90", 90), ("p99", 99), ("p99.9", 99.9),
                           ("max", 100))} if got else None,
           "phri_cpu_percent_of_one_core": round(100 * cpu / wall, 1),
           "wall_s": round(wall, 1), "exit": proc.returncode,
           "machine": {"cpus": os.cpu_count(), "python": sys.version.split()[0],
                       "liblsl": pylsl.library_version()}}
    if got:
        slow = np.flatnonzero(lat > 5.0)
        out["over_5ms"] = {"count": int(len(slow)),
                           "first_s": round(float(slow[0] / args.rate), 3) if len(slow) else None,
                           "last_s": round(float(slow[-1] / args.rate), 3) if len(slow) else None}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
