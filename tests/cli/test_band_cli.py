"""``phri simulate`` with ``strap.model: band`` (docs/model.md section 3.1).

The output's forces balance the wrench on the cuff (computed here from the log with the
load-cell transform) plus the band's pull at the shell's edges at the reported tension, by
hand on the circle (h = (0, 2 sin(edge), 0, 0, 0, 0)); the hoop's output has no band
columns; a bad band key is one line, exit 1.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import yaml

from phri_spring.io.config import load_config
from phri_spring.workflows.common import cuff_wrench, model_from_config
from support.helpers import REPO, assert_one_line_error, run_phri

EXAMPLE = REPO / "examples" / "band_strap.yaml"
HUMAN = REPO / "configs" / "human_upper_arm.yaml"


def _log(tmp_path, m=200):
    rng = np.random.default_rng(5)
    t = 0.01 * np.arange(m)
    w = np.column_stack([rng.normal(0, 5, m), np.linspace(-60, 40, m), rng.normal(0, 5, m),
                         rng.normal(0, 0.2, (m, 3))])
    path = tmp_path / "log.csv"
    pd.DataFrame(np.column_stack([t, w]), columns=["time", "Fx", "Fy", "Fz", "Mx", "My", "Mz"]
                 ).to_csv(path, index=False)
    return path, w


def test_band_columns_and_balance(tmp_path):
    log, w_lc = _log(tmp_path)
    out = tmp_path / "f.csv"
    res = run_phri("simulate", EXAMPLE, log, "-o", out, "--arm", "rigid", "--shear")
    assert res.exit_code == 0, res.output
    assert "largest strap tension" in res.output
    df = pd.read_csv(out, comment="#")
    T = df["strap_tension_N"].to_numpy()
    assert df["converged"].all() and (T >= 0).all()
    # the pull away from the shell (Fy < 0 on the load cell at -y) stretches the band
    assert T[0] > T[-1]
    cfg = load_config(EXAMPLE)
    labels = list(cfg.labels)
    f = df[[f"{lab}_force_{c}_N" for lab in labels for c in "xyz"]].to_numpy().reshape(
        len(df), len(labels), 3)
    edge = math.radians(75.0 - 35.0 / 2)
    h = np.array([0.0, 2 * math.sin(edge), 0.0])
    W = cuff_wrench(cfg, w_lc)
    assert np.allclose(f.sum(axis=1), W[:, :3] + T[:, None] * h, atol=1e-4)
    # Laplace's law on the circle of the preset
    R = cfg.geometry().radius[0]
    assert np.allclose(df["strap_pressure_kPa"], T / (0.05 * R) / 1000, rtol=1e-5)


def test_hoop_output_has_no_band_column(tmp_path):
    log, _ = _log(tmp_path, 20)
    out = tmp_path / "f.csv"
    res = run_phri("simulate", HUMAN, log, "-o", out)
    assert res.exit_code == 0, res.output
    assert "strap_tension_N" not in pd.read_csv(out, comment="#").columns
    assert "strap tension" not in res.output


def test_bad_band_key_is_one_line(tmp_path):
    log, _ = _log(tmp_path, 20)
    raw = yaml.safe_load(EXAMPLE.read_text())
    del raw["strap"]["stiffness"]
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    res = run_phri("simulate", cfg, log, "-o", tmp_path / "f.csv")
    assert_one_line_error(res, "strap.stiffness", "tension per unit strain")
    assert not (tmp_path / "f.csv").exists()


def test_the_example_runs_on_the_compliant_arm():
    model = model_from_config(load_config(EXAMPLE), "compliant")
    assert model.strap_model == "band" and model.band_tension == 15.0
