"""How often the coupled arm's active sets (friction set) hand a sample to the semismooth
Newton, and what the solve costs (docs/model.md 12.3 step 2).

    python -m benchmarks.active_set_fallbacks [--rows 36000]

For the human and Harmony presets with ``interface.friction_coefficient: 0.5`` (built-in
FE), on examples/wrench_log.csv repeated to ``--rows`` samples: the samples solved by the
active sets, those handed to the semismooth Newton, the samples not converged, and the
solve's time (process time, one run, after the FE is cached).
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
import pandas as pd

from benchmarks.common import COLS, EXAMPLES, HARMONY_CONFIG, HUMAN_CONFIG

from phri_spring.io.config import load_config
from phri_spring.physics.friction import path as friction_path
from phri_spring.physics.friction.form import interface_form
from phri_spring.workflows.common import cuff_wrench, model_from_config


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=36000)
    args = ap.parse_args(argv)
    log = pd.read_csv(EXAMPLES / "wrench_log.csv", comment="#")[COLS].to_numpy()
    log = np.tile(log, (args.rows // len(log) + 1, 1))[:args.rows]
    step = friction_path.active_step
    print("| preset | samples | by active sets | handed to the semismooth Newton | not converged "
          "| solve [s CPU] |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, path in (("human", HUMAN_CONFIG), ("Harmony", HARMONY_CONFIG)):
        cfg = dataclasses.replace(load_config(path), friction_coefficient=0.5)
        model = model_from_config(cfg, "coupled")
        form = interface_form(model)
        r = cuff_wrench(cfg, log) + model.W_pre
        count = {"ok": 0, "none": 0}

        def counted(*a):
            out = step(*a)
            count["none" if out is None else "ok"] += 1
            return out

        friction_path.active_step = counted
        try:
            t = time.process_time()
            *_, conv, _ = friction_path.solve_path(form, r, None, {})
            cpu = time.process_time() - t
        finally:
            friction_path.active_step = step
        print(f"| {name} | {len(r)} | {count['ok']} | {count['none']} | {int((~conv).sum())} "
              f"| {cpu:.2f} |")


if __name__ == "__main__":
    main()
