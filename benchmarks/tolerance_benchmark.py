"""Cost of the dose columns (docs/tolerance.md): ``phri simulate`` on a one-hour log with
and without ``--tolerance``, run in turn (A B A B ...), median wall times and their ratio.

Usage (from the repository root, after ``pip install -e .``):

    python -m benchmarks.tolerance_benchmark                  # 5 pairs, CSV output
    python -m benchmarks.tolerance_benchmark --repeats 9 --output-format parquet
    python -m benchmarks.tolerance_benchmark --uncertainty 20 --samples 60000

The log is the synthetic one-hour log of ``benchmarks/common.py`` (``make_log``: 100 Hz,
360,000 samples, fixed seed; ``--samples`` another length), written to a temporary folder.
``--uncertainty N`` times ``simulate --uncertainty N`` instead (tissue SD 10 %, force
noise 0.5 N), where every draw follows its own dose.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.common import HARMONY_CONFIG as CONFIG, make_log


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--output-format", choices=("csv", "parquet"), default="csv")
    ap.add_argument("--curve", default="linder_ganz_2006")
    ap.add_argument("--samples", type=int, default=360_000)
    ap.add_argument("--uncertainty", type=int, default=None, metavar="N")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "hour.parquet"
        make_log(log, a.samples, seed=1)
        out = Path(tmp) / f"forces.{a.output_format}"
        base = [sys.executable, "-m", "phri_cli.main", "simulate", str(CONFIG), str(log),
                "-o", str(out), "-q"]
        if a.uncertainty is not None:
            base += ["--uncertainty", str(a.uncertainty), "--uncertainty-sd",
                     "tissue=0.1,force=0.5"]
        cmds = {"default": base, "tolerance": base + ["--tolerance", a.curve]}
        times = {k: [] for k in cmds}
        for _ in range(a.repeats + 1):              # the first round warms the caches
            for k, cmd in cmds.items():
                t0 = time.perf_counter()
                subprocess.run(cmd, check=True)
                times[k].append(time.perf_counter() - t0)
        ratios = [b / a_ for a_, b in zip(times["default"][1:], times["tolerance"][1:])]
        for k, v in times.items():
            print(f"{k:10s} median {statistics.median(v[1:]):.2f} s  runs "
                  + " ".join(f"{x:.2f}" for x in v[1:]))
        print(f"ratio tolerance/default, median of pairs: {statistics.median(ratios):.3f}")


if __name__ == "__main__":
    main()
