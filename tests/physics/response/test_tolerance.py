"""Tolerance curves and the dose of a log (docs/tolerance.md).

The expected doses and times above a threshold are recomputed here with plain loops
from the curves' published points (their own piecewise log-time rule, written out
again), never from the code under test.
"""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from support.helpers import HARMONY_CONFIG, assert_one_line_error, harmony_dict, run_phri
from phri_spring.physics.response.tolerance import (MMHG_KPA, TOLERANCE_CURVES, Exposure,
                                           ToleranceCurve, tolerance_curve)

LABELS = [f"{r}{j}" for r in "ABC" for j in range(7)]
EXTRAS = ["contacts_in_touch", "peak_pressure_kPa", "peak_pressure_element",
          "peak_pressure_to_pain_threshold", "solver_iterations", "converged"]


# --------------------------------------------------------------------------- reference
def ref_allowed(times, limits, p):
    """t_allowed [s] at pressure p [kPa] from a curve's points, one segment at a time."""
    if math.isnan(p):
        return math.nan
    if times[0] == 0:                         # a time-independent limit
        return 0.0 if p >= limits[0] else math.inf
    if p < limits[-1]:
        return math.inf
    if p >= limits[0]:
        return times[0]
    for i in range(len(times) - 1):
        hi, lo = limits[i], limits[i + 1]
        if hi > lo and hi >= p >= lo:
            frac = (hi - p) / (hi - lo)
            return math.exp(math.log(times[i]) + frac * (math.log(times[i + 1])
                                                        - math.log(times[i])))
    raise AssertionError("unreachable")


def ref_exposure(times, limits, t, P, pain):
    """Plain loops over samples and elements: per-sample cumulative doses (m, n), time
    above the pain threshold and the curve's floor (n,), first times (n,)."""
    m, n = P.shape
    dose = [0.0] * n
    above_pain, above_floor = [0.0] * n, [0.0] * n
    first_pain, first_dose = [math.nan] * n, [math.nan] * n
    out = np.zeros((m, n))
    for k in range(m):
        dt = 0.0 if k == 0 else t[k] - t[k - 1]
        if not dt > 0:
            dt = 0.0
        for e in range(n):
            p = P[k, e]
            if not math.isnan(p):
                if p > pain:
                    above_pain[e] += dt
                    if math.isnan(first_pain[e]):
                        first_pain[e] = t[k]
                if p > limits[-1]:
                    above_floor[e] += dt
                ta = ref_allowed(times, limits, p)
                if ta == 0.0:
                    if dt > 0:
                        dose[e] = math.inf
                elif ta != math.inf:
                    dose[e] += dt / ta
            if dose[e] >= 1.0 and math.isnan(first_dose[e]):
                first_dose[e] = t[k]
            out[k, e] = dose[e]
    return out, np.array(above_pain), np.array(above_floor), np.array(first_pain), \
        np.array(first_dose)


def feed(exposure, t, P, cuts):
    """Feed ``exposure`` the log split at ``cuts``; the per-sample dose_max and element."""
    dmax, didx = [], []
    for a, b in zip([0, *cuts], [*cuts, len(t)]):
        d, i = exposure.add(t[a:b], P[a:b])
        dmax.append(d)
        didx.append(i)
    return np.concatenate(dmax), np.concatenate(didx)


def random_case(rng, m, n, pmax):
    t = np.cumsum(rng.choice([0.0, 0.5, 1.0, 7.0, 60.0, 600.0, -3.0], size=m)) + 10.0
    P = rng.uniform(0.0, pmax, size=(m, n))
    P[rng.random((m, n)) < 0.05] = np.nan           # samples that did not converge
    cuts = sorted(set(rng.integers(1, m, size=rng.integers(0, 5)).tolist()))
    return t, P, cuts


