"""``phri simulate`` with ``interface.friction_coefficient`` (docs/model.md section 12).

The checks read only the output file and the geometry the config describes: every element
or patch reported with 0 N normal force carries 0 N tangential force, every tangential
force is within mu times its normal force, and the reported forces balance the wrench on
the cuff (computed here from the log with the load-cell transform of docs/model.md
section 5, not by the program). Bad values are one line, exit 1, nothing written.
"""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402


import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner

from phri_cli.main import phri
from phri_spring.io.config import load_config
from phri_spring.workflows.common import cuff_wrench

ROOT = REPO
HUMAN = ROOT / "configs" / "human_upper_arm.yaml"


def _config(tmp_path, mu, **tissue):
    raw = yaml.safe_load(HUMAN.read_text())
    raw.setdefault("interface", {})["friction_coefficient"] = mu
    # the preset's tissue stiffens (tissue.stiffening): these checks use its linear law
    # unless told otherwise (test_outputs_obey_the_laws runs both)
    raw["tissue"].pop("stiffening", None)
    raw["tissue"].update(tissue)
    path = tmp_path / "mu.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def _log(tmp_path, cfg_path, seed=0, m=400):
    """One-sided pushes on the cuff (forces through its origin, as the paper's weights:
    +y, +z, -z to 55.6 N and -y to 35 N, beyond which the strap's constant pull and friction
    cannot keep the cuff from coming off through its open side), then a random stretch,
    written as the load cell would read them."""
    cfg = load_config(cfg_path)
    A = cuff_wrench(cfg, np.eye(6))                 # row j: cuff wrench of unit reading j
    rng = np.random.default_rng(seed)
    k = m // 5
    up_down = np.concatenate([np.linspace(0, 1, k // 2), np.linspace(1, 0, k - k // 2)])
    W = np.zeros((m, 6))
    for i, (axis, peak) in enumerate([(1, 55.6), (2, 55.6), (2, -55.6), (1, -35.0)]):
        W[i * k:(i + 1) * k, axis] = peak * up_down
    walk = np.cumsum(rng.normal(size=(m - 4 * k, 6)), axis=0)
    W[4 * k:] = walk / np.abs(walk).max(axis=0) * np.array([5.0, 20.0, 20.0, 0.2, 0.2, 0.2])
    W_lc = np.linalg.solve(A.T, W.T).T
    df = pd.DataFrame(W_lc, columns=["Fx", "Fy", "Fz", "Mx", "My", "Mz"])
    df.insert(0, "time", np.arange(m) / 100.0)
    path = tmp_path / "log.csv"
    df.to_csv(path, index=False, float_format="%.17g")
    return path, W_lc


@pytest.mark.parametrize("arm, tissue", [("compliant", {}), ("rigid", {}), ("coupled", {}),
                                         ("compliant", {"stiffening": 115.0})],
                         ids=["compliant", "rigid", "coupled", "compliant-exponential"])
def test_outputs_obey_the_laws(tmp_path, arm, tissue):
    mu = 0.4
    cfg_path = _config(tmp_path, mu, **tissue)
    log, W_lc = _log(tmp_path, cfg_path)
    out = tmp_path / "forces.parquet"
    res = CliRunner().invoke(phri, ["simulate", str(cfg_path), str(log), "-o", str(out),
                                    "--arm", arm, "--shear"], catch_exceptions=False)
    assert res.exit_code == 0, res.output
    assert "friction" in res.output
    df = pd.read_parquet(out)
    cfg = load_config(cfg_path)
    geom = cfg.geometry()
    labels = geom.labels
    ok = df["converged"].to_numpy()
    assert ok.all()
    reported = df[list(labels)].to_numpy()[ok]
    # the normal force along n_e, read off each element's force in the cuff frame (the
    # coupled arm's label columns are its patches' traction integrals, which differ)
    Fe = np.stack([df[[f"{lab}_force_{a}_N" for a in "xyz"]].to_numpy()[ok] for lab in labels],
                  axis=1)
    fn = np.einsum("mei,ei->me", Fe, cfg.geometry().normals)
    fn[np.all(Fe == 0.0, axis=2)] = 0.0           # released: exactly nothing
    assert np.all(reported[fn == 0] == 0.0)       # and a released patch reads 0
    if arm != "coupled":
        np.testing.assert_allclose(fn, reported, rtol=0, atol=1e-12 * np.abs(reported).max())
    ta = df[[f"{lab}_shear_axial_N" for lab in labels]].to_numpy()[ok]
    tc = df[[f"{lab}_shear_circumferential_N" for lab in labels]].to_numpy()[ok]
    tn = np.hypot(ta, tc)
    assert (fn == 0).any()                      # something lifted off
    assert np.all(tn[fn == 0] == 0.0)
    assert np.all(tn <= mu * fn + 1e-9)
    # balance of forces: the normal along n_e (into the arm), axial along +x and
    # circumferential along n_e x x, against the wrench on the cuff plus the strap's
    normals = geom.normals
    circ = np.cross(normals, [1.0, 0.0, 0.0])
    F = (np.einsum("me,ei->mi", fn, normals) + ta.sum(axis=1)[:, None] * [1.0, 0.0, 0.0]
         + np.einsum("me,ei->mi", tc, circ))
    from phri_spring.workflows.common import model_from_config

    W_pre = model_from_config(cfg, arm).W_pre
    applied = cuff_wrench(cfg, W_lc)[ok, :3] + W_pre[:3]
    np.testing.assert_allclose(F, applied, rtol=0, atol=1e-9 * np.abs(applied).max())
    p = geom.points
    M = (np.cross(p[None], fn[:, :, None] * normals[None]).sum(axis=1)
         + np.cross(p[None], ta[:, :, None] * np.array([1.0, 0, 0])).sum(axis=1)
         + np.cross(p[None], tc[:, :, None] * circ[None]).sum(axis=1))
    if arm == "coupled":   # patches also carry moments about their centres (local axes)
        mn, ma, mc = (df[[f"{lab}_moment_{part}_Nm" for lab in labels]].to_numpy()[ok]
                      for part in ("normal", "axial", "circumferential"))
        assert np.all(np.abs(np.stack([mn, ma, mc]))[:, fn == 0] == 0.0)
        M = M + (np.einsum("me,ei->mi", mn, normals) + ma.sum(axis=1)[:, None] * [1.0, 0, 0]
                 + np.einsum("me,ei->mi", mc, circ))
    else:
        assert not any("_moment_" in c for c in df.columns)
    mom = cuff_wrench(cfg, W_lc)[ok, 3:] + W_pre[3:]
    np.testing.assert_allclose(M, mom, rtol=0, atol=1e-9 * np.abs(applied).max())


@pytest.mark.parametrize("value", [-0.2, "high", [0.5]])
def test_a_bad_coefficient_is_one_line_exit_1(tmp_path, value):
    cfg_path = _config(tmp_path, value)
    log, _ = _log(tmp_path, HUMAN, m=20)
    out = tmp_path / "forces.csv"
    res = CliRunner().invoke(phri, ["simulate", str(cfg_path), str(log), "-o", str(out)],
                             catch_exceptions=False)
    assert res.exit_code == 1
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "interface.friction_coefficient" in lines[0], res.output
    assert not out.exists()


def test_chunks_carry_the_loading_path(tmp_path):
    cfg_path = _config(tmp_path, 0.4)
    log, _ = _log(tmp_path, cfg_path)
    outs = []
    for rows in (37, 65536):
        out = tmp_path / f"f{rows}.parquet"
        res = CliRunner().invoke(phri, ["simulate", str(cfg_path), str(log), "-o", str(out),
                                        "--shear", "--chunk-rows", str(rows)],
                                 catch_exceptions=False)
        assert res.exit_code == 0, res.output
        outs.append(pd.read_parquet(out))
    num = outs[0].select_dtypes("number").columns
    np.testing.assert_allclose(outs[0][num].to_numpy(float), outs[1][num].to_numpy(float),
                               rtol=0, atol=1e-9)


def test_monte_carlo_draws_follow_their_own_path(tmp_path):
    cfg_path = _config(tmp_path, 0.4)
    log, _ = _log(tmp_path, cfg_path, m=200)
    outs = []
    for rows in (23, 65536):
        out = tmp_path / f"mc{rows}.csv"
        res = CliRunner().invoke(phri, ["simulate", str(cfg_path), str(log), "-o", str(out),
                                        "--uncertainty", "4", "--chunk-rows", str(rows)],
                                 catch_exceptions=False)
        assert res.exit_code == 0, res.output
        outs.append(pd.read_csv(out, comment="#"))
    num = outs[0].select_dtypes("number").columns
    np.testing.assert_allclose(outs[0][num].to_numpy(float), outs[1][num].to_numpy(float),
                               rtol=0, atol=1e-6)
