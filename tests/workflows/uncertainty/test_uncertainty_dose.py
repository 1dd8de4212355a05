"""``phri simulate --uncertainty`` with a tolerance curve: the dose percentiles over the draws.

Reference: a constant wrench gives every draw constant pressures, so without scatter each
dose is t / t_allowed(p), t_allowed read off the published points of Linder-Ganz et al.
(32 kPa for 1 h, 9 kPa for 2 h and after, linear in log time between; docs/tolerance.md).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from phri_cli.main import phri
from phri_spring.io.config import config_from_dict
from phri_spring.workflows.uncertainty.run import (DOSE_COLUMNS, MonteCarloStream,
                                                   UncertainInputs, dose_percentiles)
from support.helpers import harmony_dict

WRENCH = [2.0, -3.0, 40.0, 0.5, -0.2, 0.3]
TIMES = np.arange(6) * 600.0


def linder_ganz_allowed_s(p_kpa: float) -> float:
    """Hand-worked: the allowed time [s] at a pressure between 9 and 32 kPa."""
    assert 9.0 < p_kpa < 32.0
    share = (32.0 - p_kpa) / (32.0 - 9.0)
    return math.exp(math.log(3600.0) + share * math.log(7200.0 / 3600.0))


@pytest.fixture()
def case(tmp_path):
    d = harmony_dict()
    d["strap"]["tension"] = 30.0
    d["tolerance"] = {"curve": "linder_ganz_2006"}
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump(d))
    log = tmp_path / "log.csv"
    pd.DataFrame(np.column_stack([TIMES, np.tile(WRENCH, (len(TIMES), 1))]),
                 columns=["time", "Fx", "Fy", "Fz", "Mx", "My", "Mz"]).to_csv(log, index=False)
    return d, cfg, log


def simulate(cfg, log, out, *options):
    """``phri simulate CFG LOG -o OUT OPTIONS``, its exit checked."""
    res = CliRunner().invoke(phri, ["simulate", str(cfg), str(log), "-o", str(out), *options])
    assert res.exit_code == 0, res.output
    return res


def without_curve(case):
    """The case's config rewritten without its tolerance section; (config, log)."""
    d, cfg, log = case
    d.pop("tolerance")
    cfg.write_text(yaml.safe_dump(d))
    return cfg, log


def test_config_curve_gives_the_dose_percentiles(tmp_path, case):
    # the config's tolerance section is no longer ignored by --uncertainty: without scatter
    # every draw is the nominal run, and its dose is t / t_allowed(peak pressure)
    _, cfg, log = case
    plain = tmp_path / "plain.csv"
    simulate(cfg, log, plain, "-q")
    peak = pd.read_csv(plain)["peak_pressure_kPa"].to_numpy()
    assert np.ptp(peak) < 1e-9 * peak[0]                        # a constant pressure
    out = tmp_path / "mc.csv"
    res = simulate(cfg, log, out, "--uncertainty", "5", "--uncertainty-sd", "tissue=0")
    t = pd.read_csv(out)
    assert list(t.columns[-3:]) == list(DOSE_COLUMNS)
    expected = TIMES / linder_ganz_allowed_s(peak[0])
    assert expected[-1] > 0.3                                    # a dose well away from 0
    for col in DOSE_COLUMNS:
        np.testing.assert_allclose(t[col].to_numpy(), expected, rtol=1e-5, atol=1e-6)
    assert "dose (linder_ganz_2006)" in res.output
    assert f"p95 {expected[-1]:.3g}" in res.output


def test_tolerance_option_with_scatter(tmp_path, case):
    # --tolerance with --uncertainty runs (it was refused): with load-cell noise the
    # percentiles are ordered, never go down and start at 0 (the first sample weighs no step)
    cfg, log = without_curve(case)
    out = tmp_path / "mc.parquet"
    simulate(cfg, log, out, "-q", "--uncertainty", "40", "--uncertainty-sd", "tissue=0,force=3",
             "--tolerance", "linder_ganz_2006")
    dose = pd.read_parquet(out)[list(DOSE_COLUMNS)].to_numpy()
    assert np.all(dose[0] == 0.0)
    assert np.all(np.diff(dose, axis=0) >= 0.0)
    assert np.all(dose[:, 0] <= dose[:, 1]) and np.all(dose[:, 1] <= dose[:, 2])
    assert dose[-1, 2] > dose[-1, 0]                             # the noise spreads the dose


def test_without_a_curve_no_dose_columns(tmp_path, case):
    cfg, log = without_curve(case)
    out = tmp_path / "mc.csv"
    simulate(cfg, log, out, "-q", "--uncertainty", "3")
    assert not any(c.startswith("dose") for c in pd.read_csv(out).columns)


def test_the_dose_goes_on_across_blocks(case):
    # each draw's dose is carried from block to block: blocks of 2 samples give the dose of
    # one block holding the whole log (no noise: the draws do not depend on the blocks)
    d, _, _ = case
    cfg = config_from_dict(d)
    w = np.tile(WRENCH, (len(TIMES), 1))
    noiseless = UncertainInputs(np.zeros(cfg.n_elements), 0.0, 0.0, 0.0)
    a = MonteCarloStream(cfg, draws=2, inputs=noiseless, tolerance="linder_ganz_2006")
    a.block(0, w, TIMES)
    b = MonteCarloStream(cfg, draws=2, inputs=noiseless, tolerance="linder_ganz_2006")
    b.block_samples = 2
    parts = np.concatenate([b.dose for _ in b.blocks([(TIMES, w)])], axis=1)
    np.testing.assert_allclose(parts, a.dose, rtol=1e-12)
    assert parts[1, -1] > 0.3


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 1e3), min_size=2, max_size=12))
def test_dose_percentiles_are_numpy_percentiles_when_finite(values):
    x = np.array(values)[:, None]
    q = [5, 50, 95]
    np.testing.assert_allclose(dose_percentiles(x, q), np.percentile(x, q, axis=0),
                               rtol=1e-12, atol=1e-12)


def test_dose_percentiles_of_infinite_doses():
    # a time-independent curve: doses are 0 or infinite; two infinite neighbours stay infinite
    x = np.array([[0.0, 0.0], [np.inf, 0.0], [np.inf, np.inf]])
    got = dose_percentiles(x, [5, 50, 95])
    assert got[0, 0] == np.inf and got[1, 0] == np.inf and got[2, 0] == np.inf
    assert got[0, 1] == 0.0 and got[1, 1] == 0.0 and got[2, 1] == np.inf