# --------------------------------------------------------------------------- the dose
@pytest.mark.parametrize("name", sorted(TOLERANCE_CURVES))
def test_dose_and_times_match_plain_loops_across_chunks(name):
    curve = TOLERANCE_CURVES[name]
    rng = np.random.default_rng(abs(hash(name)) % 2**32)
    pmax = 1.3 * max(curve.limits_kpa[0], 30.0)
    for _ in range(3):
        t, P, cuts = random_case(rng, 120, 4, pmax)
        ex = Exposure(name, 4, pain_threshold_kpa=0.6 * pmax)
        dmax, didx = feed(ex, t, P, cuts)
        cum, ap, af, fp, fd = ref_exposure(curve.times_s, curve.limits_kpa, t, P, 0.6 * pmax)
        np.testing.assert_allclose(dmax, cum.max(axis=1), rtol=1e-9)
        finite = np.isfinite(cum.max(axis=1))
        # the element of the largest dose, where it is not a tie
        ties = (cum == cum.max(axis=1, keepdims=True)).sum(axis=1) > 1
        ok = finite & ~ties
        np.testing.assert_array_equal(didx[ok], np.argmax(cum, axis=1)[ok])
        np.testing.assert_allclose(ex.dose, cum[-1], rtol=1e-9)
        np.testing.assert_allclose(ex.time_above_pain_s, ap, rtol=1e-12)
        np.testing.assert_allclose(ex.time_above_floor_s, af, rtol=1e-12)
        np.testing.assert_array_equal(ex.pain_first_s, fp)
        # a dose within rounding of 1 may cross one sample apart: compare away from it
        near = np.any(np.abs(cum - 1.0) < 1e-9, axis=0)
        np.testing.assert_array_equal(ex.dose_reached_s[~near], fd[~near])


@pytest.mark.parametrize("name", sorted(TOLERANCE_CURVES))
def test_sample_by_sample_matches_plain_loops(name):
    curve = TOLERANCE_CURVES[name]
    rng = np.random.default_rng(abs(hash(name + "1")) % 2**32)
    pmax = 1.3 * max(curve.limits_kpa[0], 30.0)
    t, P, _ = random_case(rng, 80, 4, pmax)
    ex = Exposure(name, 4, pain_threshold_kpa=0.6 * pmax)
    got = np.array([ex.add_sample(t[k], P[k])[0] for k in range(len(t))])
    cum, ap, af, fp, fd = ref_exposure(curve.times_s, curve.limits_kpa, t, P, 0.6 * pmax)
    np.testing.assert_allclose(got, cum.max(axis=1), rtol=1e-9)
    np.testing.assert_allclose(ex.dose, cum[-1], rtol=1e-9)
    np.testing.assert_allclose(ex.time_above_pain_s, ap, rtol=1e-12)
    np.testing.assert_allclose(ex.time_above_floor_s, af, rtol=1e-12)
    np.testing.assert_array_equal(ex.pain_first_s, fp)


