"""``--arm coupled`` end to end: config, built-in FE or a user's export, simulate, compare,
stiffness, and every bad continuum input (one line, exit status, nothing written).

The rigid-cuff check ties the contact solver to the FE: with a rigid cuff held by a
preload that keeps every patch pressing, the coupled model's force increments for the
six unit wrenches are the FE's rigid-cuff response (T^T K T) u = W, f = N T u
(``rigid_cuff_fe.rigid_cuff_patch_forces``, written independently of the solver), which
benchmarks/FE_CONVERGENCE.md validates against a finer direct FE (<= 0.97 % RMSE).
"""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd
import pytest
import yaml
from phri_spring.io.config import load_config
from phri_spring.physics.continuum import tissue as fe_tissue
from phri_spring.physics.continuum.coupled import build_coupled_model
from phri_spring.physics.contact.solver import solve
from phri_spring.workflows.common import geometry_from_config, model_from_config
from phri_spring.workflows.stiffness.matrix import interface_stiffness_report

from references import rigid_cuff_fe
from support.helpers import HARMONY_CONFIG, run_phri as run, stderr_of
from support.coupled_reference import kernel_K as _kernel_K


def one_line_error(res, code, *needles):
    assert res.exit_code == code, (res.exit_code, stderr_of(res))
    err = stderr_of(res).strip()
    assert "\n" not in err and "Traceback" not in err and "internal error" not in err, err
    for n in needles:
        assert n in err, err


@pytest.fixture(scope="module")
def harmony():
    return yaml.safe_load(open(HARMONY_CONFIG))


@pytest.fixture
def export(tmp_path, harmony):
    """A config using a user's surface-stiffness export (a kernel-coupled 6n x 6n K)."""
    cfg = load_config(HARMONY_CONFIG)
    g = geometry_from_config(cfg)
    npz = tmp_path / "my_fe.npz"
    np.savez(npz, K=_kernel_K(g, dofs=6), labels=np.array(g.labels))
    data = copy.deepcopy(harmony)
    data["tissue"]["continuum"] = {"thickness": 0.02, "surface_stiffness": "my_fe.npz"}
    path = tmp_path / "cfg.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_rigid_cuff_force_increments_are_the_fe_rigid_cuff_response():
    g = geometry_from_config(load_config(HARMONY_CONFIG))
    for t, nu in ((0.01, 0.30), (0.03, 0.45)):
        ops = fe_tissue.condensed_surface_operators(g, t, 1e5, nu, level=1)
        model = build_coupled_model(g, ops.K, np.inf, poisson_ratio=nu, strap_tension=3000.0,
                                    normal_output=ops.N)
        W = np.vstack([np.zeros(6), np.diag([1.0, 1.0, 1.0, 0.05, 0.05, 0.05])])
        sol = solve(model, W)
        assert sol.converged.all() and sol.contact.all()
        for k in range(6):
            ref = rigid_cuff_fe.rigid_cuff_patch_forces(ops.K, g, W[k + 1], ops.N)
            np.testing.assert_allclose(sol.forces[k + 1] - sol.forces[0], ref, rtol=0,
                                       atol=1e-9 * np.abs(ref).max())


def test_simulate_coupled_with_an_export_and_shear_columns(export, tmp_path):
    out = tmp_path / "forces.csv"
    res = run("simulate", export, "examples/wrench_log.csv", "-o", out, "--arm", "coupled",
              "--shear", "--decimals", "-1")
    assert res.exit_code == 0, stderr_of(res)
    table = pd.read_csv(out)
    assert table["converged"].all()
    assert "coupled arm" in stderr_of(res)
    cols = [c for c in table.columns if "_shear_" in c]
    assert cols[:2] == ["A0_shear_axial_N", "A0_shear_circumferential_N"] and len(cols) == 42
    # the same numbers as the library
    cfg = load_config(export)
    model = model_from_config(cfg, "coupled")
    from phri_spring.io.logs import read_wrench_log
    from phri_spring.workflows.simulate import simulate

    t, w = read_wrench_log("examples/wrench_log.csv")
    lib = simulate(cfg, w, time=t, arm="coupled", model=model, shear=True)
    np.testing.assert_allclose(table.loc[:, "A0":"C6"].to_numpy(), lib.forces, rtol=0,
                               atol=1e-12)
    np.testing.assert_allclose(table["C3_shear_axial_N"], lib.extras["C3_shear_axial_N"],
                               rtol=0, atol=1e-12)


