"""What scatters for each arm in the Monte Carlo (issue 19, item 4), and Sobol indices that
cannot be computed.

The coupled arm uses the continuum's Young's modulus E, not the per-location tissue
stiffness. The reference forces of a draw are computed here from the FE's E = 1 matrices
scaled by E (the condensed stiffness and the normal output are linear in E) and the
coupled model built directly, not through the config glue the Monte Carlo uses. Two
checks: the percentiles over the draws are those of the reference forces at the drawn
moduli, and with many draws the percentiles of each force that is monotone in E are the
reference force at the Gaussian quantiles of E, within the standard error of a sample
quantile. The coupled cases use 3 patches on one row (one FE build of a few seconds,
cached for the module).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner
from scipy.stats import norm

from support.helpers import harmony_dict, one_line
from phri_cli.main import phri
from phri_spring.io.config import config_from_dict
from phri_spring.physics.contact.solver import solve
from phri_spring.workflows.common import cuff_wrench, geometry_from_config
from phri_spring.workflows.uncertainty.run import (PERCENTILES, MonteCarloStream, UncertainInputs,
                                               monte_carlo, uncertain_inputs)

pytest.importorskip("skfem")

E0 = 5.0e4          # Pa
REL_SD = 0.2        # relative SD of the tissue (and so of E)
W_LC = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                 [0.0, 0.0, 5.0, 0.0, 0.0, 0.0],
                 [3.0, -4.0, 2.0, 0.05, -0.1, 0.1]])


def small_coupled_dict() -> dict:
    d = harmony_dict()
    d["geometry"] = {"radius": 0.04, "rows": {"A": 0.0}, "row_width": 0.02,
                     "angles": {"start": 90.0, "step": 120.0, "count": 3}}
    d["tissue"]["continuum"] = {"thickness": 0.01, "young_modulus": E0}
    # cuff springs of the tissue's order and unequal: the load sharing then depends on E
    # (with a rigid cuff it would not: scaling every tissue compliance moves no force)
    d["cuff"]["stiffness"] = {"per_angle": [1000.0, 20000.0, 4000.0]}
    d["strap"]["tension"] = 20.0
    d["load_cell"]["position"] = [0.0, 0.0, 0.0]
    return d


@pytest.fixture(scope="module")
def coupled(tmp_path_factory):
    """(config, forces_at) with the FE cached in a folder of this module."""
    cache = tmp_path_factory.mktemp("fe-cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("PHRI_SPRING_CACHE", str(cache))
        from phri_spring.io.cache.surface_stiffness import load_or_build
        from phri_spring.physics.continuum.coupled import build_coupled_model

        cfg = config_from_dict(small_coupled_dict())
        g = geometry_from_config(cfg)
        K1, info = load_or_build(g, cfg.continuum_thickness, 1.0, cfg.poisson_ratio)
        N1 = info["N"]

        def forces_at(E, w_lc=W_LC):
            m = build_coupled_model(g, K1 * E, cfg.cuff_stiffness,
                                    poisson_ratio=cfg.poisson_ratio,
                                    strap_tension=cfg.strap_tension, normal_output=N1 * E)
            sol = solve(m, cuff_wrench(cfg, w_lc))
            assert sol.converged.all() and sol.contact.all()
            return sol.forces

        yield cfg, forces_at


def test_coupled_percentiles_are_those_of_the_drawn_moduli(coupled):
    # fails before the fix: the coupled arm ignored the scatter (p5 = p95 everywhere)
    from phri_spring.workflows.uncertainty.draws import draw_configs

    cfg, forces_at = coupled
    inputs = uncertain_inputs(cfg, tissue_sd=REL_SD)
    res = monte_carlo(cfg, W_LC, draws=21, seed=5, arm="coupled", inputs=inputs)
    E = np.array([c.continuum_young_modulus for c in draw_configs(cfg, inputs, 21, 5)])
    assert np.ptp(E) > 0
    F = np.array([forces_at(e) for e in E])
    want = np.percentile(F, PERCENTILES, axis=0)
    np.testing.assert_allclose(res.forces, want, rtol=1e-9, atol=1e-9)
    spread = res.forces[2] - res.forces[0]
    assert spread[1:].max() > 0.1                       # N, under load
    np.testing.assert_allclose(spread[0], 0.0, atol=1e-9)   # zero wrench: the preload alone
    assert res.perturbed == "tissue.continuum.young_modulus (relative SD 0.2)"


def test_coupled_percentiles_follow_the_gaussian_modulus(coupled):
    # population check, independent of the draws: for a force monotone in E, its q-th
    # percentile over N draws tends to the force at E's q-quantile E0 (1 + z_q SD)
    cfg, forces_at = coupled
    n = 401
    res = monte_carlo(cfg, W_LC, draws=n, seed=11, arm="coupled",
                      inputs=uncertain_inputs(cfg, tissue_sd=REL_SD))
    grid = E0 * (1.0 + REL_SD * np.linspace(-3.0, 3.0, 25))
    Fg = np.array([forces_at(e) for e in grid])                   # (25, m, n_el)
    dF = np.diff(Fg, axis=0)
    rising, falling = np.all(dF > 0, axis=0), np.all(dF < 0, axis=0)
    monotone = rising | falling
    assert monotone.sum() >= 4
    z = norm.ppf(np.array(PERCENTILES) / 100.0)
    # standard error of a sample quantile: sqrt(q (1 - q) / N) / pdf(z_q) SD
    q = np.array(PERCENTILES) / 100.0
    se_E = np.sqrt(q * (1 - q) / n) / norm.pdf(z) * REL_SD * E0
    at = {zq: forces_at(E0 * (1.0 + REL_SD * zq)) for zq in np.concatenate([z, -z])}
    checked = 0
    for i, e in zip(*np.nonzero(monotone)):
        for a in range(3):
            zq = z[a] if rising[i, e] else -z[a]          # falling: p5 of F is F at E's p95
            Eq = E0 * (1.0 + REL_SD * zq)
            want = at[zq][i, e]
            slope = np.abs(np.interp(Eq, grid[:-1] + np.diff(grid) / 2,
                                     dF[:, i, e] / np.diff(grid)))
            assert abs(res.forces[a, i, e] - want) < 4.0 * se_E[a] * slope + 1e-9, (a, i, e)
            checked += 1
    assert checked >= 12


def test_simulate_names_what_scattered_for_the_coupled_arm(coupled, tmp_path):
    cfg, _ = coupled
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(small_coupled_dict()))
    log = tmp_path / "log.csv"
    pd.DataFrame(np.column_stack([[0.0, 0.01, 0.02], W_LC]),
                 columns=["time", "Fx", "Fy", "Fz", "Mx", "My", "Mz"]).to_csv(log, index=False)
    res = CliRunner().invoke(phri, ["simulate", str(path), str(log), "-o", str(tmp_path / "o.csv"),
                                    "--arm", "coupled", "--uncertainty", "4",
                                    "--uncertainty-sd", "tissue=0.2,tension=1"])
    assert res.exit_code == 0, res.output
    assert ("perturbed: tissue.continuum.young_modulus (relative SD 0.2), strap.tension "
            "(SD 1 N)") in res.stderr
    t = pd.read_csv(tmp_path / "o.csv")
    assert (t["A1_p95"] - t["A1_p5"]).iloc[1:].min() > 0


def test_what_scatters_for_each_arm():
    from phri_spring.workflows.uncertainty.draws import (modulus_sd, perturbed_text,
                                                       sobol_inputs, tissue_route)

    cfg = config_from_dict(harmony_dict())
    n = cfg.n_elements
    inputs = uncertain_inputs(cfg, tissue_sd=0.1)
    assert perturbed_text(cfg, inputs, "compliant") == "tissue.stiffness (21 of 21 locations)"
    assert perturbed_text(cfg, inputs, "rigid") == (
        "none (the tissue stiffness SD is unused: the rigid arm has no tissue springs)")
    assert sobol_inputs(cfg, inputs, "rigid") == []
    # the coupled arm: E given -> one modulus; E from the indenter map -> the stiffness map
    d = harmony_dict()
    d["tissue"]["continuum"] = {"thickness": 0.02, "young_modulus": 3e4}
    cg = config_from_dict(d)
    assert tissue_route(cg, "coupled") == "modulus"
    one = np.zeros(n)
    one[4] = 0.3 * cg.tissue_stiffness[4]
    # a CSV-like SD on one location only: the RMS relative SD 0.3 / sqrt(21)
    assert math.isclose(modulus_sd(cg, UncertainInputs(one)), 0.3 / math.sqrt(n), rel_tol=1e-12)
    assert modulus_sd(cg, UncertainInputs(np.zeros(n))) == 0.0
    assert [s[0] for s in sobol_inputs(cg, inputs, "coupled")] == [
        "tissue.continuum.young_modulus"]
    d["tissue"]["continuum"] = {"thickness": 0.02}
    assert tissue_route(config_from_dict(d), "coupled") == "stiffness"
    d["tissue"]["continuum"] = {"thickness": 0.02, "surface_stiffness": "k.npz"}
    assert tissue_route(config_from_dict(d), "coupled") == "none"


def test_rigid_arm_with_only_tissue_scatter_has_no_spread():
    cfg = config_from_dict(harmony_dict())
    inputs = uncertain_inputs(cfg, tissue_sd=0.1)
    mc = MonteCarloStream(cfg, draws=6, seed=1, arm="rigid", inputs=inputs)
    f, r = mc.block(0, W_LC)
    np.testing.assert_array_equal(f[0], f[2])       # one model for every draw: no scatter
    np.testing.assert_array_equal(r[0], r[2])
    assert mc.perturbed.startswith("none")
    f, _ = MonteCarloStream(cfg, draws=6, seed=1, arm="compliant", inputs=inputs).block(0, W_LC)
    assert np.all(f[2, 1:] - f[0, 1:] > 0)


# --------------------------------------------------------------------------- Sobol
def _sobol_setup():
    from phri_spring.workflows.design.objectives import LoadSet

    cfg = config_from_dict(harmony_dict())
    w = np.array([[0.0, 0.0, 20.0, 0.0, 0.0, 0.0], [5.0, -8.0, 10.0, 0.2, 0.0, 0.1]])
    loads = LoadSet(w, np.ones(len(w)), len(w))
    return cfg, loads, UncertainInputs(np.zeros(cfg.n_elements), tension_sd_N=2.0)


OBJ = ["peak_pressure_to_pain_threshold", "peak_cuff_displacement_mm"]


def test_sobol_with_an_evaluation_that_did_not_converge_is_unavailable(monkeypatch):
    pytest.importorskip("SALib")
    from SALib.sample import sobol as sobol_sample

    from phri_spring.io.config.study import UncertaintySpec
    from phri_spring.workflows.design import uncertainty

    cfg, loads, inputs = _sobol_setup()
    n_base = 8
    problem = {"num_vars": 1, "names": ["strap.tension"],
               "bounds": [[cfg.strap_tension, 2.0]], "dists": ["norm"]}
    X = sobol_sample.sample(problem, n_base, calc_second_order=False, seed=3)
    failing = float(X[0, 0])
    n_bad = int(np.count_nonzero(X[:, 0] == failing))     # Saltelli rows can repeat a value
    assert n_bad == 1
    real = uncertainty._objectives_at

    def one_fails(c, ls, arm, objectives):      # as evaluate_design reports a non-convergence
        v, p = real(c, ls, arm, objectives)
        if c.strap_tension == failing:
            return np.full_like(v, np.nan), np.full_like(p, np.nan)
        return v, p

    good = uncertainty.sobol_indices(cfg, loads, "compliant", inputs, OBJ, n_base, seed=3)
    assert np.all(np.isfinite(good["ST"])) and set(good["note"]) == {""}
    monkeypatch.setattr(uncertainty, "_objectives_at", one_fails)
    sob = uncertainty.sobol_indices(cfg, loads, "compliant", inputs, OBJ, n_base, seed=3)
    assert len(sob) == len(OBJ)
    for col in ("S1", "S1_conf", "ST", "ST_conf"):
        assert sob[col].isna().all(), col
    assert set(sob["note"]) == {f"unavailable: 1 of {len(X)} evaluations did not converge"}
    spec = UncertaintySpec(draws=3, seed=3, strap_tension_sd_N=2.0, tissue_stiffness_sd=0.0,
                           sobol=n_base)
    out = uncertainty.study_uncertainty(cfg, loads, "compliant", spec, OBJ)
    md = out["markdown"]
    assert "| peak_pressure_to_pain_threshold | (all) | unavailable | unavailable |" in md
    assert f"1 of {len(X)} evaluations did not converge" in md
    assert "| peak_cuff_displacement_mm | (all) | unavailable | unavailable |" in md
    assert "Perturbed for this arm: strap.tension (SD 2 N)." in md
    assert out["tables"]["sobol.csv"]["ST"].isna().all()


def test_unwritable_fe_cache_is_refused_in_one_line(coupled, tmp_path, monkeypatch):
    # every draw reloads the FE from the cache: without one, each draw would rebuild it
    from phri_spring.errors import UsageError

    cfg, _ = coupled
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("x")
    monkeypatch.setenv("PHRI_SPRING_CACHE", str(blocker))
    with pytest.raises(UsageError) as err:
        MonteCarloStream(cfg, draws=3, arm="coupled", inputs=uncertain_inputs(cfg, tissue_sd=0.1))
    assert one_line(str(err.value)) and "PHRI_SPRING_CACHE" in str(err.value)
