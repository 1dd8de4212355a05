"""Monte Carlo percentiles against a closed form, and ``phri simulate --uncertainty``.

Linear case: the strap preload keeps every element in contact, so each force is
affine in the Gaussian inputs (load-cell noise and strap tension):
f_e = T c_e + k_e b_e . H^-1 J (w + noise), with H = K_s + sum_e k_e b_e b_e^T
and c_e the hoop preload per newton of tension (built by the independent
``reference_model``). Each force is then Gaussian with a known mean and SD,
and its 5/50/95th percentiles are mean + z SD, z = -1.645, 0, 1.645.
"""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

import math

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner
from scipy.stats import norm

from support import reference_model as ref
from support.helpers import harmony_dict, one_line
from phri_cli.main import phri
from phri_spring.io.config import config_from_dict, load_config
from phri_spring.workflows.uncertainty.run import (UncertainInputs, monte_carlo, parse_sd,
                                               uncertain_inputs)

T_MEAN, T_SD = 30.0, 1.5
NOISE = np.array([0.4, 0.4, 0.4, 0.02, 0.02, 0.02])
W_LC = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                 [2.0, -3.0, 4.0, 0.05, -0.02, 0.03]])


def closed_form(cfg_dict):
    """(mean (m, n), sd (n,)) of every force under the Gaussian inputs, full contact."""
    m1 = ref.model_from_config({**cfg_dict, "strap": {"tension": 1.0, "model": "hoop"}})
    b, k = m1.geom.b, m1.k
    H = m1.Ks + (b.T * k) @ b
    J = ref.loadcell_to_cuff(np.eye(6), cfg_dict["load_cell"]).T      # W_cuff = J w_lc
    A = (k[:, None] * b) @ np.linalg.solve(H, J)                       # df/dw_lc (n, 6)
    c = m1.f0                                                          # df/dT (n,)
    mean = T_MEAN * c[None, :] + W_LC @ A.T
    sd = np.sqrt((A ** 2) @ (NOISE ** 2) + (c * T_SD) ** 2)
    # the linear case holds: every element stays well in compression
    assert np.all(mean - 6 * sd > 0)
    return mean, sd


@pytest.fixture(scope="module")
def linear_case():
    d = harmony_dict()
    d["strap"]["tension"] = T_MEAN
    cfg = config_from_dict(d)
    inputs = UncertainInputs(np.zeros(cfg.n_elements), T_SD, NOISE[0], NOISE[3])
    return d, cfg, inputs


def test_percentiles_converge_to_the_closed_form(linear_case):
    d, cfg, inputs = linear_case
    mean, sd = closed_form(d)
    z = norm.ppf([0.05, 0.5, 0.95])
    exact = mean[None] + z[:, None, None] * sd[None, None, :]          # (3, m, n)
    errs = []
    for n in (200, 3200):
        res = monte_carlo(cfg, W_LC, draws=n, seed=7, inputs=inputs)
        assert res.forces.shape == (3, len(W_LC), cfg.n_elements)
        # standard error of a sample quantile: sqrt(q (1 - q) / N) / pdf(z_q) * SD
        se = np.sqrt(np.array([0.05 * 0.95, 0.25, 0.05 * 0.95]) / n) / norm.pdf(z)
        err = np.abs(res.forces - exact) / (se[:, None, None] * sd[None, None, :])
        assert np.max(err) < 5.0, (n, np.max(err))
        errs.append(np.mean(np.abs(res.forces - exact)))
    assert errs[1] < 0.5 * errs[0]          # error shrinks about as 1/sqrt(N)


def test_results_depend_only_on_seed_and_draws(linear_case):
    _d, cfg, inputs = linear_case
    a = monte_carlo(cfg, W_LC, draws=20, seed=3, inputs=inputs)
    b = monte_carlo(cfg, W_LC, draws=20, seed=3, inputs=inputs)
    c = monte_carlo(cfg, W_LC, draws=20, seed=4, inputs=inputs)
    assert np.array_equal(a.forces, b.forces) and not np.array_equal(a.forces, c.forces)
    assert np.all(a.forces[0] <= a.forces[1]) and np.all(a.forces[1] <= a.forces[2])