def test_compare_three_arms_and_stiffness(export, tmp_path):
    res = run("compare", export, "examples/experiment/manifest.yaml", "-o", tmp_path / "cmp",
              "--arms", "rigid,compliant,coupled", "--no-figures", "-q")
    assert res.exit_code == 0, stderr_of(res)
    rmse = pd.read_csv(tmp_path / "cmp" / "rmse.csv")
    assert set(rmse["arm"]) == {"rigid", "compliant", "coupled"}
    rep = interface_stiffness_report(load_config(export), "coupled")
    K = np.asarray(rep.K)
    np.testing.assert_allclose(K, K.T, rtol=0, atol=1e-9 * np.abs(K).max())
    res = run("stiffness", export, "--arm", "coupled", "--json")
    assert res.exit_code == 0, stderr_of(res)


def test_builtin_fe_through_the_cli(tmp_path, harmony, monkeypatch):
    monkeypatch.setenv("PHRI_SPRING_CACHE", str(tmp_path / "cache"))
    data = copy.deepcopy(harmony)
    data["tissue"]["continuum"] = {"thickness": 0.015, "young_modulus": 8.0e4}
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(data))
    res = run("simulate", cfg, "examples/wrench_log.csv", "-o", tmp_path / "f.parquet",
              "--arm", "coupled")
    assert res.exit_code == 0, stderr_of(res)
    assert list((tmp_path / "cache").glob("*.npz"))          # built once, cached
    assert pd.read_parquet(tmp_path / "f.parquet")["converged"].all()


@pytest.mark.parametrize("edit, code, needles", [
    (lambda t: t.pop("continuum"), 1, ["tissue.continuum", "thickness"]),
    (lambda t: t["continuum"].update(thickness=0.045), 1, ["tissue.continuum.thickness",
                                                           "radius"]),
    (lambda t: t["continuum"].update(thickness=-0.01), 1, ["tissue.continuum.thickness"]),
    (lambda t: t["continuum"].update(thickness=0.0), 1, ["tissue.continuum.thickness"]),
    (lambda t: t["continuum"].update(young_modulus=0.0), 1, ["tissue.continuum.young_modulus"]),
    (lambda t: t["continuum"].update(young_modulus=-3e4), 1,
     ["tissue.continuum.young_modulus"]),
    (lambda t: t.update(poisson_ratio=0.5), 1, ["tissue.poisson_ratio", "0.5"]),
    (lambda t: t.update(poisson_ratio=0.6), 1, ["tissue.poisson_ratio"]),
    (lambda t: t["continuum"].update(tickness=1), 1, ["tickness", "did you mean 'thickness'"]),
    (lambda t: (t["continuum"].pop("young_modulus"), t.update(basis="element")), 1,
     ["tissue.continuum.young_modulus", "basis"]),
])
def test_bad_continuum_config(tmp_path, harmony, edit, code, needles):
    data = copy.deepcopy(harmony)
    data["tissue"]["continuum"] = {"thickness": 0.02, "young_modulus": 5e4}
    edit(data["tissue"])
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(data))
    out = tmp_path / "forces.csv"
    res = run("simulate", cfg, "examples/wrench_log.csv", "-o", out, "--arm", "coupled")
    one_line_error(res, code, "cfg.yaml", *needles)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cfg.yaml"]


@pytest.mark.parametrize("make, needles", [
    (lambda g: dict(K=-np.eye(6 * g.n), labels=np.array(g.labels)), ["positive definite"]),
    (lambda g: dict(K=np.triu(np.ones((3 * g.n,) * 2)) + 3 * g.n * np.eye(3 * g.n),
                    labels=np.array(g.labels)), ["symmetric"]),
    (lambda g: dict(K=np.eye(5), labels=np.array(g.labels)), ["shape"]),
    (lambda g: dict(K=np.eye(3 * g.n), labels=np.array(g.labels[::-1])), ["labels"]),
])
def test_bad_surface_stiffness_file(tmp_path, harmony, make, needles):
    g = geometry_from_config(load_config(HARMONY_CONFIG))
    np.savez(tmp_path / "k.npz", **make(g))
    data = copy.deepcopy(harmony)
    data["tissue"]["continuum"] = {"thickness": 0.02, "surface_stiffness": "k.npz"}
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(data))
    before = (tmp_path / "k.npz").read_bytes()
    res = run("simulate", tmp_path / "cfg.yaml", "examples/wrench_log.csv", "-o",
              tmp_path / "f.csv", "--arm", "coupled")
    one_line_error(res, 1, "k.npz", *needles)
    assert not (tmp_path / "f.csv").exists()
    assert (tmp_path / "k.npz").read_bytes() == before


