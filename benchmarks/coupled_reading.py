"""What a coupled patch reads (issue 32, item 3): the compressive part of its normal traction
against the traction integral clipped at 0 (the label column before), and what it costs.

    python -m benchmarks.coupled_reading [--repeats 5] [--out FILE]

For the human and Harmony presets (``--arm coupled``, the built-in FE), without a friction
key (the lift-off cone, mu = 10) and with ``interface.friction_coefficient`` 0.5, on
examples/wrench_log.csv and on one-sided pushes (30 ramps of 0..60 N in seeded random
directions of the load cell's y-z plane, 100 samples each, Fx noise 2 N): the samples
solved, the patch-samples whose label reads 0 N while the patch carries a tangential force
or a moment (above 1e-9), for the clipped integral and for the reading; the smallest
reading of a touching patch; the largest excess of a tangential force over mu times the
reading and over mu times the force along n_e (the solver's cone is on the smaller of the
force along n_e and the reading's traction integral, so both should be round-off). Then the
reading's own time per 100,000 samples against the clipped integral's (median of
``--repeats``, process time).
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

from benchmarks.common import COLS, EXAMPLES, HARMONY_CONFIG, HUMAN_CONFIG

from phri_spring.io.config import load_config
from phri_spring.physics.friction.form import interface_form
from phri_spring.physics.friction.path import solve_path
from phri_spring.workflows.common import cuff_wrench, model_from_config


def pushes(seed: int = 32, ramps: int = 30, per: int = 100, peak: float = 60.0,
           noise: float = 2.0) -> np.ndarray:
    """Load-cell wrenches (ramps * per, 6): one-sided pushes in the y-z plane."""
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(ramps):
        a = rng.uniform(0.0, 2.0 * np.pi)
        for s in np.linspace(0.0, peak, per):
            rows.append([rng.normal(0.0, noise), s * np.cos(a), s * np.sin(a), 0.0, 0.0, 0.0])
    return np.array(rows)


def clipped(model, P, touching):
    """The label column before: N_out C_t P, clipped at 0, 0 out of contact."""
    f = np.maximum(P @ (model.N_out @ model.C_t).T, 0.0)
    f[~touching] = 0.0
    return f


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    example = pd.read_csv(EXAMPLES / "wrench_log.csv", comment="#")[COLS].to_numpy()
    logs = {"examples/wrench_log.csv": example, "pushes (3,000)": pushes()}
    lines = [f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python "
             f"{platform.python_version()}, numpy {np.__version__}. Command: "
             f"`python -m benchmarks.coupled_reading --repeats {args.repeats}`.", "",
             "| preset | mu | log | solved | label 0 N with a load: clipped integral | "
             "label 0 N with a load: reading | smallest reading in contact [N] | "
             "tangential - mu reading, largest [N] | tangential - mu f_n, largest [N] |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    timing = None
    for preset in (HUMAN_CONFIG, HARMONY_CONFIG):
        base = load_config(preset)
        for mu in (None, 0.5):
            cfg = dataclasses.replace(base, friction_coefficient=mu)
            model = model_from_config(cfg, "coupled")
            m = model.interface_mu
            for name, log in logs.items():
                r = cuff_wrench(cfg, log) + model.W_pre
                u, P, cls, _, conv, _ = solve_path(interface_form(model), r)
                P, touching = P[conv], cls[conv] > 0
                Pe = P.reshape(len(P), model.n, model.dofs)
                load = ((np.abs(Pe[:, :, 1:3]).max(axis=2) > 1e-9)
                        | (np.abs(Pe[:, :, 3:]).max(axis=2) > 1e-9))
                old = clipped(model, P, touching)
                new = model.reported_normal(P, touching)
                tn = np.linalg.norm(Pe[:, :, 1:3], axis=2)
                lines.append(
                    f"| {Path(preset).stem} | {'none (10)' if mu is None else mu} | {name} | "
                    f"{int(conv.sum())} of {len(conv)} | {int(((old == 0) & load).sum())} | "
                    f"{int(((new == 0) & load).sum())} | {new[touching].min():.3f} | "
                    f"{(tn - m * new).max():.3f} | {(tn - m * Pe[:, :, 0]).max():.1e} |")
                if timing is None:
                    timing = (model, np.tile(P, (max(1, 100_000 // len(P)), 1)))
    model, P = timing
    touching = np.ones((len(P), model.n), dtype=bool)
    t_old, t_new = [], []
    for _ in range(args.repeats):
        t0 = time.process_time()
        clipped(model, P, touching)
        t_old.append(time.process_time() - t0)
        t0 = time.process_time()
        model.reported_normal(P, touching)
        t_new.append(time.process_time() - t0)
    per = 100_000 / len(P)
    lines += ["", f"Per 100,000 samples ({model.n} patches, "
              f"{len(model.reading.owner)} skin nodes): reading "
              f"{statistics.median(t_new) * per:.3f} s, clipped integral "
              f"{statistics.median(t_old) * per:.3f} s (process time, median of "
              f"{args.repeats})."]
    text = "\n".join(lines)
    print(text)
    if args.out:
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
