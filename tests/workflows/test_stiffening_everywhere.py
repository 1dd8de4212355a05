"""Every command runs the exponential tissue law (``tissue.stiffening``) and says which law ran.

For compare, simulate --uncertainty, design and the flat API, the forces and objectives
with ``tissue.stiffening`` must differ from the linear law's and equal those of
``simulate`` (the reference path, tested against closed forms in test_exponential_law.py)
on the same config, where the two compute the same thing; the summary lines and reports
must name the law; the coupled arm (a linear continuum) must say it does not use the
stiffening instead of silently ignoring it.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

import phri_spring as ps
from support.helpers import HARMONY_DICT, REPO, assert_one_line_error, example_log_lines, run_phri, \
    stderr_of
from phri_spring.io.config import load_config
from phri_spring.workflows.uncertainty.draws import (UncertainInputs, config_at, draw_configs,
                                                   perturbed_text, sobol_inputs,
                                                   uncertain_inputs)
from phri_spring.workflows.uncertainty.run import monte_carlo

BETA = 150.0
LAW = f"exponential tissue law (beta {BETA:g} 1/m)"
COUPLED_NOTE = "linear continuum (tissue.stiffening is used by the compliant arm only)"
EXPERIMENT = REPO / "examples" / "experiment"


# --------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """Configs (linear, stiffening 150 1/m, and with a fit-stiffness CSV holding beta and its
    SD), a 300-sample log and a two-trial manifest."""
    d = tmp_path_factory.mktemp("stiffening")
    lin = copy.deepcopy(HARMONY_DICT)
    (d / "linear.yaml").write_text(yaml.safe_dump(lin))
    stiff = copy.deepcopy(lin)
    stiff["tissue"]["stiffening"] = BETA
    (d / "stiff.yaml").write_text(yaml.safe_dump(stiff))
    labels = [f"{r}{j}" for r in "ABC" for j in range(7)]
    pd.DataFrame({"location": labels, "stiffness_N_per_m": np.full(21, 4242.0),
                  "std_N_per_m": np.full(21, 100.0),
                  "stiffening_per_m": np.linspace(100.0, 200.0, 21),
                  "stiffening_std_per_m": np.linspace(5.0, 25.0, 21)}).to_csv(d / "fit.csv",
                                                                             index=False)
    fit = copy.deepcopy(lin)
    fit["tissue"]["stiffness"] = "fit.csv"
    fit["tissue"]["stiffening"] = "fit.csv"
    (d / "fit.yaml").write_text(yaml.safe_dump(fit))
    lines = example_log_lines(300)
    # the example log's loads grow after 2 s: scale them up so that the law matters
    (d / "log.csv").write_text("time,Fx,Fy,Fz,Mx,My,Mz\n" + "\n".join(lines) + "\n")
    w = pd.read_csv(d / "log.csv")
    w[["Fx", "Fy", "Fz"]] *= 20.0
    w[["Mx", "My", "Mz"]] *= 5.0
    w.to_csv(d / "log.csv", index=False)
    man = {"baseline": "no_load", "trials": [
        {"file": str(EXPERIMENT / "iact_horizontal_1.csv"), "experiment": "I-Act",
         "direction": "horizontal", "trial": 1},
        {"file": str(EXPERIMENT / "iipass_vertical_1.csv"), "experiment": "II-Pass",
         "direction": "vertical", "trial": 1, "baseline": "start"}]}
    (d / "manifest.yaml").write_text(yaml.safe_dump(man))
    return d


def _coupled_config(folder: Path, stiffening: bool) -> Path:
    """A coupled-arm config on a user's surface-stiffness export (no FE build)."""
    from support.coupled_reference import kernel_K as _kernel_K
    from phri_spring.workflows.common import geometry_from_config

    npz = folder / "fe.npz"
    if not npz.exists():
        g = geometry_from_config(load_config(folder / "linear.yaml"))
        np.savez(npz, K=_kernel_K(g, dofs=6), labels=np.array(g.labels))
    data = yaml.safe_load((folder / ("stiff.yaml" if stiffening else "linear.yaml")).read_text())
    data["tissue"]["continuum"] = {"thickness": 0.02, "surface_stiffness": "fe.npz"}
    path = folder / f"coupled_{int(stiffening)}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _wrench(folder: Path) -> np.ndarray:
    return pd.read_csv(folder / "log.csv")[["Fx", "Fy", "Fz", "Mx", "My", "Mz"]].to_numpy()


