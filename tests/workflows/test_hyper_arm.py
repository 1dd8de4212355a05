"""``tissue.continuum.law: neo_hookean`` end to end: identification, cache, CLI, bad input.

The reduced model is checked against the hyperelastic FE it was identified from, under
load control at wrenches that lie on none of the identification rays (the FE walks to
them by its own Newton iteration with the cuff's six dofs free; the reduced model solves
its 6-unknown equation): this checks the fit, the equation H u + dR = W and the force
outputs together. A small cuff (one row of five patches) on the coarsest mesh, with the
shipped 96 rays (fewer than 64 leave the cubic terms underdetermined in the held-out
check: each of its 8 folds must fit 56 cubic coefficients), keeps the identification to
a few minutes; benchmarks/HYPERELASTIC_ROM.md measures the shipped settings against the
level-3 reference.
"""

from __future__ import annotations

import builtins

import numpy as np
import pandas as pd
import pytest

from phri_spring.io.config import config_from_dict
from phri_spring.physics.contact.solver import Solver, solve

from support.helpers import (REPO, assert_one_line_error, cached_identification_only, run_phri,
                      small_human_cuff, stderr_of, write_yaml)

HUMAN = REPO / "configs" / "human_upper_arm.yaml"


def _raw(**continuum):
    return small_human_cuff(**{**dict(law="neo_hookean", max_force=20.0, max_moment=0.6),
                               **continuum})