def test_tissue_sd_from_the_fit_stiffness_csv(tmp_path):
    d = harmony_dict()
    labels = [f"{r}{j}" for r in "ABC" for j in range(7)]
    sd = np.linspace(10, 300, 21)
    pd.DataFrame({"location": labels, "stiffness_N_per_m": np.full(21, 4242.0),
                  "std_N_per_m": sd}).to_csv(tmp_path / "k.csv", index=False)
    d["tissue"]["stiffness"] = "k.csv"
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(d))
    cfg = load_config(tmp_path / "c.yaml")
    np.testing.assert_array_equal(uncertain_inputs(cfg).tissue_sd, sd)
    rel = uncertain_inputs(cfg, tissue_sd=0.06).tissue_sd
    np.testing.assert_allclose(rel, 0.06 * 4242.0, rtol=1e-15)
    res = monte_carlo(cfg, W_LC, draws=40, seed=1)
    # at zero wrench the hoop preload fixes every force (f_e = k_e delta0_e = f0_e): no
    # scatter; under load the tissue stiffness spreads them
    np.testing.assert_allclose(res.forces[2, 0], res.forces[0, 0], rtol=1e-12)
    assert np.all(res.forces[2, 1] > res.forces[0, 1])


def test_parse_sd():
    assert parse_sd("tension=0.1,force=0.3") == {"tissue_sd": "from_csv", "tension_sd_N": 0.1,
                                                  "force_sd_N": 0.3, "moment_sd_Nm": 0.0}
    assert parse_sd("tissue=0.06")["tissue_sd"] == 0.06


def test_simulate_uncertainty_cli(tmp_path):
    d = harmony_dict()
    d["strap"]["tension"] = T_MEAN
    cfg_path = tmp_path / "c.yaml"
    cfg_path.write_text(yaml.safe_dump(d))
    log = tmp_path / "log.csv"
    pd.DataFrame(np.column_stack([[0.0, 0.01], W_LC]),
                 columns=["time", "Fx", "Fy", "Fz", "Mx", "My", "Mz"]).to_csv(log, index=False)
    out = tmp_path / "mc.csv"
    res = CliRunner().invoke(phri, ["simulate", str(cfg_path), str(log), "-o", str(out),
                                    "--uncertainty", "400", "--seed", "2", "--uncertainty-sd",
                                    f"tension={T_SD},force={NOISE[0]},moment={NOISE[3]}"])
    assert res.exit_code == 0, res.output
    t = pd.read_csv(out)
    assert list(t.columns[:4]) == ["time", "A0_p5", "A0_p50", "A0_p95"]
    assert "peak_pressure_to_pain_threshold_p95" in t.columns
    mean, sd = closed_form(d)
    # 400 draws: the median within 5 standard errors of the exact mean (decimals: 1e-6 N)
    se = math.sqrt(0.25 / 400) / norm.pdf(0) * sd
    assert np.all(np.abs(t[[f"{lab}_p50" for lab in ref_labels()]].to_numpy() - mean)
                  < 5 * se + 1e-6)
    bad = CliRunner().invoke(phri, ["simulate", str(cfg_path), str(log), "-o",
                                    str(tmp_path / "x.csv"), "--uncertainty", "10",
                                    "--uncertainty-sd", "tension=-1"])
    assert bad.exit_code == 2 and one_line(bad.stderr) and "--uncertainty-sd" in bad.stderr
    assert not (tmp_path / "x.csv").exists()


def ref_labels():
    return [f"{r}{j}" for r in "ABC" for j in range(7)]


def test_study_uncertainty_and_sobol(tmp_path):
    pytest.importorskip("SALib")
    from support.design_study import make_study
    from phri_spring.workflows.design.study import run_study

    path = make_study(tmp_path / "s", n=60, vary={"strap.tension": {"values": [10, 20]}},
                      constraints={},
                      uncertainty={"draws": 20, "seed": 1, "strap_tension_sd_N": 2.0,
                                   "tissue_stiffness_sd": 0.06, "sobol": 16})
    r = run_study(path, tmp_path / "out", workers=1, figures=False)
    out = tmp_path / "out"
    obj = pd.read_csv(out / "uncertainty_objectives.csv")
    assert list(obj["objective"]) == ["peak_pressure_to_pain_threshold", "lift_off_fraction"]
    assert np.all(obj["p5"] <= obj["p50"]) and np.all(obj["p50"] <= obj["p95"])
    sob = pd.read_csv(out / "sobol.csv")
    assert set(sob["input"]) == {f"tissue.stiffness[{lab}]" for lab in ref_labels()} | \
        {"strap.tension"}
    # a 2 N SD on the tension moves the peak far more than 6 % on one location's tissue
    pk = sob[sob["objective"] == "peak_pressure_to_pain_threshold"].set_index("input")
    assert pk.loc["strap.tension", "ST"] == pk["ST"].max()
    assert "Uncertainty of the best design" in (out / "report.md").read_text()
    assert r.best >= 0


