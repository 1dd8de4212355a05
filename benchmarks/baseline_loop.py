"""The baseline of the benchmarks: `phri simulate` done the plain way.

pandas reads the log, a per-sample Python loop solves each sample with
np.linalg.solve in an active-set loop (phri_spring.physics.contact.solver.solve_per_sample:
same method and stopping rule, no vectorisation, caching or warm start), and
pandas writes the forces. Usage:

    python -m benchmarks.baseline_loop CONFIG LOG.csv OUT.csv
"""

import sys

import pandas as pd

from phri_spring.io.config import load_config
from phri_spring.physics.contact.solver import solve_per_sample
from phri_spring.workflows.common import cuff_wrench, model_from_config


def main(config, log, out):
    cfg = load_config(config)
    model = model_from_config(cfg, "compliant")
    df = pd.read_csv(log, comment="#")
    w = df[["Fx", "Fy", "Fz", "Mx", "My", "Mz"]].to_numpy(float)
    sol = solve_per_sample(model, cuff_wrench(cfg, w), max_iterations=cfg.max_iterations)
    res = pd.DataFrame(sol.forces, columns=list(model.labels))
    res.insert(0, "time", df["time"].to_numpy())
    res["solver_iterations"] = sol.iterations
    res.to_csv(out, index=False)


if __name__ == "__main__":
    main(*sys.argv[1:4])