def test_held_exactly_the_allowed_time_gives_dose_one():
    # Linder-Ganz: 40 kPa is above the 32 kPa plateau: 15 min; 20.5 kPa is halfway from
    # 32 to 9 kPa, i.e. halfway from 1 h to 2 h in log time: sqrt(3600 * 7200) s
    for name, p, allowed in (("linder_ganz_2006", 40.0, 900.0),
                             ("linder_ganz_2006", 20.5, math.sqrt(3600.0 * 7200.0)),
                             ("reswick_rogers_1976", 250 * MMHG_KPA, 7200.0)):
        n = 1000
        t = np.linspace(0.0, allowed, n + 1)
        ex = Exposure(name, 1, 120.0)
        dose, _ = ex.add(t, np.full((n + 1, 1), p))
        assert dose[-1] == pytest.approx(1.0, rel=1e-3), name
        assert dose[n // 2] == pytest.approx(0.5, rel=1e-3), name


def test_below_the_floor_no_dose_and_time_independent_limits():
    ex = Exposure("linder_ganz_2006", 2, 120.0)
    t = np.arange(0.0, 36000.0, 10.0)
    ex.add(t, np.column_stack([np.full(len(t), 8.99), np.full(len(t), 9.01)]))
    assert ex.dose[0] == 0.0 and ex.time_above_floor_s[0] == 0.0
    assert ex.dose[1] > 1.0 and ex.time_above_floor_s[1] == pytest.approx(t[-1])
    # a threshold without time: the dose is infinite from the first step at or above it
    ex = Exposure("cuff_calf_pain_2001", 1, 120.0)
    d, _ = ex.add([0.0, 1.0, 2.0], [[30.0], [25.0], [26.0]])
    assert d[0] == 0.0 and d[1] == 0.0 and d[2] == math.inf
    assert ex.dose_reached_s[0] == 2.0


def test_registry_holds_the_published_values():
    lg = TOLERANCE_CURVES["linder_ganz_2006"]
    assert lg.limit_kpa(1800.0) == pytest.approx(32.0)
    assert lg.limit_kpa(3 * 3600.0) == pytest.approx(9.0)
    assert TOLERANCE_CURVES["cuff_calf_pain_2001"].floor_kpa == 26.0
    assert TOLERANCE_CURVES["cuff_knee_pain_2020"].floor_kpa == 52.9
    assert TOLERANCE_CURVES["cuff_knee_discomfort_2020"].floor_kpa == 13.7
    assert TOLERANCE_CURVES["paper_upper_arm_pain"].floor_kpa == 120.0
    rr = TOLERANCE_CURVES["reswick_rogers_1976"]
    assert rr.limit_kpa(8 * 3600.0) == pytest.approx(60 * MMHG_KPA, rel=1e-3)
    for c in TOLERANCE_CURVES.values():
        assert c.kind in ("pain", "discomfort", "damage") and c.citation and c.notes


@settings(max_examples=60, deadline=None)
@given(name=st.sampled_from(sorted(TOLERANCE_CURVES)),
       p=st.lists(st.floats(0.0, 1000.0), min_size=2, max_size=8),
       t=st.lists(st.floats(1.0, 1e6), min_size=2, max_size=8))
def test_curves_are_monotone(name, p, t):
    curve = TOLERANCE_CURVES[name]
    allowed = curve.allowed_time_s(np.sort(p))
    assert np.all(allowed[:-1] >= allowed[1:])          # inf >= inf holds below the floor
    limit = curve.limit_kpa(np.sort(t))
    assert np.all(np.diff(limit) <= 1e-12)
    # the limit at the allowed time is not above the pressure
    for q in p:
        ta = float(curve.allowed_time_s(q))
        if 0 < ta < math.inf:
            assert float(curve.limit_kpa(ta)) <= q * (1 + 1e-9)


def test_a_bad_curve_is_refused():
    from phri_spring.errors import ModelInputError

    with pytest.raises(ModelInputError):
        ToleranceCurve("x", "damage", "", "", (60.0, 30.0), (10.0, 5.0), "c")
    with pytest.raises(ModelInputError):
        ToleranceCurve("x", "damage", "", "", (30.0, 60.0), (5.0, 10.0), "c")
    with pytest.raises(ModelInputError, match="linder_ganz_2006"):
        tolerance_curve("nope")


# --------------------------------------------------------------------------- simulate
def _log(path: Path, n=300, seed=3):
    rng = np.random.default_rng(seed)
    t = np.round(np.arange(n) * 0.5, 10)
    W = np.column_stack([rng.normal(0, 20, (n, 3)) + [0, 0, 60], rng.normal(0, 1, (n, 3))])
    pd.DataFrame(np.column_stack([t, W]), columns=["time", "Fx", "Fy", "Fz", "Mx", "My",
                                                   "Mz"]).to_csv(path, index=False)
    return path


def test_simulate_dose_columns_match_plain_loops(tmp_path):
    from phri_spring.io.config import load_config
    from phri_spring.workflows.common import model_from_config

    log = _log(tmp_path / "log.csv")
    out = tmp_path / "forces.parquet"
    r = run_phri("simulate", HARMONY_CONFIG, log, "-o", out, "--tolerance",
                 "cuff_knee_discomfort_2020", "--chunk-rows", 37, "-q")
    assert r.exit_code == 0, r.output
    df = pd.read_parquet(out)
    assert list(df.columns) == ["time", *LABELS, *EXTRAS, "dose_max", "dose_element"]
    model = model_from_config(load_config(HARMONY_CONFIG), "compliant")
    P = df[LABELS].to_numpy() * np.asarray(model.inv_area_kpa)     # absolute: no baseline
    c = TOLERANCE_CURVES["cuff_knee_discomfort_2020"]
    cum, ap, af, fp, fd = ref_exposure(c.times_s, c.limits_kpa, df["time"].to_numpy(), P,
                                       120.0)
    np.testing.assert_allclose(df["dose_max"].to_numpy(), cum.max(axis=1))
    table = pd.read_csv(tmp_path / "forces_exposure.csv")
    assert list(table["element"]) == LABELS
    np.testing.assert_allclose(table["time_above_curve_floor_s"], af, atol=1e-5)
    np.testing.assert_allclose(table["time_above_pain_threshold_s"], ap, atol=1e-5)
    assert af.max() > 0            # the log does press above 13.7 kPa somewhere
    # CSV: chunks encoded on several threads, the dose still added in log order
    csv = tmp_path / "forces.csv"
    r = run_phri("simulate", HARMONY_CONFIG, log, "-o", csv, "--tolerance",
                 "linder_ganz_2006", "--chunk-rows", 23, "--decimals", -1, "-q")
    assert r.exit_code == 0, r.output
    lg = TOLERANCE_CURVES["linder_ganz_2006"]
    cum = ref_exposure(lg.times_s, lg.limits_kpa, df["time"].to_numpy(), P, 120.0)[0]
    assert 0 < cum.max() < math.inf
    np.testing.assert_allclose(pd.read_csv(csv)["dose_max"], cum.max(axis=1), rtol=1e-9)


def test_no_option_no_columns_and_same_forces(tmp_path):
    log = _log(tmp_path / "log.csv", n=80)
    plain, dosed = tmp_path / "plain.csv", tmp_path / "dosed.csv"
    assert run_phri("simulate", HARMONY_CONFIG, log, "-o", plain, "-q").exit_code == 0
    assert not (tmp_path / "plain_exposure.csv").exists()
    a = pd.read_csv(plain)
    assert list(a.columns) == ["time", *LABELS, *EXTRAS]
    raw = harmony_dict()
    raw["tolerance"] = {"curve": "linder_ganz_2006"}
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(raw, sort_keys=False))
    r = run_phri("simulate", cfg, log, "-o", dosed)
    assert r.exit_code == 0, r.output
    assert "dose (linder_ganz_2006) max" in r.output
    b = pd.read_csv(dosed)
    assert list(b.columns) == ["time", *LABELS, *EXTRAS, "dose_max", "dose_element"]
    pd.testing.assert_frame_equal(a, b[a.columns])


