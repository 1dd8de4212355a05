"""The coupled arm's default interface: lift-off released (docs/model.md 10.2) against the
old bonded-everywhere default, and frictionless contact (mu = 0) on the coupled arm.

    python -m benchmarks.coupled_lift_off [--repeats 3] [--minutes 5] [--out FILE]

1. Speed: ``solve`` on the first ``--minutes`` of the one-hour log of
   ``friction_benchmark.py`` (examples/wrench_log.csv repeated), coupled arm, each preset,
   bonded everywhere (``lift_off=False``, the old default) and lift-off released (the new
   default), interleaved, median of ``--repeats``, scaled to one hour.
2. How far the forces moved on the paper's loading (examples/wrench_log.csv): the largest
   change of a reported patch force, and the largest tangential force the old default left
   on a patch out of contact (the new one leaves none).
3. mu = 0 on the Harmony preset and examples/wrench_log.csv: each sample solved alone, in
   order (one ``solve`` call per sample, the path carried): median and largest CPU time of
   a sample (process time: what the sample costs, not how long a busy machine kept it
   waiting; the first, which builds the model's solver data, left out) and how many were
   flagged. ``--frictionless-only`` runs this part alone.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.common import ROOT  # noqa: E402

from phri_spring.io.config import load_config  # noqa: E402
from phri_spring.physics.contact.solver import FactorCache, solve  # noqa: E402
from phri_spring.workflows.common import cuff_wrench, model_from_config  # noqa: E402

COLS = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
HOUR = 360_000


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--minutes", type=float, default=5.0)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--frictionless-only", action="store_true")
    args = ap.parse_args()
    log = pd.read_csv(ROOT / "examples" / "wrench_log.csv", comment="#")[COLS].to_numpy()
    m = int(args.minutes * 6000)
    long_log = np.tile(log, (-(-m // len(log)), 1))[:m]
    lines = [f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python "
             f"{platform.python_version()}, numpy {np.__version__}. Command: "
             f"`python -m benchmarks.coupled_lift_off --repeats {args.repeats} "
             f"--minutes {args.minutes:g}`.", "",
             "| preset | samples | bonded everywhere `solve` [s] | lift-off released `solve` [s] "
             "| one hour, released [s] | event samples | not converged (released) | "
             "largest change of a patch force, paper's loading [N] (of peak [N]) | "
             "largest tangential force on a lifted patch, old default [N] |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for preset in () if args.frictionless_only else ("human_upper_arm", "harmony_upper_arm"):
        cfg = load_config(ROOT / "configs" / f"{preset}.yaml")
        new = model_from_config(cfg, "coupled")
        old = dataclasses.replace(new, lift_off=False)
        W = cuff_wrench(cfg, long_log)
        solve(new, W[:500])
        tb, tn, sol = [], [], None
        for _ in range(args.repeats):     # interleaved: drift touches both alike
            t0 = time.perf_counter()
            solve(old, W)
            tb.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            sol = solve(new, W)
            tn.append(time.perf_counter() - t0)
        tb, tn = statistics.median(tb), statistics.median(tn)
        Wp = cuff_wrench(cfg, log)
        a, b = solve(old, Wp), solve(new, Wp)
        ok = a.converged & b.converged
        moved = np.abs(a.forces[ok] - b.forces[ok]).max()
        peak = np.abs(a.forces[ok]).max()
        lifted_shear = np.linalg.norm(old.patch_forces(a.u[ok], a.contact[ok])[..., 1:3],
                                      axis=2)[~a.contact[ok]].max(initial=0.0)
        lines.append(f"| {preset} | {m:,} | {tb:.2f} | {tn:.2f} | {tn * HOUR / m:.0f} (scaled) | "
                     f"{int((sol.iterations > 1).sum()):,} ({100 * (sol.iterations > 1).mean():.1f} %) | "
                     f"{int((~sol.converged).sum())} | {moved:.2f} ({peak:.1f}) | {lifted_shear:.2f} |")
        print(lines[-1], flush=True)
    # frictionless contact, sample by sample
    cfg = dataclasses.replace(load_config(ROOT / "configs" / "harmony_upper_arm.yaml"),
                              friction_coefficient=0.0)
    model = model_from_config(cfg, "coupled")
    W = cuff_wrench(cfg, log)
    cache = FactorCache()
    times, flagged = [], 0
    for i in range(len(W)):
        t0 = time.process_time()
        s = solve(model, W[i:i + 1], cache=cache)
        times.append(time.process_time() - t0)
        flagged += int((~s.converged).sum())
    t = np.array(times[1:])
    lines += ["", f"mu = 0, Harmony preset, coupled arm, examples/wrench_log.csv ({len(W):,} "
              f"samples, one `solve` per sample, CPU time): total {sum(times):.2f} s, median sample "
              f"{1e3 * np.median(t):.3f} ms, largest {1e3 * t.max():.3f} ms "
              f"({t.max() / np.median(t):.0f}x the median; 99.9th percentile "
              f"{1e3 * np.percentile(t, 99.9):.3f} ms), first sample (set-up) "
              f"{1e3 * times[0]:.1f} ms; {flagged:,} flagged (no equilibrium)."]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        args.out.write_text(args.out.read_text() + "\n" + text if args.out.exists() else text)


if __name__ == "__main__":
    main()
