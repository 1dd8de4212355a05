"""Time of every sample of a log with friction, one sample at a time, and why some have no answer.

    python -m benchmarks.no_equilibrium_timing CONFIG ARM MU LOG [--rows N] [--repeats 3]

LOG is a wrench log CSV (load-cell columns Fx..Mz) or ``random20`` (uniform random forces
of +-20 N on each load-cell axis, no moment, independent samples, seed 0). Each sample is
solved by ``Solver`` (one call per sample, the path carried from call to call, as a
control loop does), ``--repeats`` times from the strap's state; a sample's time is its
least over the repeats (the machine's noise only adds). The first sample (it builds the
model's interface arrays) is left out. Prints the share of samples without an answer by
reason (``phri_spring.physics.contact.no_equilibrium``) and the median, 99th percentile and
largest sample time.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml


from phri_spring.io.config import load_config  # noqa: E402
from phri_spring.physics.contact.no_equilibrium import REASONS, explain  # noqa: E402
from phri_spring.physics.contact.solver import Solver  # noqa: E402
from phri_spring.workflows.common import cuff_wrench, model_from_config  # noqa: E402

COLS = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config")
    ap.add_argument("arm")
    ap.add_argument("mu", type=float)
    ap.add_argument("log")
    ap.add_argument("--rows", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args()
    raw = yaml.safe_load(Path(a.config).read_text())
    raw.setdefault("interface", {})["friction_coefficient"] = a.mu
    tmp = Path(f"/tmp/no_equilibrium_timing_{a.arm}.yaml")
    tmp.write_text(yaml.safe_dump(raw))
    cfg = load_config(tmp)
    model = model_from_config(cfg, a.arm)
    if a.log == "random20":
        rng = np.random.default_rng(0)
        W_lc = np.zeros((a.rows, 6))
        W_lc[:, :3] = rng.uniform(-20.0, 20.0, (a.rows, 3))
    else:
        W_lc = pd.read_csv(a.log, comment="#", nrows=a.rows)[COLS].to_numpy()
    W = cuff_wrench(cfg, W_lc)
    m = len(W)
    times = np.full(m, np.inf)
    conv = np.zeros(m, dtype=bool)
    for _ in range(a.repeats):
        solver = Solver(model)
        for i in range(m):
            t0 = time.perf_counter()
            solver.forces(W[i])
            times[i] = min(times[i], time.perf_counter() - t0)
            conv[i] = solver.last_converged
    code, s_N, s_Nm = explain(model, W, conv)
    t = times[1:]
    med = np.median(t)
    shares = ", ".join(f"{REASONS[k]} {100 * np.mean(code == k):.1f} %" for k in range(1, 5)
                       if (code == k).any())
    print(f"{Path(a.config).stem} {a.arm} mu={a.mu:g} {Path(a.log).name} {m} samples: "
          f"no answer {100 * np.mean(~conv):.1f} % ({shares or 'none'}); sample time median "
          f"{1e3 * med:.3f} ms, p99 {1e3 * np.percentile(t, 99):.3f} ms, max "
          f"{1e3 * t.max():.3f} ms = {t.max() / med:.0f}x the median")


if __name__ == "__main__":
    main()