def test_simulate_in_memory_has_the_same_dose(tmp_path):
    from phri_spring.workflows.simulate import simulate

    rng = np.random.default_rng(0)
    t = np.arange(50) * 60.0
    W = np.column_stack([rng.normal(0, 20, (50, 3)) + [0, 0, 80], np.zeros((50, 3))])
    res = simulate(HARMONY_CONFIG, W, time=t, tolerance="linder_ganz_2006")
    c = TOLERANCE_CURVES["linder_ganz_2006"]
    P = res.absolute_forces * 1.0
    from phri_spring.io.config import load_config
    from phri_spring.workflows.common import model_from_config

    P = P * np.asarray(model_from_config(load_config(HARMONY_CONFIG)).inv_area_kpa)
    cum = ref_exposure(c.times_s, c.limits_kpa, t, P, 120.0)[0]
    np.testing.assert_allclose(res.extras["dose_max"], cum.max(axis=1))
    assert "dose_max" not in simulate(HARMONY_CONFIG, W, time=t).extras


@pytest.mark.parametrize("section, key", [
    ("linder_ganz_2006", "tolerance"),
    ({"curve": "linder"}, "tolerance.curve"),
    ({"curv": "linder_ganz_2006"}, "tolerance.curv"),
    ({}, "tolerance.curve"),
    ({"curve": 3}, "tolerance.curve"),
])
def test_bad_tolerance_sections_are_one_line(tmp_path, section, key):
    raw = harmony_dict()
    raw["tolerance"] = section
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(raw, sort_keys=False))
    r = run_phri("simulate", cfg, _log(tmp_path / "log.csv", n=5), "-o", tmp_path / "o.csv")
    assert_one_line_error(r, key, str(cfg))
    assert not (tmp_path / "o.csv").exists()


