"""``tissue.continuum.law: ogden`` end to end: the FE's material, identification, exponent, bad input.

References computed independently of the reduced model:

* the one-term Ogden solid with alpha = 2 is the neo-Hookean solid (its energy
  (2 mu / alpha^2)(sum lambda_i^alpha - 3) is mu/2 (I1 - 3) there): the FE with felupe's
  automatically differentiated Ogden law gives felupe's hand-written NeoHooke answer;
* the reduced model against the Ogden FE it was identified from, under load control at
  wrenches on none of its rays (as tests/workflows/test_hyper_arm.py does for the neo-Hookean law),
  on a small cuff (one row of five patches, coarsest mesh) with the shipped 96 rays: the
  Ogden layer (alpha 8) is far more nonlinear than the neo-Hookean one, and 40 rays (120
  poses for 84 coefficients) overfit it (patch forces 4 % RMSE off, measured);
* the exponent identified from the indenter curve: the punch FE is checked in
  tests/physics/hyperelastic/test_fe_punch_ogden.py; here, that its inputs are the indenter test's (punch
  radius, pain-threshold force) and that it is cached.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from phri_spring.io.config import config_from_dict
from phri_spring.physics.contact.solver import solve

from support.helpers import (REPO, assert_one_line_error, cached_identification_only, run_phri,
                      small_human_cuff, stderr_of, write_yaml)

HUMAN = REPO / "configs" / "human_upper_arm.yaml"
ALPHA = 8.0


def _raw(**continuum):
    return small_human_cuff(**{**dict(law="ogden", ogden_alpha=ALPHA, max_force=20.0,
                                      max_moment=0.6), **continuum})


def _log(folder, rows=1):
    path = folder / "log.csv"
    t = np.arange(rows) * 0.01
    pd.DataFrame({"time": t, "Fx": 0 * t, "Fy": -8 * np.sin(np.pi * t) - 1.0, "Fz": t,
                  "Mx": 0 * t, "My": 0 * t, "Mz": 0.05 + 0 * t}).to_csv(path, index=False)
    return path


def _needs_fe():
    pytest.importorskip("felupe", reason="the hyper extra (felupe) is not installed")
    pytest.importorskip("tensortrax", reason="the hyper extra (tensortrax) is not installed")
    pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")


def test_ogden_with_alpha_2_is_the_neo_hookean_fe():
    _needs_fe()
    from phri_spring.physics.hyperelastic import fe as fh
    from phri_spring.physics.cuff.geometry import cuff_geometry

    g = cuff_geometry([0.0], 0.045, 0.025, 75.0, 35.0, 5)
    u = np.array([0.001, -0.006, 0.0005, 0.02, -0.01, 0.05])
    neo = fh.patch_forces(fh.build_hyper_cuff(g, 0.025, 30e3, 0.45, level=1), u, preload=False)
    og = fh.patch_forces(fh.build_hyper_cuff(g, 0.025, 30e3, 0.45, level=1, law="ogden",
                                             ogden_alpha=2.0), u, preload=False)
    peak = np.abs(neo.normal_forces).max()
    np.testing.assert_allclose(og.normal_forces, neo.normal_forces, rtol=0, atol=1e-8 * peak)
    np.testing.assert_allclose(og.wrench, neo.wrench, rtol=0,
                               atol=1e-8 * np.abs(neo.wrench).max())
    # and a larger exponent stiffens the layer: the same pose takes more force
    stiff = fh.patch_forces(fh.build_hyper_cuff(g, 0.025, 30e3, 0.45, level=1, law="ogden",
                                                ogden_alpha=ALPHA), u, preload=False)
    assert np.linalg.norm(stiff.wrench[:3]) > 1.1 * np.linalg.norm(neo.wrench[:3])


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    """(model, its Ogden FE, the cache folder, config): identified once for the module."""
    _needs_fe()
    from phri_spring.io.cache import hyper_reduction as store
    from phri_spring.physics.hyperelastic import fe as fh
    from phri_spring.workflows.common import coupled_model

    cache = tmp_path_factory.mktemp("cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(store, "IDENTIFY_LEVEL", 1)
        cfg = config_from_dict(_raw(), path=HUMAN, base_dir=HUMAN.parent)
        model = coupled_model(cfg, cache_dir=cache, level=1)
    fe = fh.build_hyper_cuff(cfg.geometry(), cfg.continuum_thickness,
                             cfg.continuum_young_modulus, cfg.poisson_ratio, level=1,
                             delta=model.linear.delta, law="ogden", ogden_alpha=ALPHA)
    return model, fe, cache, cfg


def test_identified_ogden_model_matches_its_fe_off_its_rays(identified):
    from phri_spring.physics.hyperelastic import fe as fh

    model, fe, cache, _ = identified
    assert model.continuum_law == "ogden"
    assert model.reduction.info["source"] == "identified"
    assert model.reduction.info["ogden_alpha"] == ALPHA
    assert list(cache.glob("ogden-*.npz")) and not list(cache.glob("neo-hookean-*"))
    W = np.array([[0.0, 12.0, 0.0, 0.0, 0.0, 0.0],
                  [0.0, -12.0, 0.0, 0.0, 0.0, 0.0],
                  [6.0, 0.0, -5.0, 0.25, 0.0, 0.2]])
    sol = solve(model, W)
    assert sol.converged.all()
    S = np.array([1, 1, 1, 0.045, 0.045, 0.045])
    for i, w in enumerate(W):
        fe.restore({})
        ref = fh.solve_wrench(fe, w, W_pre=model.W_pre)
        peak = np.abs(ref.normal_forces).max()
        rmse = np.sqrt(np.mean((sol.forces[i] - ref.normal_forces) ** 2))
        assert rmse < 0.02 * peak, (w, sol.forces[i], ref.normal_forces)
        # the bound on the displacement (rotations scaled by the radius)
        assert np.linalg.norm((sol.u[i] - ref.u) * S) < 0.05 * np.linalg.norm(ref.u * S)


def test_reduction_keys_tell_the_laws_apart():
    from phri_spring.io.cache.hyper_reduction import reduction_key
    from phri_spring.physics.cuff.geometry import cuff_geometry

    g = cuff_geometry([0.0], 0.045, 0.025, 75.0, 35.0, 5)
    args = (g, 0.025, 30e3, 0.45, (15.0, "hoop", None, None))
    kw = dict(max_force=70.0, max_moment=4.0, level=2, rays=96, patch_gap=None)
    keys = {reduction_key(*args, **kw), reduction_key(*args, law="ogden", ogden_alpha=8.0, **kw),
            reduction_key(*args, law="ogden", ogden_alpha=8.5, **kw)}
    assert len(keys) == 3


def test_simulate_cli_names_the_ogden_law(identified, tmp_path, monkeypatch):
    _, _, cache, _ = identified
    cached_identification_only(monkeypatch, cache)
    cfg = write_yaml(tmp_path, _raw())
    out = tmp_path / "forces.csv"
    res = run_phri("simulate", cfg, _log(tmp_path, 50), "--arm", "coupled", "-o", out)
    assert res.exit_code == 0, stderr_of(res)
    assert "Ogden continuum (alpha 8" in stderr_of(res)
    assert np.isfinite(pd.read_csv(out).filter(like="_N").to_numpy()).all()


def test_exponent_from_the_indenter_curve_uses_the_indenter_test_and_is_cached(
        tmp_path, monkeypatch):
    """Without ogden_alpha, the exponent comes from tissue.stiffening through the punch FE
    (replaced here by a recorder: tests/physics/hyperelastic/test_fe_punch_ogden.py checks the FE itself), with
    the indenter's radius and the force where the pain threshold is reached under it."""
    from phri_spring.physics.hyperelastic import punch_ogden as fe_punch_ogden
    from phri_spring.workflows.hyper_arm import ogden_exponent

    calls = []

    def fake(beta, radius, thickness, E, nu, force_max, **kw):
        calls.append((beta, radius, thickness, E, nu, force_max))
        return 9.5

    monkeypatch.setattr(fe_punch_ogden, "ogden_alpha_from_stiffening", fake)
    raw = _raw(ogden_alpha=None)
    raw["tissue"]["continuum"].pop("ogden_alpha")
    raw["tissue"]["stiffening"] = 115.0
    cfg = config_from_dict(raw, path=HUMAN, base_dir=HUMAN.parent)
    E = cfg.continuum_young_modulus
    a = cfg.indenter_diameter / 2
    for _ in range(2):
        assert ogden_exponent(cfg, E, cache_dir=tmp_path) == (9.5, "tissue.stiffening")
    assert len(calls) == 1                     # the second call read the cache
    beta, radius, thickness, E_used, nu, force_max = calls[0]
    assert (beta, radius, thickness, E_used, nu) == (115.0, a, cfg.continuum_thickness, E,
                                                    cfg.poisson_ratio)
    assert force_max == pytest.approx(cfg.pain_threshold_kpa * 1e3 * np.pi * a * a, rel=1e-12)