def test_compare_bands(tmp_path):
    repo = REPO
    cfg = repo / "configs" / "harmony_upper_arm.yaml"
    man = repo / "examples" / "experiment" / "manifest.yaml"
    out = tmp_path / "cmp"
    res = CliRunner().invoke(phri, ["compare", str(cfg), str(man), "-o", str(out), "-q",
                                    "--no-figures", "--uncertainty", "3", "--uncertainty-sd",
                                    "tissue=0,tension=0"])
    assert res.exit_code == 0, res.output
    b = pd.read_csv(out / "bands.csv")
    # no scatter: every draw is the config itself, so the band is the compare prediction
    for col in ("sim_p5_N", "sim_p50_N", "sim_p95_N"):
        np.testing.assert_allclose(b[col], b["simulated_N"], atol=2e-6, rtol=0)
    assert not (out / "bands").exists()              # --no-figures
    out2 = tmp_path / "cmp2"
    res = CliRunner().invoke(phri, ["compare", str(cfg), str(man), "-o", str(out2), "-q",
                                    "--no-figures", "--arms", "compliant", "--uncertainty",
                                    "8", "--uncertainty-sd",
                                    "tissue=0.06,tension=0.5"])
    assert res.exit_code == 0, res.output
    b = pd.read_csv(out2 / "bands.csv")
    assert np.all(b["sim_p5_N"] <= b["sim_p50_N"] + 1e-9)
    assert np.all(b["sim_p50_N"] <= b["sim_p95_N"] + 1e-9)
    # zeroed compliant-arm loads depend on the tissue stiffness: a spread where loaded (the
    # rigid arm's would not: cuff springs only, and zeroing removes the preload)
    loaded = b[b["simulated_N"].abs() > 0.5]
    assert len(loaded) and np.all(loaded["sim_p95_N"] - loaded["sim_p5_N"] > 0)


def test_simulate_uncertainty_needs_absolute_forces(tmp_path):
    log = tmp_path / "log.csv"
    pd.DataFrame(np.column_stack([[0.0, 0.01], W_LC]),
                 columns=["time", "Fx", "Fy", "Fz", "Mx", "My", "Mz"]).to_csv(log, index=False)
    res = CliRunner().invoke(phri, ["simulate", str(REPO / "configs" /
                                                    "harmony_upper_arm.yaml"), str(log), "-o",
                                    str(tmp_path / "o.csv"), "--uncertainty", "5",
                                    "--baseline", "zero"])
    assert res.exit_code == 2 and one_line(res.stderr) and "--baseline" in res.stderr
    assert not (tmp_path / "o.csv").exists()


def test_bands_figure():
    from phri_spring.reports.uncertainty.figures import bands_figure

    meas = np.zeros((3, 4))
    P = np.sort(np.random.default_rng(0).normal(size=(3, 3, 4)), axis=0)
    fig = bands_figure(meas, {"compliant": P, "rigid": P + 1}, conditions=["base", "L1", "L2"],
                       labels=["A0", "A1", "B0", "B1"], baseline_index=0, title="t")
    axes = fig.get_axes()
    assert len(axes) == 2 and [a.get_title(loc="left") for a in axes] == ["L1", "L2"]
    assert axes[0].get_ylabel() == "zeroed load [N]"


def _long_log(m, seed=0):
    rng = np.random.default_rng(seed)
    w = rng.normal(0.0, 1.0, (m, 6)) * [3, 3, 8, 0.2, 0.2, 0.2] + [0, 0, 20, 0, 0, 0]
    return np.arange(m) * 0.01, w


def test_streamed_blocks_are_the_array_percentiles(linear_case):
    # the log read in chunks of odd sizes (none a block): the same percentiles to the bit as
    # the whole log at once (block boundaries and noise streams do not depend on the reading)
    from phri_spring.workflows.uncertainty.run import MonteCarloStream

    _, cfg, inputs = linear_case
    time, w = _long_log(3000)
    whole = monte_carlo(cfg, w, draws=300, seed=4, inputs=inputs)
    mc = MonteCarloStream(cfg, draws=300, seed=4, inputs=inputs)
    assert 2 * mc.block_samples < 3000                          # several blocks
    edges = [0, 7, 700, 701, 1999, 2900, 3000]
    chunks = ((time[a:b], w[a:b]) for a, b in zip(edges[:-1], edges[1:]))
    got = list(mc.blocks(chunks))
    assert [len(t) for t, _, _ in got][:-1] == [mc.block_samples] * (len(got) - 1)
    np.testing.assert_array_equal(np.concatenate([t for t, _, _ in got]), time)
    np.testing.assert_array_equal(np.concatenate([f for _, f, _ in got], axis=1), whole.forces)
    np.testing.assert_array_equal(np.concatenate([r for _, _, r in got], axis=1),
                                  whole.pain_ratio)


