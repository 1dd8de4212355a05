"""``phri simulate --uncertainty`` with a tissue history: relaxation and a log's activation.

Reference: ``phri simulate`` on the same log (its chunked history solve). Without scatter
every draw is that run, so all three percentiles are its forces; a draw that shared
another's history (the time going back at each draw) would not be.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import yaml
from click.testing import CliRunner

from phri_cli.main import phri
from phri_spring.io.config import load_config
from phri_spring.workflows.uncertainty.run import MonteCarloStream, UncertainInputs, monte_carlo
from support.helpers import REPO, harmony_dict

RELAXATION = REPO / "examples" / "relaxation.yaml"
LABELS = [f"{r}{j}" for r in "ABC" for j in range(7)]


def _log(path, m=200, activation=None, seed=1):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.005, 0.05, m))
    W = np.cumsum(rng.normal(size=(m, 6)), axis=0) * [2, 2, 2, 0.05, 0.05, 0.05]
    df = pd.DataFrame(W, columns=["Fx", "Fy", "Fz", "Mx", "My", "Mz"])
    df.insert(0, "time", t)
    if activation is not None:
        df["activation"] = activation
    df.to_csv(path, index=False, float_format="%.17g")
    return path, t, W


def _percentiles_are_simulate(tmp_path, cfg, log):
    sim = tmp_path / "sim.csv"
    res = CliRunner().invoke(phri, ["simulate", str(cfg), str(log), "-o", str(sim), "-q"])
    assert res.exit_code == 0, res.output
    out = tmp_path / "mc.csv"
    res = CliRunner().invoke(phri, ["simulate", str(cfg), str(log), "-o", str(out), "-q",
                                    "--uncertainty", "3", "--uncertainty-sd", "tissue=0"])
    assert res.exit_code == 0, res.output       # (was an internal error with relaxation)
    ref, mc = pd.read_csv(sim), pd.read_csv(out)
    for tag in ("p5", "p50", "p95"):
        np.testing.assert_allclose(mc[[f"{lab}_{tag}" for lab in LABELS]].to_numpy(),
                                   ref[LABELS].to_numpy(), rtol=0, atol=2e-6)
    return ref


def test_relaxing_tissue_draws_are_the_simulated_run(tmp_path):
    log, _, _ = _log(tmp_path / "log.csv")
    _percentiles_are_simulate(tmp_path, RELAXATION, log)


def test_an_activation_column_is_read_by_every_draw(tmp_path):
    raw = harmony_dict()
    raw["tissue"]["activation_factor"] = 3.0
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    log, _, _ = _log(tmp_path / "log.csv", activation=np.linspace(0.0, 1.0, 200))
    ref = _percentiles_are_simulate(tmp_path, cfg, log)
    plain, _, _ = _log(tmp_path / "plain.csv")
    res = CliRunner().invoke(phri, ["simulate", str(cfg), str(plain), "-o",
                                    str(tmp_path / "p.csv"), "-q"])
    assert res.exit_code == 0, res.output
    gap = np.abs(pd.read_csv(tmp_path / "p.csv")[LABELS].to_numpy() - ref[LABELS].to_numpy())
    assert gap[-1].max() > 1e-3                  # the activation changed the forces


def test_each_draw_carries_its_history_across_blocks(tmp_path):
    cfg = load_config(RELAXATION)
    _, t, W = _log(tmp_path / "log.csv", m=60)
    inputs = UncertainInputs(np.zeros(cfg.n_elements), 0.0, 0.0, 0.0)
    whole = monte_carlo(cfg, W, draws=2, inputs=inputs, time=t)
    mc = MonteCarloStream(cfg, draws=2, inputs=inputs)
    mc.block_samples = 7
    parts = list(mc.blocks([(t[:25], W[:25]), (t[25:], W[25:])]))
    np.testing.assert_allclose(np.concatenate([f for _, f, _ in parts], axis=1), whole.forces,
                               rtol=0, atol=1e-12)