def test_an_indenter_curve_no_exponent_matches_is_one_line(tmp_path, monkeypatch):
    from phri_spring.physics.hyperelastic import punch_ogden as fe_punch_ogden

    def fake(*a, **k):
        raise ValueError("the Ogden law reaches beta 20-400 1/m on this layer and punch, "
                         "got 5000")

    monkeypatch.setattr(fe_punch_ogden, "ogden_alpha_from_stiffening", fake)
    monkeypatch.setenv("PHRI_SPRING_CACHE", str(tmp_path / "cache"))
    raw = _raw()
    raw["tissue"]["continuum"].pop("ogden_alpha")
    raw["tissue"]["stiffening"] = 5000.0
    cfg = write_yaml(tmp_path, raw)
    res = run_phri("simulate", cfg, _log(tmp_path), "--arm", "coupled", "-o",
                   tmp_path / "f.csv")
    assert_one_line_error(res, str(cfg), "tissue.stiffening", "Ogden", code=1)
    assert not (tmp_path / "f.csv").exists()


@pytest.mark.parametrize("edit, key", [
    (lambda r: r["tissue"]["continuum"].update(law="neo_hookean"),
     "tissue.continuum.ogden_alpha"),                       # alpha for another law
    (lambda r: r["tissue"]["continuum"].update(ogden_alpha=0.0), "tissue.continuum.ogden_alpha"),
    (lambda r: r["tissue"]["continuum"].update(ogden_alpha=55.0), "tissue.continuum.ogden_alpha"),
    (lambda r: r["tissue"]["continuum"].update(ogden_alpha="ten"), "tissue.continuum.ogden_alpha"),
    (lambda r: (r["tissue"]["continuum"].pop("ogden_alpha"), r["tissue"].pop("stiffening")),
     "tissue.continuum.ogden_alpha"),                       # no alpha, no curve to take it from
    (lambda r: (r["tissue"]["continuum"].pop("ogden_alpha"),
                r["tissue"].update(stiffening={"per_angle": [50, 60, 70, 80, 90]})),
     "tissue.stiffening"),                                  # one exponent for the layer
    (lambda r: r["cuff"].update(stiffness=1e5), "cuff.stiffness"),
])
def test_bad_ogden_configs_are_one_line(tmp_path, monkeypatch, edit, key):
    monkeypatch.setenv("PHRI_SPRING_CACHE", str(tmp_path / "cache"))
    raw = _raw()
    edit(raw)
    cfg = write_yaml(tmp_path, raw)
    out = tmp_path / "forces.csv"
    res = run_phri("simulate", cfg, _log(tmp_path), "--arm", "coupled", "-o", out)
    assert_one_line_error(res, key, code=1)
    assert not out.exists()
    assert not (tmp_path / "cache").exists()            # refused before any FE ran