@pytest.mark.parametrize("fmt", ["parquet", "csv"])
def test_simulate_uncertainty_streams_the_log(tmp_path, linear_case, fmt):
    # phri simulate --uncertainty writes block by block: the table holds the array
    # percentiles (Parquet: every bit; CSV: to its 1e-6 N decimals), in write_monte_carlo's
    # columns
    from phri_spring.workflows.uncertainty.run import simulate_uncertainty_file, write_monte_carlo

    d, cfg, inputs = linear_case
    cfg_path = tmp_path / "c.yaml"
    cfg_path.write_text(yaml.safe_dump(d))
    time, w = _long_log(2300, seed=1)
    log = tmp_path / f"log.{fmt}"
    frame = pd.DataFrame(np.column_stack([time, w]),
                         columns=["time", "Fx", "Fy", "Fz", "Mx", "My", "Mz"])
    frame.to_parquet(log) if fmt == "parquet" else frame.to_csv(log, index=False)
    sd = f"tension={T_SD},force={NOISE[0]},moment={NOISE[3]},tissue=0"
    run = simulate_uncertainty_file(cfg_path, log, tmp_path / f"mc.{fmt}", draws=120, seed=8,
                                    sd=sd)
    assert run.samples == 2300 and run.draws == 120 and run.not_converged == 0
    line = run.summary_line()
    assert "2,300 samples x 21 elements" in line and "120 Monte Carlo draws, seed 8" in line
    assert "95th percentile of peak pressure up to" in line and "\n" not in line
    ref_res = monte_carlo(load_config(cfg_path), pd.read_parquet(log).to_numpy()[:, 1:]
                          if fmt == "parquet" else pd.read_csv(log).to_numpy()[:, 1:],
                          draws=120, seed=8, inputs=uncertain_inputs(load_config(cfg_path),
                                                                     **parse_sd(sd)))
    write_monte_carlo(ref_res, pd.read_csv(log)["time"] if fmt == "csv" else
                      pd.read_parquet(log)["time"], tmp_path / f"ref.{fmt}")
    read = pd.read_parquet if fmt == "parquet" else pd.read_csv
    got, want = read(tmp_path / f"mc.{fmt}"), read(tmp_path / f"ref.{fmt}")
    assert list(got.columns) == list(want.columns)
    if fmt == "parquet":
        np.testing.assert_array_equal(got.to_numpy(), want.to_numpy())
        ratio = got["peak_pressure_to_pain_threshold_p95"]
        assert run.max_pain_ratio_p95 == ratio.max()                # the summary line's peak
        assert run.max_pain_ratio_time == got["time"][ratio.idxmax()]
    else:
        np.testing.assert_allclose(got.to_numpy(), want.to_numpy(), rtol=0, atol=1.0001e-6)


def test_simulate_uncertainty_bad_value_mid_log_leaves_nothing(tmp_path, monkeypatch):
    # the log is streamed: a bad cell far into it (after blocks were already written to the
    # temporary table) still ends in one line naming it, and nothing is left behind
    from phri_spring.io import logs

    written = []
    write = logs.ForcesWriter.write
    monkeypatch.setattr(logs.ForcesWriter, "write",
                        lambda self, *a: (written.append(len(a[0])), write(self, *a))[1])
    time, w = _long_log(60000, seed=2)
    frame = pd.DataFrame(np.column_stack([time, w]),
                         columns=["time", "Fx", "Fy", "Fz", "Mx", "My", "Mz"]).astype(object)
    frame.iloc[59000, 3] = "n/a?"
    log = tmp_path / "log.csv"
    frame.to_csv(log, index=False)
    out = tmp_path / "out"
    out.mkdir()
    res = CliRunner().invoke(phri, ["simulate", str(load_config_path()), str(log), "-o",
                                    str(out / "mc.csv"), "--uncertainty", "40"])
    assert res.exit_code == 1 and one_line(res.stderr), res.stderr
    assert "Fz" in res.stderr and "line 59002" in res.stderr
    assert written, "no block was written before the bad cell was read"
    assert list(out.iterdir()) == []


def load_config_path():
    return REPO / "configs" / "harmony_upper_arm.yaml"