def test_missing_surface_stiffness_file(tmp_path, harmony):
    data = copy.deepcopy(harmony)
    data["tissue"]["continuum"] = {"thickness": 0.02, "surface_stiffness": "missing.npz"}
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(data))
    res = run("simulate", tmp_path / "cfg.yaml", "examples/wrench_log.csv", "-o",
              tmp_path / "f.csv", "--arm", "coupled")
    one_line_error(res, 1, "missing.npz", "not found")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cfg.yaml"]


def test_missing_fe_extra_names_it(tmp_path, harmony, monkeypatch):
    import builtins

    real_import = builtins.__import__

    def no_skfem(name, *args, **kwargs):
        if name == "skfem" or name.startswith("skfem."):
            raise ImportError("No module named 'skfem'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_skfem)
    monkeypatch.setenv("PHRI_SPRING_CACHE", str(tmp_path / "cache"))
    data = copy.deepcopy(harmony)
    data["tissue"]["continuum"] = {"thickness": 0.02, "young_modulus": 5e4}
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(data))
    res = run("simulate", tmp_path / "cfg.yaml", "examples/wrench_log.csv", "-o",
              tmp_path / "f.csv", "--arm", "coupled")
    one_line_error(res, 2, "pip install -e .[fe]")
    assert not (tmp_path / "f.csv").exists()


def test_per_patch_spread_scales_each_patch_by_its_modulus(export, tmp_path):
    # a uniform indenter map: per_patch is the homogeneous layer; doubling one location's
    # indenter stiffness doubles that patch's own stiffness (K_ee scaled by s_e = 2 relative
    # to the others, the mean moving with it)
    data = yaml.safe_load(export.read_text())
    data["tissue"]["continuum"]["spread"] = "per_patch"
    cfg_path = tmp_path / "spread.yaml"
    cfg_path.write_text(yaml.safe_dump(data))
    W = np.array([[0.0, 0.0, 30.0, 0.0, 0.0, 0.0], [20.0, -10.0, 5.0, 0.5, 0.0, 0.2]])
    same = solve(model_from_config(load_config(export), "coupled"), W).forces
    np.testing.assert_allclose(solve(model_from_config(load_config(cfg_path), "coupled"),
                                     W).forces, same, rtol=0, atol=1e-12)
    data["tissue"]["stiffness"] = {lab: (8484.0 if lab == "B3" else 4242.0)
                                   for lab in load_config(export).labels}
    cfg_path.write_text(yaml.safe_dump(data))
    base = model_from_config(load_config(export), "coupled")
    scaled = model_from_config(load_config(cfg_path), "coupled")
    s = np.full(21, 4242.0)
    s[10] = 8484.0
    s /= s.mean()
    e = 10 * 6                                         # B3's first dof (6 dofs per patch)
    np.testing.assert_allclose(scaled.K_t[e:e + 6, e:e + 6], s[10] * base.K_t[e:e + 6, e:e + 6],
                               rtol=1e-12)
    np.testing.assert_allclose(scaled.K_t[:6, :6], s[0] * base.K_t[:6, :6], rtol=1e-12)


@pytest.mark.parametrize("nu", [0.46, 0.49, 0.499])
def test_poisson_ratio_above_the_fe_s_converged_range_is_refused(tmp_path, harmony, nu):
    """Above nu = 0.45 the built-in FE locks (its stiffness still changes by 7-8 % per mesh
    refinement at 0.49): one line naming the key and the limit, exit 1, nothing written,
    before any FE is built."""
    data = copy.deepcopy(harmony)
    data["tissue"]["poisson_ratio"] = nu
    data["tissue"]["continuum"] = {"thickness": 0.015, "young_modulus": 8.0e4}
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(data))
    out = tmp_path / "f.csv"
    res = run("simulate", cfg, "examples/wrench_log.csv", "-o", out, "--arm", "coupled")
    one_line_error(res, 1, "tissue.poisson_ratio", "0.45")
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["cfg.yaml"]
    with pytest.raises(ValueError, match="poisson_ratio"):
        fe_tissue.flat_punch_stiffness(0.02, 1.0, nu, level=1)


def test_poisson_ratio_above_0_45_is_fine_with_a_users_own_fe(export, tmp_path):
    """The limit is the built-in FE's: a user's surface stiffness with its modulus runs."""
    data = yaml.safe_load(export.read_text())
    data["tissue"]["poisson_ratio"] = 0.49
    data["tissue"]["continuum"]["young_modulus"] = 3.0e4
    export.write_text(yaml.safe_dump(data))
    res = run("simulate", export, "examples/wrench_log.csv", "-o", tmp_path / "f.csv",
              "--arm", "coupled")
    assert res.exit_code == 0, stderr_of(res)