def test_the_identification_shows_its_progress_on_a_terminal(tmp_path, monkeypatch):
    """The identification takes minutes: on a terminal, phri shows its rays on stderr (off
    when stderr is not a terminal, as every progress line). The FE is replaced by a
    recorder that reports two rays and then fails, so no FE runs."""
    from phri_spring.errors import ConfigError
    from phri_spring.io.cache import hyper_reduction as store

    def fake(*args, progress=None, **kwargs):
        progress(1, 2)
        progress(2, 2)
        raise ConfigError("stopped after the rays", key="tissue.continuum.max_force")

    monkeypatch.setattr(store, "load_or_identify", fake)
    monkeypatch.setenv("PHRI_SPRING_CACHE", str(tmp_path / "cache"))
    cfg = write_yaml(tmp_path, _raw())
    for terminal in (True, False):
        monkeypatch.setattr("phri_cli._common.progress_enabled", lambda flag: terminal)
        res = run_phri("simulate", cfg, _log(tmp_path), "--arm", "coupled", "-o",
                       tmp_path / "f.csv")
        err = stderr_of(res)
        assert res.exit_code == 1 and "stopped after the rays" in err
        shown = "identifying the hyperelastic tissue model" in err and "(2 / 2 rays)" in err
        assert shown == terminal, err