def _short_log(folder, rows=1):
    """A log of ``rows`` samples of 1 N along +y (bad-config tests never solve it)."""
    path = folder / "log.csv"
    t = np.arange(rows) * 0.01
    pd.DataFrame({"time": t, "Fx": 0 * t, "Fy": 1.0 + 0 * t, "Fz": 0 * t, "Mx": 0 * t,
                  "My": 0 * t, "Mz": 0 * t}).to_csv(path, index=False)
    return path


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    """(model at mesh level 1, its FE, the cache folder): identified once for the module."""
    pytest.importorskip("felupe", reason="the hyper extra (felupe) is not installed")
    pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")
    from phri_spring.io.cache import hyper_reduction as store
    from phri_spring.physics.hyperelastic import fe as fh
    from phri_spring.workflows.common import coupled_model

    cache = tmp_path_factory.mktemp("cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(store, "IDENTIFY_LEVEL", 1)
        cfg = config_from_dict(_raw(), path=HUMAN, base_dir=HUMAN.parent)
        model = coupled_model(cfg, cache_dir=cache, level=1)
    lin = model.linear
    fe = fh.build_hyper_cuff(cfg.geometry(), cfg.continuum_thickness,
                             cfg.continuum_young_modulus, cfg.poisson_ratio, level=1,
                             delta=lin.delta)
    return model, fe, cache, cfg


def test_identified_model_matches_the_fe_off_its_rays(identified):
    from phri_spring.physics.hyperelastic import fe as fh

    model, fe, _, _ = identified
    assert model.reduction.info["source"] == "identified"
    assert model.reduction.info["samples"] == 289
    # the fit's own estimate of its error between rays, which the check below measures
    assert model.reduction.info["held_out_normal_pct"] < 2.0
    W = np.array([[0.0, 12.0, 0.0, 0.0, 0.0, 0.0],          # pressed into the arm
                  [0.0, -12.0, 0.0, 0.0, 0.0, 0.0],         # pulled away
                  [6.0, 0.0, -5.0, 0.25, 0.0, 0.2],
                  [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    sol = solve(model, W)
    assert sol.converged.all()
    for i, w in enumerate(W):
        fe.restore({})
        ref = fh.solve_wrench(fe, w, W_pre=model.W_pre)
        peak = np.abs(ref.normal_forces).max()
        rmse = np.sqrt(np.mean((sol.forces[i] - ref.normal_forces) ** 2))
        assert rmse < 0.02 * peak, (w, sol.forces[i], ref.normal_forces)
        S = np.array([1, 1, 1, 0.045, 0.045, 0.045])
        assert np.linalg.norm((sol.u[i] - ref.u) * S) < 0.03 * np.linalg.norm(ref.u * S) + 2e-6
    # the neo-Hookean layer is stiffer pushed than pulled: the +y push moves less
    assert abs(sol.u[0, 1]) < abs(sol.u[1, 1])


def test_second_build_reads_the_cache(identified):
    from phri_spring.workflows.common import coupled_model

    model, _, cache, cfg = identified
    with pytest.MonkeyPatch.context() as mp:
        cached_identification_only(mp)
        again = coupled_model(cfg, cache_dir=cache, level=1)
    assert again.reduction.info["source"] == "cache"
    for name, arr in model.reduction.arrays().items():
        np.testing.assert_array_equal(getattr(again.reduction, name), arr)
    W = np.array([1.0, 8.0, -2.0, 0.1, 0.05, -0.1])
    np.testing.assert_array_equal(Solver(again).forces(W), Solver(model).forces(W))


def test_simulate_cli_runs_the_neo_hookean_arm(identified, tmp_path, monkeypatch):
    _, _, cache, _ = identified
    cached_identification_only(monkeypatch, cache)
    # the CLI builds the linear part at the shipped level: its identification is at level 1
    cfg = write_yaml(tmp_path, _raw())
    t = np.arange(0, 1.0, 0.01)
    log = tmp_path / "log.csv"
    pd.DataFrame({"time": t, "Fx": 0 * t, "Fy": -10 * np.sin(np.pi * t), "Fz": 2 * t,
                  "Mx": 0 * t, "My": 0 * t, "Mz": 0.1 * t}).to_csv(log, index=False)
    out = tmp_path / "forces.csv"
    res = run_phri("simulate", cfg, log, "--arm", "coupled", "-o", out)
    assert res.exit_code == 0, stderr_of(res)
    assert "neo-Hookean continuum" in stderr_of(res)
    df = pd.read_csv(out)
    assert len(df) == len(t) and np.isfinite(df.filter(like="_N").to_numpy()).all()


def _per_patch_moduli(raw):
    """E converted per patch from indenter values that differ (needs the fe extra)."""
    pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")
    del raw["tissue"]["continuum"]["young_modulus"]
    raw["tissue"]["stiffness"] = {"per_angle": [300.0, 350.0, 400.0, 450.0, 500.0]}
    raw["tissue"]["continuum"]["spread"] = "per_patch"


@pytest.mark.parametrize("edit, key", [
    (lambda r: r["cuff"].update(stiffness=1e5), "cuff.stiffness"),
    (lambda r: r.setdefault("interface", {}).update(friction_coefficient=0.5),
     "interface.friction_coefficient"),
    (lambda r: r["tissue"]["continuum"].update(law="mooney"), "tissue.continuum.law"),
    (lambda r: r["tissue"]["continuum"].update(max_force=-1.0), "tissue.continuum.max_force"),
    (lambda r: r["tissue"]["continuum"].update(max_moment=float("nan")),
     "tissue.continuum.max_moment"),
    (lambda r: r["tissue"]["continuum"].update(surface_stiffness="k.npz"),
     "tissue.continuum.surface_stiffness"),
    (_per_patch_moduli, "tissue.continuum.spread"),
])
def test_configs_it_is_not_identified_for_are_one_line(tmp_path, edit, key):
    raw = _raw()
    edit(raw)
    cfg = write_yaml(tmp_path, raw)
    np.savez(tmp_path / "k.npz", K=np.eye(30), labels=np.array([f"A{i}" for i in range(5)]))
    log = _short_log(tmp_path)
    out = tmp_path / "forces.csv"
    res = run_phri("simulate", cfg, log, "--arm", "coupled", "-o", out)
    assert_one_line_error(res, key, code=1)
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cfg.yaml", "k.npz", "log.csv"]


def test_a_range_the_fe_cannot_reach_is_one_line(tmp_path, monkeypatch):
    pytest.importorskip("felupe", reason="the hyper extra (felupe) is not installed")
    pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")
    from phri_spring.io.cache import hyper_reduction as store

    monkeypatch.setenv("PHRI_SPRING_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(store, "IDENTIFY_LEVEL", 1)
    cfg = write_yaml(tmp_path, _raw(max_force=5000.0, max_moment=200.0))
    log = _short_log(tmp_path)
    res = run_phri("simulate", cfg, log, "--arm", "coupled", "-o", tmp_path / "f.csv")
    assert_one_line_error(res, str(cfg), "tissue.continuum.max_force", "identification", code=1)
    assert not (tmp_path / "f.csv").exists()
    assert not list((tmp_path / "cache").glob("neo-hookean-*"))


def test_missing_felupe_is_one_line_naming_the_extra(tmp_path, monkeypatch):
    pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")
    real = builtins.__import__

    def no_felupe(name, *args, **kwargs):
        if name == "felupe" or name.startswith("felupe."):
            raise ImportError("No module named 'felupe'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_felupe)
    monkeypatch.setenv("PHRI_SPRING_CACHE", str(tmp_path / "cache"))
    cfg = write_yaml(tmp_path, _raw())
    log = _short_log(tmp_path)
    res = run_phri("simulate", cfg, log, "--arm", "coupled", "-o", tmp_path / "f.csv")
    assert_one_line_error(res, "hyper", code=2)


def test_monte_carlo_that_would_identify_per_draw_is_refused(tmp_path, monkeypatch):
    monkeypatch.setenv("PHRI_SPRING_CACHE", str(tmp_path / "cache"))
    cfg = write_yaml(tmp_path, _raw())
    log = _short_log(tmp_path, rows=2)
    # a strap tension that scatters changes the preload, so every draw is another model
    res = run_phri("simulate", cfg, log, "--arm", "coupled", "--uncertainty", 20,
                   "--uncertainty-sd", "tension=1.5", "-o", tmp_path / "f.csv")
    assert_one_line_error(res, "tissue.continuum.law", "every draw", code=2)
    assert not (tmp_path / "f.csv").exists()