def test_bad_tolerance_options_are_one_line(tmp_path):
    log = _log(tmp_path / "log.csv", n=5)
    r = run_phri("simulate", HARMONY_CONFIG, log, "-o", tmp_path / "o.csv", "--tolerance",
                 "reswick")
    assert_one_line_error(r, "--tolerance", "reswick_rogers_1976", code=2)
    # (with --uncertainty the dose is every draw's: tests/workflows/uncertainty/)
    # the exposure table would overwrite the log
    import shutil

    shutil.copy(log, tmp_path / "o_exposure.csv")
    r = run_phri("simulate", HARMONY_CONFIG, tmp_path / "o_exposure.csv", "-o",
                 tmp_path / "o.csv", "--tolerance", "linder_ganz_2006")
    assert_one_line_error(r, "o_exposure.csv", code=2)
    assert not (tmp_path / "o.csv").exists()


# --------------------------------------------------------------------------- compare
def test_compare_exposure_matches_plain_loops(tmp_path):
    from phri_spring.workflows.common import model_from_config
    from phri_spring.workflows.compare.run import compare, write_compare

    repo = REPO
    res = compare(HARMONY_CONFIG, repo / "examples" / "experiment" / "manifest.yaml",
                  arms="rigid", tolerance="cuff_knee_discomfort_2020")
    c = TOLERANCE_CURVES["cuff_knee_discomfort_2020"]
    inv_area = np.asarray(model_from_config(res.config, "rigid").inv_area_kpa)
    tc = res.trials[0]
    d = tc.data
    P = np.full((len(d.time), len(LABELS)), np.nan)
    for k, cond in enumerate(d.condition_series):
        if cond in tc.conditions:
            P[k] = tc.simulated_abs["rigid"][tc.conditions.index(cond)] * inv_area
    _, ap, af, _, _ = ref_exposure(c.times_s, c.limits_kpa, d.time, P, 120.0)
    rows = res.exposure[(res.exposure["trial"] == tc.spec.trial)
                        & (res.exposure["experiment"] == tc.spec.experiment)
                        & (res.exposure["direction"] == tc.spec.direction)]
    np.testing.assert_allclose(rows["time_above_curve_floor_s"], af)
    np.testing.assert_allclose(rows["time_above_pain_threshold_s"], ap)
    assert af.max() > 0            # some element is predicted above 13.7 kPa
    out = write_compare(res, tmp_path / "cmp", figures=False)
    assert (tmp_path / "cmp" / "exposure.csv") in out.files
    assert "cuff_knee_discomfort_2020" in (tmp_path / "cmp" / "report.md").read_text()
    plain = compare(HARMONY_CONFIG, repo / "examples" / "experiment" / "manifest.yaml",
                    arms="rigid")
    assert plain.exposure is None