def test_an_indenter_fe_that_fails_is_one_line_naming_the_exponent(tmp_path, monkeypatch):
    """The indenter FE that identifies alpha stops before the fit range (an element
    inverts): one line that says to give tissue.continuum.ogden_alpha instead."""
    from phri_spring.errors import ConvergenceError
    from phri_spring.physics.hyperelastic import punch_ogden as fe_punch_ogden

    def fake(*a, **k):
        raise ConvergenceError("the punch curve stopped at 4.2 mm (element inverted)")

    monkeypatch.setattr(fe_punch_ogden, "ogden_alpha_from_stiffening", fake)
    monkeypatch.setenv("PHRI_SPRING_CACHE", str(tmp_path / "cache"))
    raw = _raw()
    raw["tissue"]["continuum"].pop("ogden_alpha")
    cfg = write_yaml(tmp_path, raw)
    res = run_phri("simulate", cfg, _log(tmp_path), "--arm", "coupled", "-o",
                   tmp_path / "f.csv")
    assert_one_line_error(res, str(cfg), "tissue.continuum.ogden_alpha", "4.2 mm", code=1)
    assert not (tmp_path / "f.csv").exists()


def test_a_reduction_that_misses_its_held_out_rays_is_refused(tmp_path, monkeypatch):
    """A fit whose held-out patch forces are more than 5 % off (replaced here: no FE runs)
    is refused in one line naming the range; the identification is cached all the same."""
    _needs_fe()
    from phri_spring.io.cache import hyper_reduction as store
    from phri_spring.physics.hyperelastic import reduced as hr

    def fake(cuff, linear, *, max_force, max_moment, rays, progress=None, **kw):
        n, K = cuff.geometry.n, len(hr.EXPONENTS)
        return hr.HyperReduction(scale=np.ones(6), wrench=np.zeros((K, 6)),
                                 normal=np.zeros((K, n)), patch=np.zeros((K, 6 * n)),
                                 range_map=np.eye(6), info=dict(held_out_normal_pct=9.3))

    monkeypatch.setattr(hr, "identify", fake)
    monkeypatch.setattr(store, "IDENTIFY_LEVEL", 1)
    monkeypatch.setenv("PHRI_SPRING_CACHE", str(tmp_path / "cache"))
    cfg = write_yaml(tmp_path, _raw())
    res = run_phri("simulate", cfg, _log(tmp_path), "--arm", "coupled", "-o",
                   tmp_path / "f.csv")
    assert_one_line_error(res, str(cfg), "tissue.continuum.max_force", "9.3 %", code=1)
    assert not (tmp_path / "f.csv").exists()
    assert list((tmp_path / "cache").glob("ogden-*.npz"))
