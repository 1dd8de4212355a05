"""What the coupled arm's interface events cost: ``solve`` on the first minutes of a long
log, one preset, the coupled arm, with its default interface (lift-off released) or a
Coulomb coefficient; CPU time of the solve alone (model built and warmed up first), and
that time scaled to one hour of 100 Hz samples.

    python -m benchmarks.coupled_event_cost [--preset human_upper_arm] [--mu 0.5]
        [--minutes 2] [--log FILE] [--root CHECKOUT]

The log is examples/wrench_log.csv repeated (``--log``: another CSV with the load cell's
six columns). ``--root``: time the phri_spring of another checkout (an older commit) with
this same script; run the two alternately and compare medians.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.common import ROOT, use_checkout

COLS = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
HOUR = 360_000


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="human_upper_arm")
    ap.add_argument("--mu", type=float, default=None, help="Coulomb coefficient (default: none)")
    ap.add_argument("--minutes", type=float, default=2.0)
    ap.add_argument("--log", type=Path, default=None)
    ap.add_argument("--root", type=Path, default=None)
    args = ap.parse_args()
    root = (args.root or ROOT).resolve()
    if args.root is not None:
        use_checkout(root)
    from phri_spring.io.config import load_config
    from phri_spring.physics.contact.solver import solve
    from phri_spring.workflows.common import cuff_wrench, model_from_config

    log = pd.read_csv(args.log or root / "examples" / "wrench_log.csv", comment="#")[COLS]
    log = log.to_numpy()
    m = int(args.minutes * 6000)
    log = np.tile(log, (-(-m // len(log)), 1))[:m]
    cfg = load_config(root / "configs" / f"{args.preset}.yaml")
    if args.mu is not None:
        cfg = dataclasses.replace(cfg, friction_coefficient=args.mu)
    model = model_from_config(cfg, "coupled")
    W = cuff_wrench(cfg, log)
    solve(model, W[:50])                    # the model's solver data, built once
    t0 = time.process_time()
    sol = solve(model, W)
    t = time.process_time() - t0
    print(f"{args.preset} mu={args.mu} samples={m} solve_cpu_s={t:.3f} "
          f"hour_s={t * HOUR / m:.1f} events={int((sol.iterations > 1).sum())} "
          f"not_converged={int((~sol.converged).sum())}")


if __name__ == "__main__":
    main()
