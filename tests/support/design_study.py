"""A small design study (two logs with duplicate rows, a grid over three keys), shared by
the design, dask and uncertainty tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from phri_spring.synthetic.wrench import smooth_random_log
from support.helpers import harmony_dict

COLS = ["time", "Fx", "Fy", "Fz", "Mx", "My", "Mz"]


def write_log(path: Path, n: int, seed: int, repeat_every: int = 7) -> Path:
    """A smooth log with exact duplicate rows (every ``repeat_every``-th row repeats)."""
    t, W = smooth_random_log(n, seed=seed, force_amp_n=25.0, moment_amp_nm=0.8)
    W = np.round(W, 3)
    W[repeat_every::repeat_every] = W[0]
    pd.DataFrame(np.column_stack([t, W]), columns=COLS).to_csv(path, index=False,
                                                               float_format="%.17g")
    return path


def make_study(folder: Path, extra: dict | None = None, n: int = 400, **over) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    cfg = harmony_dict()
    (folder / "base.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    write_log(folder / "log_a.csv", n, seed=3)
    write_log(folder / "log_b.csv", n // 2, seed=4)
    study = {
        "config": "base.yaml",
        "loads": ["log_a.csv", "log_b.csv"],
        "arm": "compliant",
        "vary": {"strap.tension": {"values": [4, 15, 40]},
                 "cuff.stiffness.per_angle": {"scale": [0.5, 2]},
                 "cuff.stiffness.per_angle[5]": {"range": [1.0e5, 2.0e6], "log": True,
                                                 "count": 2}},
        "plan": "grid",
        "minimise": ["peak_pressure_to_pain_threshold", "lift_off_fraction"],
        "constraints": {"stiffness_translational_N_per_mm": ">= 2"},
    }
    study.update(over)
    if extra:
        study.update(extra)
    path = folder / "study.yaml"
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    return path
