"""``phri fit-stiffness --law exponential``: k0 and the stiffening rate beta of tissue that stiffens.

References are independent of the package's law: the synthetic trials follow the law as
written out in :mod:`phri_spring.synthetic.indenter` (not taken from tissue_laws), the array
tests write it here in closed form, and the element areas of the config test come from the
cuff's dimensions by hand. Nothing is compared with the command's own earlier output.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from phri_spring.errors import UsageError
from phri_spring.physics.indentation.linear import fit_trial
from phri_spring.physics.indentation.exponential import fit_branches, fit_trial_exponential
from phri_spring.synthetic.indenter import synth_dataset, synth_trial, truth_map, write_trials

from support.helpers import HARMONY_CONFIG, REPO, assert_one_line_error, run_phri, stderr_of

SPEC_COLUMNS = ["location", "row", "angle_index", "stiffness_N_per_m", "std_N_per_m",
                "n_trials"]
QUALITY = ["n_strokes", "r2_min", "loading_slope_N_per_m", "hysteresis_ratio", "peak_force_N",
           "peak_depth_mm", "trial_spread", "n_trials_skipped", "flags"]
STIFFENING = ["stiffening_per_m", "stiffening_std_per_m"]


def closed_form(d, k0, beta):
    """F = (k0/beta)(exp(beta d) - 1) for d > 0, k0 d at beta = 0 [N]."""
    d = np.maximum(np.asarray(d, dtype=float), 0.0)
    return k0 * d if beta == 0 else k0 * np.expm1(beta * d) / beta


def fit_synthetic(k0, beta, seed, **kwargs):
    tr = synth_trial(k0, stiffening=beta, seed=seed, rate=(100.0, 200.0, 250.0, 500.0)[seed % 4],
                     **kwargs)
    return tr, fit_trial_exponential(fit_trial(tr.time, tr.displacement, tr.force))


# --------------------------------------------------------------------------- (a) noise-free


@pytest.mark.parametrize("k0, beta, hysteresis", [
    (2500.0, 0.0, None), (4242.0, 0.0, 0.15), (4242.0, 60.0, None), (3000.0, 150.0, 0.0),
    (8000.0, 300.0, None), (5000.0, 500.0, 0.15)])
def test_noise_free_trials_recover_the_law(k0, beta, hysteresis):
    """Hand-like trials, loading softer than unloading (a dent h * dmax moves each push's
    contact point), no force noise, no encoder steps: k0 and beta to 1e-6 (3 % and 10 % are
    the requirement; round-off level, about 1e-11, is what the fit reaches)."""
    for seed in range(3):
        tr, fit = fit_synthetic(k0, beta, seed, noise_sd=0.0, encoder_step=0.0,
                                hysteresis=hysteresis)
        assert fit.converged, fit.message
        assert fit.k0 == pytest.approx(k0, rel=1e-6)
        if beta:
            assert fit.status == "ok"
            assert fit.stiffening == pytest.approx(beta, rel=1e-6)
        else:
            assert fit.stiffening < 1e-4            # [1/m]: beta * 5 mm < 1e-6
        assert fit.r2_min > 1 - 1e-9
        assert fit.trial.n_strokes == tr.n_pushes


@st.composite
def branches(draw):
    """(k0, beta, contact points, per-stroke depth and force) of the law, no noise."""
    k0 = math.exp(draw(st.floats(math.log(300.0), math.log(3e4))))
    beta = draw(st.one_of(st.just(0.0), st.floats(10.0, 1000.0)))
    n = draw(st.integers(1, 3))
    offsets, depths, forces = [], [], []
    for _ in range(n):
        d0 = draw(st.floats(-1e-3, 2e-3))
        top = d0 + draw(st.floats(1.5e-3, 6e-3))
        m = draw(st.integers(40, 400))
        d = np.linspace(top, d0, m)                 # unloading: depth decreasing in time
        f = closed_form(d - d0, k0, beta)
        keep = f > 0.05                             # in contact: above a threshold
        offsets.append(d0)
        depths.append(d[keep])
        forces.append(f[keep])
    return k0, beta, np.array(offsets), depths, forces


@settings(max_examples=40, deadline=None)
@given(case=branches())
def test_fit_branches_recovers_every_parameter(case):
    k0, beta, offsets, depths, forces = case
    out = fit_branches(depths, forces)
    assert out["status"] in ("ok", "at_bound")
    assert out["k0"] == pytest.approx(k0, rel=1e-6)
    if beta:
        assert out["status"] == "ok"
        assert out["stiffening"] == pytest.approx(beta, rel=1e-6)
    else:
        assert out["stiffening"] * 6e-3 < 1e-6
    np.testing.assert_allclose(out["offset"], offsets, rtol=0, atol=1e-9)


def test_softening_stroke_ends_on_the_bound_without_error():
    """A concave stroke (softening) has no beta >= 0 to match: beta = 0, reported."""
    d = np.linspace(4e-3, 0.05e-3, 300)
    f = 5000.0 * d - 2e5 * d * d
    out = fit_branches([d], [f])
    assert out["status"] == "at_bound" and out["stiffening"] == 0.0
    assert "bound 0" in out["message"]
    assert out["k0"] > 0


# --------------------------------------------------------------------------- (b) noisy


@pytest.mark.parametrize("beta", [0.0, 40.0, 150.0, 400.0])
def test_noisy_trials_within_limits(beta):
    """The bundled example's noise (force noise 0.01-0.04 N, 0.025 mm encoder steps, tremor
    and drift): k0 within 3 % in every trial and 1 % on average; beta within 10 % on average
    (5 % is asked here) and in every trial from 150 1/m up; linear tissue gives beta near 0."""
    ek, eb, b0 = [], [], []
    for k0 in (2500.0, 8000.0):
        for seed in range(10, 22):
            _, fit = fit_synthetic(k0, beta, seed)
            assert fit.converged, fit.message
            ek.append(fit.k0 / k0 - 1)
            if beta:
                eb.append(fit.stiffening / beta - 1)
            else:
                b0.append(fit.stiffening)
    ek = np.abs(ek)
    assert ek.max() < 0.03 and ek.mean() < 0.01, (ek.max(), ek.mean())
    if beta:
        eb = np.abs(eb)
        assert eb.mean() < 0.05, eb.mean()
        if beta >= 150:
            assert eb.max() < 0.10, eb.max()
    else:
        # [1/m]: over a 5 mm push the tangent changes by less than 3 %
        assert max(b0) < 6.0 and np.mean(b0) < 2.0, (max(b0), np.mean(b0))


# --------------------------------------------------------------------------- (c) end to end


@pytest.fixture(scope="module")
def stiffening_set(tmp_path_factory):
    """21 locations x 2 trials of tissue that stiffens, beta 60 to 460 1/m over the map,
    written like the bundled example (3 decimals of N, 0.001 mm)."""
    truth = truth_map(seed=77)
    beta = {lab: 60.0 + 20.0 * i for i, lab in enumerate(truth)}
    trials = synth_dataset(truth, seed=909, stiffening=beta,
                           rates=(100.0, 173.0, 250.0, 500.0))
    base = tmp_path_factory.mktemp("stiffening")
    write_trials(trials, base / "folder", force_decimals=3)
    out = base / "fit.csv"
    res = run_phri("fit-stiffness", base / "folder", "-o", out, "--law", "exponential",
                   "--plots", base / "figs", "--trials-csv", base / "trials.csv")
    assert res.exit_code == 0, stderr_of(res)
    return truth, beta, trials, base, res


def test_cli_recovers_k0_and_beta_per_location(stiffening_set):
    truth, beta, trials, base, res = stiffening_set
    assert "exponential law over 21 locations" in res.stdout
    table = pd.read_csv(base / "fit.csv")
    assert list(table.columns) == SPEC_COLUMNS + STIFFENING + QUALITY
    assert list(table["location"]) == list(truth)
    assert (table["n_trials"] == 2).all()
    k_err = table["stiffness_N_per_m"].to_numpy() / np.array(list(truth.values())) - 1
    b_err = table["stiffening_per_m"].to_numpy() / np.array(list(beta.values())) - 1
    assert np.abs(k_err).max() < 0.01, k_err
    assert np.abs(b_err).max() < 0.03, b_err
    assert (table["r2_min"] > 0.999).all()
    # the trials of a location share beta: their scatter is the fit's, small
    assert (table["stiffening_std_per_m"] < 0.05 * table["stiffening_per_m"]).all()
    for name in ("force_displacement.png", "stiffness_map.png"):
        assert (base / "figs" / name).stat().st_size > 0


def test_cli_per_trial_values_and_spreads(stiffening_set):
    """Each trial's k0 against its own true stiffness; the location SDs are the sample SDs
    (ddof = 1) of those trial values."""
    truth, beta, trials, base, _ = stiffening_set
    per_trial = pd.read_csv(base / "trials.csv")
    assert {"stiffening_per_m", "contact_offsets_mm", "fit_status"} <= set(per_trial.columns)
    true_k = {(t.location, t.trial): t.stiffness for t in trials}
    got_k = per_trial.set_index(["location", "trial"])["stiffness_N_per_m"]
    rel = np.array([got_k[key] / k - 1 for key, k in true_k.items()])
    assert np.abs(rel).max() < 0.02, rel
    got_b = per_trial.set_index(["location", "trial"])["stiffening_per_m"]
    rel_b = np.array([got_b[(t.location, t.trial)] / beta[t.location] - 1 for t in trials])
    assert np.abs(rel_b).max() < 0.10, rel_b
    table = pd.read_csv(base / "fit.csv").set_index("location")
    for lab, group in per_trial.groupby("location"):
        # (the CSVs hold 8 significant digits: an SD of close values keeps fewer)
        assert table.loc[lab, "std_N_per_m"] == pytest.approx(
            np.std(group["stiffness_N_per_m"], ddof=1), rel=1e-5, abs=1e-3)
        assert table.loc[lab, "stiffening_std_per_m"] == pytest.approx(
            np.std(group["stiffening_per_m"], ddof=1), rel=1e-5, abs=1e-4)


def test_force_displacement_grid_draws_the_fitted_curves(stiffening_set):
    from phri_spring.reports.indenter_figures import force_displacement_grid
    from phri_spring.workflows.fit.stiffness import fit_stiffness

    _, _, _, base, _ = stiffening_set
    result = fit_stiffness(base / "folder", law="exponential")
    fig = force_displacement_grid(result.locations)
    for ax, loc in zip(fig.axes, result.locations):
        dashed = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
        expected = [(ft, i) for ft in loc.fits for i in range(ft.trial.n_strokes)]
        assert len(dashed) == len(expected)
        for ln, (ft, i) in zip(dashed, expected):
            d = np.asarray(ln.get_xdata()) * 1e-3
            np.testing.assert_allclose(ln.get_ydata(),
                                       closed_form(d - ft.offset[i], ft.k0, ft.stiffening),
                                       rtol=1e-12, atol=1e-12)
            assert len(d) > 2                        # a curve, not a straight segment
        assert "\u03b2" in ax.get_title()
    assert "exponential unloading fit" in [t.get_text() for t in fig.legends[0].get_texts()]


# --------------------------------------------------------------------------- config use


def test_csv_is_tissue_stiffness_and_stiffening_of_a_config(stiffening_set, tmp_path):
    """The CSV as both keys of a copy of the Harmony config: simulate runs, and the model's
    law carries the CSV's per-location k0 (converted to elements by area) and beta."""
    from phri_spring.io.config import load_config
    from phri_spring.workflows.common import model_from_config

    _, _, _, base, _ = stiffening_set
    csv = tmp_path / "fit.csv"
    csv.write_bytes((base / "fit.csv").read_bytes())
    data = yaml.safe_load(HARMONY_CONFIG.read_text())
    data["tissue"].update(stiffness="fit.csv", stiffening="fit.csv")
    cfg_path = tmp_path / "cfg.yaml"
    cfg_path.write_text(yaml.safe_dump(data))

    log = tmp_path / "log.csv"
    pd.read_csv(REPO / "examples" / "wrench_log.csv", comment="#").iloc[::80].to_csv(
        log, index=False)
    out = tmp_path / "forces.csv"
    res = run_phri("simulate", cfg_path, log, "-o", out, "-q")
    assert res.exit_code == 0, stderr_of(res)
    assert pd.read_csv(out)["converged"].all()

    table = pd.read_csv(csv).set_index("location")
    cfg = load_config(cfg_path)
    labels = list(cfg.labels)
    model = model_from_config(cfg, "compliant")
    assert model.law.name == "exponential"
    np.testing.assert_array_equal(model.law.params["stiffening"],
                                  table.loc[labels, "stiffening_per_m"].to_numpy())
    np.testing.assert_array_equal(cfg.tissue_stiffness,
                                  table.loc[labels, "stiffness_N_per_m"].to_numpy())
    g = data["geometry"]
    area = g["radius"] * math.radians(g["angles"]["step"]) * g["row_width"]
    indenter = math.pi * data["tissue"]["indenter_diameter"] ** 2 / 4
    np.testing.assert_allclose(model.law.k0,
                               table.loc[labels, "stiffness_N_per_m"].to_numpy() * area
                               / indenter, rtol=1e-12)