# --------------------------------------------------------------------------- design
def test_design_dose_objective_matches_plain_loops_over_every_sample(tmp_path):
    from phri_spring.io.config import load_config
    from phri_spring.workflows.common import model_from_config
    from phri_spring.workflows.design.objectives import evaluate_design, load_set
    from phri_spring.workflows.simulate import simulate

    rng = np.random.default_rng(5)
    logs = []
    for i, n in enumerate((60, 25)):
        t = np.cumsum(rng.choice([1.0, 30.0, 300.0], size=n))
        W = np.round(np.column_stack([rng.normal(0, 25, (n, 3)) + [0, 0, 70],
                                      rng.normal(0, 1, (n, 3))]), 1)
        W[::4] = W[0]                        # repeated rows: merged by the load set
        path = tmp_path / f"log{i}.csv"
        pd.DataFrame(np.column_stack([t, W]), columns=["time", "Fx", "Fy", "Fz", "Mx", "My",
                                                       "Mz"]).to_csv(path, index=False)
        logs.append((t, W, path))
    raw = harmony_dict()
    raw["tolerance"] = {"curve": "cuff_knee_discomfort_2020"}
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(raw, sort_keys=False))
    cfg = load_config(tmp_path / "cfg.yaml")
    loads = load_set([p for _, _, p in logs])
    assert len(loads.weights) < loads.n_samples
    got = evaluate_design(cfg, loads, "compliant")["dose_max"]
    # every sample of every log, its own step, in plain loops; each log starts at 0 s of dose
    c = TOLERANCE_CURVES["cuff_knee_discomfort_2020"]
    inv_area = np.asarray(model_from_config(cfg, "compliant").inv_area_kpa)
    total = np.zeros(len(LABELS))
    for t, W, _ in logs:
        P = simulate(cfg, W, time=t).absolute_forces * inv_area
        above = ref_exposure(c.times_s, c.limits_kpa, t, P, 120.0)[2]
        total += above       # a time-independent limit: its dose is infinite once above
    assert total.max() > 0
    assert got == math.inf
    # a time-dependent curve: finite, equal to the plain sum
    raw["tolerance"] = {"curve": "linder_ganz_2006"}
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(raw, sort_keys=False))
    cfg = load_config(tmp_path / "cfg.yaml")
    c = TOLERANCE_CURVES["linder_ganz_2006"]
    total = np.zeros(len(LABELS))
    for t, W, _ in logs:
        P = simulate(cfg, W, time=t).absolute_forces * inv_area
        total += ref_exposure(c.times_s, c.limits_kpa, t, P, 120.0)[0][-1]
    assert total.max() > 0
    assert evaluate_design(cfg, loads, "compliant")["dose_max"] == pytest.approx(total.max(),
                                                                                 rel=1e-9)
    raw.pop("tolerance")
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(raw, sort_keys=False))
    assert "dose_max" not in evaluate_design(load_config(tmp_path / "cfg.yaml"), loads,
                                             "compliant")


def test_a_study_minimising_the_dose_needs_a_curve(tmp_path):
    from phri_spring.errors import ConfigError
    from phri_spring.workflows.design.study import prepare_study

    (tmp_path / "base.yaml").write_text(yaml.safe_dump(harmony_dict(), sort_keys=False))
    _log(tmp_path / "log.csv", n=10)
    study = {"config": "base.yaml", "loads": ["log.csv"],
             "vary": {"strap.tension": {"values": [5, 10]}}, "minimise": ["dose_max"]}
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    with pytest.raises(ConfigError) as info:
        prepare_study(tmp_path / "study.yaml")
    msg = str(info.value)
    assert "\n" not in msg and "study.yaml" in msg and "tolerance" in msg, msg


# --------------------------------------------------------------------------- live
def test_live_dose_equals_simulate_and_its_alarm_is_raised_once(tmp_path):
    from click.testing import CliRunner

    from phri_cli.main import phri

    log = _log(tmp_path / "log.csv", n=200)
    sim = tmp_path / "sim.parquet"
    assert run_phri("simulate", HARMONY_CONFIG, log, "-o", sim, "--tolerance",
                    "linder_ganz_2006", "-q").exit_code == 0
    ref = pd.read_parquet(sim)
    dose = ref["dose_max"].to_numpy()
    assert dose[-1] > 0
    thr = float(0.5 * dose[-1])
    out = tmp_path / "live.parquet"
    res = CliRunner().invoke(phri, ["live", str(HARMONY_CONFIG), "--source", "-", "-o", str(out),
                                    "--tolerance", "linder_ganz_2006", "--dose-alarm",
                                    f"{thr!r}", "--no-progress"],
                             input=log.read_bytes())
    assert res.exit_code == 0, res.output
    live = pd.read_parquet(out)
    np.testing.assert_allclose(live["dose_max"], dose, rtol=1e-9)
    assert list(live["dose_element"]) == list(ref["dose_element"])
    assert res.stderr.count("DOSE ALARM") == 1
    first = np.flatnonzero(dose >= thr)[0]
    assert f"at t = {ref['time'][first]:.3f} s" in res.stderr
    assert "dose alarms 1" in res.stderr
    r = CliRunner().invoke(phri, ["live", str(HARMONY_CONFIG), "--source", "-", "--dose-alarm",
                                  "1"], input=log.read_bytes())
    assert_one_line_error(r, "--dose-alarm", "tolerance", code=2)