# --------------------------------------------------------------------------- simulate / flat API
def test_flat_api_and_simulate_cli_run_the_law(folder):
    cfg = ps.config_with(folder / "linear.yaml", {"tissue.stiffening": BETA})
    assert cfg.tissue_law == "exponential"
    assert type(ps.model_from_config(cfg).law).__name__ == "ExponentialLaw"
    W = _wrench(folder)
    f_api = ps.simulate(cfg, W).forces
    f_lin = ps.simulate(folder / "linear.yaml", W).forces
    assert np.max(np.abs(f_api - f_lin)) > 1e-2          # the law changes the forces
    res = run_phri("simulate", folder / "stiff.yaml", folder / "log.csv", "-o",
                   folder / "f.csv", "--decimals", "-1")
    assert res.exit_code == 0, stderr_of(res)
    assert f"compliant arm, {LAW}, baseline none" in stderr_of(res)
    got = pd.read_csv(folder / "f.csv")[list(cfg.labels)].to_numpy()
    np.testing.assert_allclose(got, f_api, rtol=0, atol=1e-9)


def test_coupled_simulate_says_its_continuum_is_linear(folder):
    out = {}
    for stiff in (False, True):
        res = run_phri("simulate", _coupled_config(folder, stiff), folder / "log.csv", "-o",
                       folder / f"c{int(stiff)}.csv", "--arm", "coupled")
        assert res.exit_code == 0, stderr_of(res)
        line = stderr_of(res).strip()
        assert (COUPLED_NOTE in line) == stiff and "tissue law" not in line, line
        out[stiff] = pd.read_csv(folder / f"c{int(stiff)}.csv")
    pd.testing.assert_frame_equal(out[False], out[True])   # the stiffening is not used


# --------------------------------------------------------------------------- compare
def test_compare_runs_the_law_and_names_it(folder):
    cfg = load_config(folder / "stiff.yaml")
    result = ps.compare(cfg, folder / "manifest.yaml", arms=("rigid", "compliant"))
    lin = ps.compare(folder / "linear.yaml", folder / "manifest.yaml", arms=("compliant",))
    for tc, tl in zip(result.trials, lin.trials):
        want = ps.simulate(cfg, tc.data.wrench).forces
        np.testing.assert_allclose(tc.simulated_abs["compliant"], want, rtol=0, atol=1e-9)
        assert np.max(np.abs(tc.simulated_abs["compliant"] - tl.simulated_abs["compliant"])) \
            > 1e-3
    out = folder / "cmp"
    res = run_phri("compare", folder / "stiff.yaml", folder / "manifest.yaml", "-o", out,
                   "--no-figures", "--uncertainty", "3", "--uncertainty-sd",
                   "tissue=0,stiffening=0.2")
    assert res.exit_code == 0, stderr_of(res)
    assert f"compliant arm: {LAW}" in stderr_of(res)
    report = (out / "report.md").read_text()
    assert f"- tissue law: compliant arm: {LAW}" in report
    assert "## Model bands (Monte Carlo)" in report
    bands = pd.read_csv(out / "bands.csv")
    comp = bands[bands["arm"] == "compliant"]
    assert set(comp["tissue_law"]) == {LAW}
    assert set(comp["perturbed"]) == {"tissue.stiffening (21 of 21 locations)"}
    rigid = bands[bands["arm"] == "rigid"]
    assert "the stiffening SD is unused" in rigid["perturbed"].iloc[0]
    # only beta scatters, and it moves the compliant arm's loaded conditions
    loaded = comp[comp["simulated_N"].abs() > 0.5]
    assert len(loaded) and np.any(loaded["sim_p95_N"] - loaded["sim_p5_N"] > 1e-4)
    np.testing.assert_allclose(rigid["sim_p95_N"], rigid["sim_p5_N"], atol=1e-9)


def test_compare_with_a_linear_config_says_nothing_new(folder):
    out = folder / "cmp_lin"
    res = run_phri("compare", folder / "linear.yaml", folder / "manifest.yaml", "-o", out,
                   "--no-figures", "-q")
    assert res.exit_code == 0, stderr_of(res)
    assert "- tissue law: compliant arm: linear tissue law" in (out / "report.md").read_text()


