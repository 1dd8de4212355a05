"""``phri fit-stiffness --law qlv``: quasi-linear viscoelastic tissue from indenter trials.

References are independent of the fit: the model force of a trial is checked against the
O(m^2) hereditary integral of ``tests/support/reference_qlv.py`` and against the closed
form of a ramp written out here; the synthetic trials compute the force in closed form over
the depth path (:mod:`phri_spring.synthetic.indenter_qlv`), not with the recursion the fit
uses; recovered parameters are compared with the ones the trials were made with.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from phri_spring.errors import DataError, UsageError
from phri_spring.physics.indentation.qlv import (ELASTIC_LAWS, elastic_force, fit_qlv,
                                                 memory_terms, qlv_force)
from phri_spring.physics.indentation.qlv_window import (HOLD_MIN_S, check_identifiable,
                                                        qlv_window)
from phri_spring.physics.indentation.signal import TrialError
from phri_spring.physics.history.relaxation import Prony
from phri_spring.synthetic.indenter import write_trials
from phri_spring.synthetic.indenter_qlv import (qlv_path_force, ramp_hold_path,
                                                synth_qlv_trial)

from support.helpers import REPO, assert_one_line_error, run_phri, stderr_of
from support.reference_qlv import hereditary_force

EXAMPLE = REPO / "examples" / "indenter_qlv"
#: what examples/make_indenter_qlv_data.py made the example with
EXAMPLE_K = {"B2": 4100.0, "B3": 4300.0, "B4": 3900.0}
EXAMPLE_G, EXAMPLE_TAU = (0.30, 0.20), (0.4, 5.0)


def fit_trials(trials, terms, elastic="linear"):
    windows = [qlv_window(tr.time, tr.displacement, tr.force) for tr in trials]
    check_identifiable(windows)
    return fit_qlv(windows, terms=terms, elastic=elastic)


# --------------------------------------------------------------------------- the model


@settings(max_examples=15, deadline=None)
@given(st.data())
def test_model_force_is_the_hereditary_integral(data):
    """Irregular sampling, a long gap (the recursion's blocks), any elastic history."""
    rng = np.random.default_rng(data.draw(st.integers(0, 2 ** 31)))
    m = 60
    dt = rng.uniform(0.005, 0.05, m - 1)
    dt[m // 2] = data.draw(st.floats(0.5, 30.0))           # a rest of many tau
    t = np.concatenate([[0.0], np.cumsum(dt)])
    depth = np.cumsum(rng.normal(0.0, 2e-4, m)) + 1e-3
    tau = np.sort(rng.uniform(0.01, 3.0, 2))
    prony = Prony(rng.uniform(0.0, 0.45, 2), tau)
    beta = data.draw(st.sampled_from([0.0, 250.0]))
    fe = elastic_force(depth, 3000.0, beta)
    np.testing.assert_allclose(qlv_force(t, depth, 3000.0, prony, beta),
                               hereditary_force(prony, t, fe), rtol=1e-9, atol=1e-9)


def test_model_force_of_a_ramp_is_the_closed_form():
    """Linear law, ramp d = v t from rest: F = k v (G_inf t + sum g tau (1 - exp(-t/tau))),
    then held: F = k v (G_inf T + sum g tau (exp(-(t-T)/tau) - exp(-t/tau)))."""
    k, v, T = 4000.0, 4e-3, 1.0
    g, tau = np.array([0.3, 0.2]), np.array([0.4, 5.0])
    t = np.linspace(0.0, 6.0, 601)
    d = v * np.minimum(t, T)
    ramp = k * v * ((1 - g.sum()) * t + (g * tau * -np.expm1(-t[:, None] / tau)).sum(1))
    held = k * v * ((1 - g.sum()) * T + (g * tau * (np.exp(-(t[:, None] - T) / tau)
                                                   - np.exp(-t[:, None] / tau))).sum(1))
    ref = np.where(t <= T, ramp, held)
    np.testing.assert_allclose(qlv_force(t, d, k, Prony(g, tau)), ref, rtol=1e-10, atol=1e-10)
    kt, kd = ramp_hold_path(v * T, T, 5.0, 0.0, release=False)
    np.testing.assert_allclose(qlv_path_force(t, kt, kd, k, g, tau), ref, rtol=1e-10,
                               atol=1e-10)


def test_memory_terms_of_a_step_after_a_long_rest():
    """A step of F^e at t_1 after 1e4 tau of nothing: h = b exp(-(t - t_1)/tau) dF^e with
    b = tau/dt (1 - exp(-dt/tau)) (F^e linear over the step), no overflow on the way."""
    tau = 0.01
    t = np.concatenate([[0.0, 100.0], 100.0 + np.arange(1, 2001) * 1e-3])
    fe = np.concatenate([[0.0], np.ones(t.size - 1)])
    h = memory_terms(t, fe, [tau])[:, 0]
    b = tau / 100.0 * -np.expm1(-100.0 / tau)
    np.testing.assert_allclose(h, np.concatenate([[0.0], b * np.exp(-(t[1:] - 100.0) / tau)]),
                               rtol=1e-10, atol=1e-300)


# --------------------------------------------------------------------------- recovery


@pytest.mark.parametrize("elastic, beta, g, tau", [
    ("linear", 0.0, [0.4], [2.0]),
    ("linear", 0.0, [0.3, 0.2], [0.5, 6.0]),
    ("exponential", 300.0, [0.35], [1.0]),
    ("exponential", 300.0, [0.3, 0.2], [0.5, 6.0]),
])
def test_clean_trials_recover_the_parameters(elastic, beta, g, tau):
    tr = synth_qlv_trial(4000.0, g, tau, stiffening=beta)
    fit = fit_trials([tr], len(g), elastic)
    assert fit.status == "ok", fit.message
    np.testing.assert_allclose(fit.times_s, tau, rtol=0.05)
    np.testing.assert_allclose(fit.fractions, g, atol=0.02)
    assert fit.stiffness == pytest.approx(4000.0, rel=0.01)
    assert fit.stiffening == pytest.approx(beta, rel=0.05, abs=1e-6)
    assert fit.r2_min > 0.9999


@pytest.mark.parametrize("elastic, beta", [("linear", 0.0), ("exponential", 250.0)])
def test_noisy_trials_recover_the_parameters(elastic, beta):
    """0.5 % noise, sensor offset, 0.025 mm encoder steps, two trials at one location."""
    g, tau = [0.3, 0.2], [0.4, 5.0]
    trials = [synth_qlv_trial(4200.0, g, tau, stiffening=beta, noise=0.005, offset=0.2 * s,
                              encoder=True, seed=s, trial=s + 1) for s in range(2)]
    fit = fit_trials(trials, 2, elastic)
    assert fit.status == "ok", fit.message
    np.testing.assert_allclose(fit.times_s, tau, rtol=0.15)
    np.testing.assert_allclose(fit.fractions, g, atol=0.03)
    assert fit.stiffness == pytest.approx(4200.0, rel=0.03)
    if beta:
        assert fit.stiffening == pytest.approx(beta, rel=0.25)
    assert fit.r2_min > 0.99


@st.composite
def prony_series(draw):
    n = draw(st.integers(1, 2))
    tau = [draw(st.floats(0.05, 10.0 / 5.0 ** (n - 1)))]
    if n == 2:
        tau.append(draw(st.floats(5.0 * tau[0], 10.0)))
    g = [draw(st.floats(0.05, 0.4)) for _ in range(n)]
    return np.array(g), np.array(tau)


@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(prony_series(), st.sampled_from(["linear", "exponential"]))
def test_recovery_on_drawn_relaxation(series, elastic):
    """tau in 0.05..10 s, g_i >= 0.05 with sum <= 0.8, terms >= 5x apart, clean trials."""
    g, tau = series
    beta = 200.0 if elastic == "exponential" else 0.0
    fit = fit_trials([synth_qlv_trial(3500.0, g, tau, stiffening=beta)], len(g), elastic)
    np.testing.assert_allclose(fit.times_s, tau, rtol=0.05)
    np.testing.assert_allclose(fit.fractions, g, atol=0.02)
    assert fit.stiffness == pytest.approx(3500.0, rel=0.02)


def test_two_ramp_rates_without_a_hold_identify_the_relaxation():
    """Ramp and release at once, 0.5 s and 3 s ramps: no hold, two rates 6x apart."""
    g, tau = [0.4], [1.0]
    trials = [synth_qlv_trial(4000.0, g, tau, ramp_s=r, hold_s=0.0, trial=i + 1)
              for i, r in enumerate((0.5, 3.0))]
    windows = [qlv_window(tr.time, tr.displacement, tr.force) for tr in trials]
    assert max(w.hold_s for w in windows) < HOLD_MIN_S
    fit = fit_trials(trials, 1)
    np.testing.assert_allclose(fit.times_s, tau, rtol=0.05)
    np.testing.assert_allclose(fit.fractions, g, atol=0.02)


def test_a_record_that_ends_in_the_hold_is_fitted_to_its_end():
    tr = synth_qlv_trial(4000.0, [0.4], [2.0], release=False)
    w = qlv_window(tr.time, tr.displacement, tr.force)
    assert w.time[-1] == pytest.approx(tr.time[-1])
    fit = fit_qlv([w], terms=1)
    assert fit.times_s[0] == pytest.approx(2.0, rel=0.05)


def test_one_rate_without_a_hold_is_not_identifiable():
    tr = synth_qlv_trial(4000.0, [0.4], [1.0], hold_s=0.0)
    with pytest.raises(TrialError, match="hold"):
        fit_trials([tr], 1)


def test_elastic_parts_of_the_registry_are_those_of_the_fit():
    from phri_spring.workflows.fit.laws import ELASTIC_PARTS, FIT_LAWS

    assert tuple(ELASTIC_PARTS) == tuple(ELASTIC_LAWS)
    assert "qlv" in FIT_LAWS


# --------------------------------------------------------------------------- command line


def test_cli_fits_the_example_and_prints_a_config_relaxation(tmp_path):
    out, per_trial, figs = tmp_path / "qlv.csv", tmp_path / "trials.csv", tmp_path / "figs"
    res = run_phri("fit-stiffness", EXAMPLE, "-o", out, "--law", "qlv", "--trials-csv",
                   per_trial, "--plots", figs)
    assert res.exit_code == 0, stderr_of(res)
    line = res.stdout.strip().splitlines()[-1]
    assert line.startswith("qlv law over 3 locations: k ")
    assert " N/m" in line and " s" in line
    snippet = yaml.safe_load(line[line.index("tissue.relaxation:"):])["tissue.relaxation"]
    prony = Prony(snippet["fractions"], snippet["times_s"])
    np.testing.assert_allclose(prony.tau, EXAMPLE_TAU, rtol=0.1)
    np.testing.assert_allclose(prony.g, EXAMPLE_G, atol=0.02)
    table = pd.read_csv(out).set_index("location")
    assert list(table.columns[:5]) == ["row", "angle_index", "stiffness_N_per_m",
                                       "std_N_per_m", "n_trials"]
    for i in (1, 2):
        assert {f"relaxation_fraction_{i}", f"relaxation_time_{i}_s"} <= set(table.columns)
    for lab, k in EXAMPLE_K.items():
        assert table.loc[lab, "stiffness_N_per_m"] == pytest.approx(k, rel=0.02)
        assert table.loc[lab, "relaxation_time_2_s"] == pytest.approx(EXAMPLE_TAU[1], rel=0.1)
    assert len(pd.read_csv(per_trial)) == 3
    assert sorted(p.name for p in figs.iterdir()) == ["force_time.png", "stiffness_map.png"]


def test_cli_exponential_part_and_one_term(tmp_path):
    folder = tmp_path / "in"
    trials = [synth_qlv_trial(4000.0, [0.35], [1.0], stiffening=300.0, location=lab,
                              noise=0.002, seed=i) for i, lab in enumerate(("A0", "A1"))]
    write_trials(trials, folder, time_decimals=3, force_decimals=5, displacement_decimals=6)
    out = tmp_path / "qlv.csv"
    res = run_phri("fit-stiffness", folder, "-o", out, "--law", "qlv", "--elastic",
                   "exponential", "--relaxation-terms", "1")
    assert res.exit_code == 0, stderr_of(res)
    table = pd.read_csv(out)
    assert "stiffening_per_m" in table.columns and "relaxation_time_2_s" not in table.columns
    np.testing.assert_allclose(table["stiffening_per_m"], 300.0, rtol=0.1)
    np.testing.assert_allclose(table["relaxation_time_1_s"], 1.0, rtol=0.05)
    assert "stiffening" in res.stdout and "1/m" in res.stdout


def test_cli_lists_the_registered_laws():
    res = run_phri("fit-stiffness", "--help")
    assert res.exit_code == 0
    assert "[linear|exponential|qlv]" in res.stdout
    res = run_phri("fit-stiffness", EXAMPLE, "-o", "x.csv", "--law", "qvl")
    assert_one_line_error(res, "--law", "qvl", "qlv", code=2)


@pytest.mark.parametrize("args, needle", [
    (["--elastic", "exponential"], "--elastic"),
    (["--relaxation-terms", "3"], "--relaxation-terms"),
    (["--law", "exponential", "--elastic", "linear"], "--elastic"),
    (["--law", "qlv", "--max-trial-spread", "0.2"], "--max-trial-spread"),
    (["--law", "qlv", "--relaxation-terms", "9"], "--relaxation-terms"),
])
def test_cli_refuses_options_that_do_not_apply(args, needle, tmp_path):
    out = tmp_path / "x.csv"
    res = run_phri("fit-stiffness", EXAMPLE, "-o", out, *args)
    assert_one_line_error(res, needle, code=2)
    assert not out.exists()


def test_library_refuses_qlv_options_with_another_law():
    from phri_spring.workflows.fit.stiffness import fit_stiffness

    with pytest.raises(UsageError) as err:
        fit_stiffness(EXAMPLE, law="linear", relaxation_terms=2)
    assert err.value.key == "relaxation_terms"


def _write(folder, name, df):
    folder.mkdir(exist_ok=True)
    df.to_csv(folder / name, index=False)
    return folder


def _frame(tr):
    return pd.DataFrame({"time": tr.time, "displacement": tr.displacement * 1e3,
                         "force": tr.force})


def test_cli_bad_trials_are_one_line_data_errors(tmp_path):
    ok = _frame(synth_qlv_trial(4000.0, [0.4], [1.0]))
    no_time = _write(tmp_path / "a", "B3_1.csv", ok.drop(columns="time"))
    res = run_phri("fit-stiffness", no_time, "-o", tmp_path / "o.csv", "--law", "qlv")
    assert_one_line_error(res, "B3_1.csv", "time", code=1)

    back = ok.copy()
    back.loc[700, "time"] = back.loc[698, "time"]
    folder = _write(tmp_path / "b", "B3_1.csv", back)
    res = run_phri("fit-stiffness", folder, "-o", tmp_path / "o.csv", "--law", "qlv")
    assert_one_line_error(res, "B3_1.csv", "time", "increasing", code=1)

    flat = _frame(synth_qlv_trial(4000.0, [0.4], [1.0], hold_s=0.0))
    folder = _write(tmp_path / "c", "B3_1.csv", flat)
    res = run_phri("fit-stiffness", folder, "-o", tmp_path / "o.csv", "--law", "qlv")
    assert_one_line_error(res, "B3_1.csv", "location B3", "hold", "loading rate", code=1)
    assert not (tmp_path / "o.csv").exists()


def test_skip_bad_trials_leaves_an_unidentifiable_location_out(tmp_path):
    folder = tmp_path / "in"
    write_trials([synth_qlv_trial(4000.0, [0.4], [1.0], location="A0"),
                  synth_qlv_trial(4000.0, [0.4], [1.0], hold_s=0.0, location="A1")], folder,
                 force_decimals=5, displacement_decimals=6)
    from phri_spring.workflows.fit.stiffness import fit_stiffness

    with pytest.raises(DataError, match="A1_1.csv"):
        fit_stiffness(folder, law="qlv", relaxation_terms=1)
    result = fit_stiffness(folder, law="qlv", relaxation_terms=1, skip_bad_trials=True)
    assert result.labels == ["A0"]
    assert any("A1" in w and "hold" in w for w in result.warnings)


def test_force_time_figure_has_a_panel_per_location():
    from matplotlib.figure import Figure

    from phri_spring.physics.indentation.qlv import QlvLocationFit
    from phri_spring.reports.indenter_qlv_figures import force_time_grid

    locs = []
    for lab in ("A0", "A1", "A2"):
        tr = synth_qlv_trial(4000.0, [0.4], [1.0], hold_s=3.0)
        w = qlv_window(tr.time, tr.displacement, tr.force)
        locs.append(QlvLocationFit(lab, np.array([1]), (w,), fit_qlv([w], terms=1)))
    fig = force_time_grid(locs)
    assert isinstance(fig, Figure)
    panels = [ax for ax in fig.axes if ax.lines]
    assert len(panels) == 3
    assert all(len(ax.lines) == 2 for ax in panels)              # data and fit


def test_the_example_is_what_its_script_makes(tmp_path):
    """The committed trials come from examples/make_indenter_qlv_data.py with its seed, and the
    truth this file checks the fit against is the script's."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "make_qlv", REPO / "examples" / "make_indenter_qlv_data.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    assert script.STIFFNESS == EXAMPLE_K
    assert (script.FRACTIONS, script.TIMES_S) == (EXAMPLE_G, EXAMPLE_TAU)
    script.main(tmp_path)
    committed = sorted(p.name for p in EXAMPLE.glob("*.csv"))
    assert committed == sorted(p.name for p in tmp_path.glob("*.csv")) == \
        ["B2_1.csv", "B3_1.csv", "B4_1.csv"]
    for name in committed:
        a, b = pd.read_csv(EXAMPLE / name), pd.read_csv(tmp_path / name)
        assert list(a.columns) == list(b.columns) and len(a) == len(b)
        np.testing.assert_allclose(a.to_numpy(), b.to_numpy(), rtol=0, atol=2e-4)
