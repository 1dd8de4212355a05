"""The coupled arm's default interface (the lift-off cone, no friction key): how many
samples the semismooth Newton leaves unanswered and how many of those the active sets
then answer (docs/model.md 12.3 step 4).

    python -m benchmarks.coupled_rescue [--rows 2000] [--seeds 3]

For the human and Harmony presets (``--arm coupled``, the built-in FE), on
examples/wrench_log.csv and on ``--seeds`` smooth random logs of ``--rows`` samples
(pushes up to about 60 N at the cuff, ``phri_spring.synthetic.wrench.smooth_random_log``):
the samples flagged without the rescue and with it, and, for the run with it, the largest
imbalance of the written forces (normal, shear, moments) against the wrench plus the
strap's and the largest excess of a shear force over mu times its cone's normal force.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd

from benchmarks.common import COLS, EXAMPLES, HARMONY_CONFIG, HUMAN_CONFIG

from phri_spring.io.config import load_config
from phri_spring.physics.contact.paths import solve_friction
from phri_spring.physics.friction import path as friction_path
from phri_spring.physics.friction.form import interface_form
from phri_spring.synthetic.wrench import smooth_random_log
from phri_spring.workflows.common import cuff_wrench, model_from_config


def law_excess(model, W, sol):
    """(largest imbalance [N or N*m], largest shear beyond mu times the cone force [N])
    over the converged samples of a solution."""
    form = interface_form(model)
    ok = sol.converged
    m = int(ok.sum())
    P = np.zeros((m, form.n, form.d))
    P[:, :, 0] = sol.normal[ok]
    P[:, :, 1:3] = sol.tangential[ok]
    if sol.moments is not None:
        P[:, :, 3:] = sol.moments[ok]
    P = P.reshape(m, -1)
    balance = np.abs(P @ form.T - (W[ok] + model.W_pre)).max()
    shear = np.linalg.norm(sol.tangential[ok], axis=2)
    cone = (shear - model.interface_mu * np.maximum(form.cone_force(P), 0.0)).max()
    return balance, cone


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=2000)
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args(argv)
    example = pd.read_csv(EXAMPLES / "wrench_log.csv", comment="#")[COLS].to_numpy()
    print("| preset | log | samples | flagged without | flagged with | imbalance | cone excess |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for name, path in (("human", HUMAN_CONFIG), ("Harmony", HARMONY_CONFIG)):
        cfg = load_config(path)
        model = model_from_config(cfg, "coupled")
        logs = {"example": cuff_wrench(cfg, example)}
        for seed in range(args.seeds):
            logs[f"random seed {seed}"] = smooth_random_log(args.rows, seed=seed)[1]
        for log, W in logs.items():
            flagged = []
            for rescue in (False, True):
                friction_path._RESCUE = rescue
                t = time.perf_counter()
                sol = solve_friction(model, W, False, None)
                flagged.append((int((~sol.converged).sum()), time.perf_counter() - t))
            balance, cone = law_excess(model, W, sol)
            print(f"| {name} | {log} | {len(W)} | {flagged[0][0]} | {flagged[1][0]} | "
                  f"{balance:.1e} | {cone:.1e} |")
    friction_path._RESCUE = True


if __name__ == "__main__":
    main()