# --------------------------------------------------------------------------- Monte Carlo
def test_draws_perturb_k0_with_the_tissue_sd_and_beta_only_with_its_own(folder):
    cfg = load_config(folder / "stiff.yaml")
    only_k = uncertain_inputs(cfg, tissue_sd=0.05)
    draws = draw_configs(cfg, only_k, 5, seed=2)
    for c in draws:
        assert c.tissue_law == "exponential"
        np.testing.assert_array_equal(c.tissue_law_parameters["stiffening"], BETA)
    assert np.ptp([c.tissue_stiffness[0] for c in draws]) > 0
    assert perturbed_text(cfg, only_k, "compliant") == (
        "tissue.stiffness (21 of 21 locations); tissue.stiffening held fixed (no SD given)")
    both = uncertain_inputs(cfg, tissue_sd=0.05, stiffening_sd=0.1)
    np.testing.assert_allclose(both.beta_sd, 0.1 * BETA)
    drawn = draw_configs(cfg, both, 5, seed=2)
    # beta has a random stream of its own: the stiffness draws stay those without it
    for a, b in zip(draws, drawn):
        np.testing.assert_array_equal(a.tissue_stiffness, b.tissue_stiffness)
    assert np.ptp([c.tissue_law_parameters["stiffening"][3] for c in drawn]) > 0
    assert perturbed_text(cfg, both, "coupled").endswith(
        "(the stiffening SD is unused: the coupled arm's continuum is linear)")
    names = [n for n, *_ in sobol_inputs(cfg, both, "compliant")]
    assert "tissue.stiffening[A0]" in names and "tissue.stiffness[A0]" in names
    which = [w for *_, w in sobol_inputs(cfg, both, "compliant") if w[0] == "b"][:1]
    at = config_at(cfg, which, [-5.0])                       # clipped to the linear law
    assert at.tissue_law_parameters["stiffening"][0] == 0.0
    assert cfg.tissue_law_parameters["stiffening"][0] == BETA   # the config is untouched


def test_stiffening_sd_from_the_fit_stiffness_csv(folder):
    cfg = load_config(folder / "fit.yaml")
    np.testing.assert_allclose(cfg.tissue_law_parameters["stiffening"],
                               np.linspace(100.0, 200.0, 21))
    inputs = uncertain_inputs(cfg)                           # from_csv for both
    np.testing.assert_allclose(inputs.beta_sd, np.linspace(5.0, 25.0, 21))
    np.testing.assert_allclose(inputs.tissue_sd, 100.0)
    beta = np.array([c.tissue_law_parameters["stiffening"]
                     for c in draw_configs(cfg, inputs, 4000, seed=1)])
    np.testing.assert_allclose(beta.mean(axis=0), np.linspace(100.0, 200.0, 21), atol=1.5)
    np.testing.assert_allclose(beta.std(axis=0, ddof=1), np.linspace(5.0, 25.0, 21),
                               rtol=0.06)
    # numbers in the config: beta held fixed
    assert not uncertain_inputs(load_config(folder / "stiff.yaml")).beta_sd.any()


def test_simulate_uncertainty_runs_the_law(folder):
    out = folder / "mc.csv"
    res = run_phri("simulate", folder / "stiff.yaml", folder / "log.csv", "-o", out,
                   "--uncertainty", "2", "--uncertainty-sd", "tissue=0")
    assert res.exit_code == 0, stderr_of(res)
    line = stderr_of(res).strip()
    assert f"compliant arm: {LAW}; perturbed: none; tissue.stiffening held fixed" in line
    # nothing scatters: every percentile is the prediction of simulate with the law
    cfg = load_config(folder / "stiff.yaml")
    want = ps.simulate(cfg, _wrench(folder)).forces
    got = pd.read_csv(out)
    for q in ("p5", "p50", "p95"):
        np.testing.assert_allclose(got[[f"{lab}_{q}" for lab in cfg.labels]].to_numpy(), want,
                                   rtol=0, atol=2e-6)          # CSV: 6 decimals
    # a model built for every draw (a tension SD of 1e-12 N): each runs the law
    mc = monte_carlo(cfg, _wrench(folder), draws=3, seed=0,
                     inputs=UncertainInputs(np.zeros(21), tension_sd_N=1e-12))
    assert mc.perturbed.startswith("strap.tension") and mc.tissue_law == f"compliant arm: {LAW}"
    np.testing.assert_allclose(mc.forces[1], want, rtol=0, atol=1e-9)
    res = run_phri("simulate", folder / "stiff.yaml", folder / "log.csv", "-o", out,
                   "--uncertainty", "4", "--uncertainty-sd", "tissue=0,stiffening=0.3")
    assert res.exit_code == 0, stderr_of(res)
    assert "perturbed: tissue.stiffening (21 of 21 locations))" in stderr_of(res)
    got = pd.read_csv(out)
    spread = got[[f"{lab}_p95" for lab in cfg.labels]].to_numpy() - \
        got[[f"{lab}_p5" for lab in cfg.labels]].to_numpy()
    assert spread.max() > 1e-3


# --------------------------------------------------------------------------- design
def _study(folder: Path, name: str, **over) -> Path:
    study = {"config": "linear.yaml", "loads": ["log.csv"], "arm": "compliant",
             "vary": {"tissue.stiffening": {"values": [0, 100, 200, 400]}}, "plan": "grid",
             "minimise": ["peak_cuff_displacement_mm"],
             "maximise": ["stiffness_rotational_Nm_per_deg"]}
    study.update(over)
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    return path