# --------------------------------------------------------------------------- figure
def test_binned_time_at_or_above_matches_plain_loops_and_the_figure_draws():
    from matplotlib.figure import Figure

    from phri_spring.reports.tolerance_figure import exposure_figure

    rng = np.random.default_rng(11)
    t, P, cuts = random_case(rng, 90, 3, 60.0)
    edges = np.array([0.5, 5.0, 9.0, 20.0, 32.0, 50.0])
    ex = Exposure("linder_ganz_2006", 3, 120.0, edges_kpa=edges)
    feed(ex, t, P, cuts)
    T = ex.time_at_or_above_s()
    for e in range(3):
        for b in range(len(edges) - 1):
            want = 0.0
            for k in range(1, len(t)):
                dt = t[k] - t[k - 1]
                p = P[k, e]
                if dt > 0 and not math.isnan(p) and edges[b] <= p < edges[-1]:
                    want += dt
            assert T[e, b] == pytest.approx(want, abs=1e-9)
    fig = exposure_figure(edges, T, labels=["a", "b", "c"], curve=ex.curve, dose=ex.dose,
                          pain_threshold_kpa=40.0)
    assert isinstance(fig, Figure) and len(fig.axes) == 1


def test_simulate_plot_draws_the_exposure_only_with_a_curve(tmp_path):
    log = _log(tmp_path / "log.csv", n=40)
    r = run_phri("simulate", HARMONY_CONFIG, log, "-o", tmp_path / "a.csv", "--plot",
                 tmp_path / "a.png", "-q")
    assert r.exit_code == 0, r.output
    assert not (tmp_path / "a_exposure.png").exists()
    r = run_phri("simulate", HARMONY_CONFIG, log, "-o", tmp_path / "b.csv", "--plot",
                 tmp_path / "b.png", "--tolerance", "reswick_rogers_1976", "-q")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "b_exposure.png").stat().st_size > 1000


# --------------------------------------------------------------------------- docs
def test_the_worked_example_of_the_docs_runs_and_matches_its_closed_form():
    import re

    doc = REPO / "docs" / "tolerance.md"
    blocks = re.findall(r"```python\n(.*?)```", doc.read_text(encoding="utf-8"), flags=re.S)
    assert blocks
    ns = {}
    exec(compile(blocks[0], str(doc), "exec"), ns)  # noqa: S102 - our own docs
    allowed = math.sqrt(3600.0 * 7200.0)             # halfway from 1 h to 2 h in log time
    assert ns["dose_max"][1800] == pytest.approx(1800.0 / allowed, rel=1e-9)
    reached = 1800.0 + (1.0 - 1800.0 / allowed) * 900.0
    assert ns["exposure"].dose_reached_s[0] == math.ceil(reached)


def test_a_study_can_minimise_the_dose(tmp_path):
    raw = harmony_dict()
    raw["tolerance"] = {"curve": "linder_ganz_2006"}
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(raw, sort_keys=False))
    _log(tmp_path / "log.csv", n=40)
    study = {"config": "base.yaml", "loads": ["log.csv"],
             "vary": {"strap.tension": {"values": [5, 40]}},
             "minimise": ["dose_max", "peak_pressure_to_pain_threshold"]}
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    r = run_phri("design", tmp_path / "study.yaml", "-o", tmp_path / "out", "--no-figures")
    assert r.exit_code == 0, r.output
    table = pd.read_csv(tmp_path / "out" / "designs.csv")
    assert np.all(table["dose_max"] > 0)
    # a tighter strap presses harder: a larger dose
    d = dict(zip(table["strap.tension"], table["dose_max"]))
    assert d[40] > d[5]
