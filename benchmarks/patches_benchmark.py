"""Samples per second of a 16 x 16 pressure mat (256 patches) against the paper's 21-element
grid: ``phri simulate`` (compliant arm) on the same one-hour log, whole process, the two
commands alternated and compared pair by pair (ratio of each pair, then the median).

    python -m benchmarks.patches_benchmark [--repeats 5] [--workdir /tmp/phri_patches]

The log is benchmarks/common.py's make_log(path, 360000, 1) (one hour at 100 Hz);
the configs are configs/harmony_upper_arm.yaml and examples/pressure_mat_16x16.yaml.
Prints the median wall and CPU (user + system) seconds of each and the paired ratios.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import time
from pathlib import Path

from benchmarks.common import HARMONY_CONFIG, ROOT, make_log


def run(cmd) -> tuple:
    """(wall [s], cpu user + system [s]) of one command, whole process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--workdir", type=Path, default=Path("/tmp/phri_patches"))
    a = ap.parse_args()
    a.workdir.mkdir(parents=True, exist_ok=True)
    log = a.workdir / "hour.csv"
    if not log.exists():
        make_log(log, 360000, 1)
    phri = shutil.which("phri") or "phri"
    grid = [phri, "simulate", str(HARMONY_CONFIG), str(log),
            "-o", str(a.workdir / "grid.parquet"), "-q"]
    mat = [phri, "simulate", str(ROOT / "examples" / "pressure_mat_16x16.yaml"), str(log),
           "-o", str(a.workdir / "mat.parquet"), "-q"]
    run(grid), run(mat)                                     # warm-up (file cache, imports)
    rows = {"grid": [], "mat": []}
    for _ in range(a.repeats):
        rows["grid"].append(run(grid))
        rows["mat"].append(run(mat))
    med = {k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v))
           for k, v in rows.items()}
    wall_ratio = statistics.median(m[0] / g[0] for g, m in zip(rows["grid"], rows["mat"]))
    cpu_ratio = statistics.median(m[1] / g[1] for g, m in zip(rows["grid"], rows["mat"]))
    print(f"cores visible: {os.cpu_count()}; repeats: {a.repeats}")
    for k in ("grid", "mat"):
        print(f"{k}: median wall {med[k][0]:.2f} s, cpu {med[k][1]:.2f} s, "
              f"{360000 / med[k][0]:,.0f} samples/s (wall)")
    print(f"mat / grid, median of paired ratios: wall {wall_ratio:.2f}, cpu {cpu_ratio:.2f}; "
          f"the mat runs at {100 / wall_ratio:.0f} % (wall) / {100 / cpu_ratio:.0f} % (cpu) "
          "of the grid's samples/s")


if __name__ == "__main__":
    main()