def test_design_varies_the_stiffening(folder):
    study = _study(folder, "study", uncertainty={"draws": 3, "tissue_stiffness_sd": 0.0,
                                                 "stiffening_sd": 1e-12})
    out = folder / "design"
    res = run_phri("design", study, "-o", out, "--no-figures", "--workers", "1")
    assert res.exit_code == 0, stderr_of(res)
    text = "compliant arm: linear/exponential tissue law, varied by the study (beta 0-400 1/m " \
           "over the designs)"
    assert text in stderr_of(res)
    t = pd.read_csv(out / "designs.csv")
    assert list(t["tissue.stiffening"]) == [0, 100, 200, 400]
    # more stiffening: a stiffer interface at the preload, a cuff that moves less
    assert np.all(np.diff(t["stiffness_rotational_Nm_per_deg"]) > 0)
    assert np.all(np.diff(t["peak_cuff_displacement_mm"]) < 0)
    # each design's peak pressure ratio is that of simulate on its config
    W = _wrench(folder)
    for beta, ratio in zip(t["tissue.stiffening"], t["peak_pressure_to_pain_threshold"]):
        cfg = ps.config_with(folder / "linear.yaml", {"tissue.stiffening": float(beta)})
        want = ps.simulate(cfg, W).extras["peak_pressure_to_pain_threshold"].max()
        assert abs(ratio - want) <= 1e-9 * max(1.0, want)
    assert t["peak_pressure_to_pain_threshold"].nunique() == 4
    report = (out / "report.md").read_text()
    assert f"- tissue law (compliant arm): {text.split(': ', 1)[1]}" in report
    # the best design (beta 400) is the uncertainty section's: its law, and beta perturbed
    assert "Tissue: exponential tissue law (beta 400 1/m)" in report
    assert "Perturbed for this arm: tissue.stiffening (21 of 21 locations)" in report
    u = pd.read_csv(out / "uncertainty_objectives.csv").set_index("objective")
    for name in ("peak_cuff_displacement_mm", "stiffness_rotational_Nm_per_deg"):
        assert abs(u.loc[name, "p50"] - t[name].iloc[3]) <= 1e-8 * abs(t[name].iloc[3])
    best = yaml.safe_load((out / "best.yaml").read_text().split("\n", 1)[1])
    assert best["tissue"]["stiffening"] == 400


def test_design_with_the_coupled_arm_says_the_stiffening_is_unused(folder):
    _coupled_config(folder, True)
    study = _study(folder, "study_c", config="coupled_1.yaml", arm="coupled",
                   vary={"strap.tension": {"values": [10, 20]}})
    out = folder / "design_c"
    res = run_phri("design", study, "-o", out, "--no-figures", "--workers", "1")
    assert res.exit_code == 0, stderr_of(res)
    assert f"coupled arm: {COUPLED_NOTE}" in stderr_of(res)
    assert f"- tissue law (coupled arm): {COUPLED_NOTE}" in (out / "report.md").read_text()


def test_design_bad_stiffening_is_one_line(folder):
    study = _study(folder, "study_neg", vary={"tissue.stiffening": {"values": [0, -100]}})
    res = run_phri("design", study, "-o", folder / "neg", "--no-figures", "--workers", "1")
    assert_one_line_error(res, "tissue.stiffening", "design 1", ">= 0")
    assert not (folder / "neg").exists()
    study = _study(folder, "study_sd", uncertainty={"stiffening_sd": "lots"})
    res = run_phri("design", study, "-o", folder / "sd", "--no-figures")
    assert_one_line_error(res, "uncertainty.stiffening_sd", "from_csv")


@pytest.mark.parametrize("value", ["abc", "-1", "nan"])
def test_bad_stiffening_sd_on_the_command_line_is_one_line(folder, value):
    out = folder / f"bad_sd_{value}.csv"
    res = run_phri("simulate", folder / "stiff.yaml", folder / "log.csv", "-o", out,
                   "--uncertainty", "3", "--uncertainty-sd", f"stiffening={value}")
    assert_one_line_error(res, "--uncertainty-sd", "stiffening", ">= 0", code=2)
    assert not out.exists()


@pytest.mark.parametrize("value", [-1.0, float("nan")])
def test_bad_stiffening_sd_in_a_study_is_one_line(folder, value):
    study = _study(folder, f"study_sd_{value}", uncertainty={"stiffening_sd": value})
    res = run_phri("design", study, "-o", folder / f"sd_{value}", "--no-figures")
    assert_one_line_error(res, "uncertainty.stiffening_sd", ">= 0")
    assert not (folder / f"sd_{value}").exists()