# --------------------------------------------------------------------------- (d), (e)


@pytest.fixture(scope="module")
def linear_folder(tmp_path_factory):
    trials = synth_dataset(truth_map(seed=5, rows="AB", n_angles=3), seed=17)
    folder = tmp_path_factory.mktemp("linear") / "folder"
    write_trials(trials, folder, force_decimals=3)
    return folder


def test_bad_law_is_a_one_line_usage_error(linear_folder, tmp_path):
    out = tmp_path / "k.csv"
    res = run_phri("fit-stiffness", linear_folder, "-o", out, "--law", "cubic")
    assert_one_line_error(res, "--law", "cubic", code=2)
    assert not out.exists()
    from phri_spring.workflows.fit.stiffness import fit_stiffness

    with pytest.raises(UsageError) as err:
        fit_stiffness(linear_folder, law="cubic")
    assert err.value.key == "law"


def test_linear_law_is_the_default_and_unchanged(linear_folder, tmp_path):
    """--law linear writes exactly what no --law writes, with the linear columns only, and
    the generator's linear trials do not move with the new option."""
    outs = {}
    for name, extra in (("default", []), ("linear", ["--law", "linear"])):
        out, per_trial = tmp_path / f"{name}.csv", tmp_path / f"{name}_trials.csv"
        res = run_phri("fit-stiffness", linear_folder, "-o", out, "--trials-csv", per_trial,
                       *extra)
        assert res.exit_code == 0, stderr_of(res)
        assert res.stdout.startswith("stiffness over 6 locations:")
        outs[name] = (out.read_bytes(), per_trial.read_bytes())
    assert outs["default"] == outs["linear"]
    header = outs["linear"][0].decode().splitlines()[0].split(",")
    assert header == SPEC_COLUMNS + QUALITY
    a = synth_trial(4242.0, seed=3)
    b = synth_trial(4242.0, seed=3, stiffening=0.0)
    for name in ("time", "displacement", "force"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_linear_tissue_is_reported_on_the_bound(linear_folder, tmp_path):
    """Tissue that does not stiffen: beta near 0, the trials on the bound named in warnings."""
    out = tmp_path / "k.csv"
    res = run_phri("fit-stiffness", linear_folder, "-o", out, "--law", "exponential")
    assert res.exit_code == 0, stderr_of(res)
    table = pd.read_csv(out)
    assert (table["stiffening_per_m"] < 6.0).all()
    bound = table["flags"].fillna("").str.contains("stiffening_bound")
    lines = [ln for ln in stderr_of(res).splitlines() if "bound 0 1/m" in ln]
    assert len(lines) >= bound.sum() > 0
    assert all(ln.startswith("warning: ") and " trial " in ln for ln in lines)


def test_a_fit_that_does_not_converge_is_a_warning(linear_folder, tmp_path, monkeypatch):
    """An optimiser stopped after one evaluation: every trial reported as failed, values left
    empty, exit 0 (not a crash)."""
    import scipy.optimize

    real = scipy.optimize.least_squares
    monkeypatch.setattr(scipy.optimize, "least_squares",
                        lambda *a, **k: real(*a, **{**k, "max_nfev": 1}))
    out = tmp_path / "k.csv"
    res = run_phri("fit-stiffness", linear_folder, "-o", out, "--law", "exponential")
    assert res.exit_code == 0, stderr_of(res)
    table = pd.read_csv(out)
    assert table["stiffness_N_per_m"].isna().all() and (table["n_trials"] == 0).all()
    assert table["flags"].str.contains("fit_failed").all()
    err = stderr_of(res)
    assert err.count("exponential fit failed") == 12 and "Traceback" not in err


def test_generator_rejects_a_negative_stiffening():
    with pytest.raises(ValueError, match="stiffening"):
        synth_trial(4242.0, seed=1, stiffening=-1.0)
