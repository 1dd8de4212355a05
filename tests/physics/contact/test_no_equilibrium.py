"""Why a sample with friction has no answer (docs/model.md section 12.7).

References are worked by hand:

- a full ring of equal elements under a pure torsion or a pure axial force keeps every
  normal force at the hoop's f0 (symmetry), so friction holds at most mu R n f0 of torsion
  and mu n f0 of axial force: beyond, the sample is flagged with the difference as its
  shortfall; below, it has an answer;
- the capacity disc sqrt(F_a^2 + (M_a/R)^2) <= mu sum f_n with numbers worked by hand;
- a cuff over 70 degrees of the arm pulled off through its open side: the pull is opposite
  to every element's push, so its distance from the pushes' cone is its own size;
- frictionless contact (mu = 0): every sample with an axial force is flagged, quickly.
"""

from support.helpers import REPO  # noqa: E402
import time

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from phri_spring.physics.cuff.geometry import cuff_geometry
from phri_spring.physics.springs.model import build_model
from phri_spring.physics.contact.no_equilibrium import (AXIAL, NONE, NOT_CONVERGED, PULL, REASONS,
                                                TORSION, arm_radius, explain,
                                                friction_shortfall)
from phri_spring.physics.contact.solver import solve

MU = 0.5
R = 0.045


def _ring(mu=MU, n=8, tension=20.0, law="linear", params=None):
    g = cuff_geometry([0.0], R, 0.025, 0.0, 360.0 / n, n)
    return build_model(g, np.full(n, 5e4), np.inf, shear_ratio=0.4, strap_tension=tension,
                       friction_coefficient=mu, law=law, law_parameters=params)


def test_capacity_disc_by_hand():
    # mu sum f_n = 0.5 * 40 = 20 N; R = 0.05 m
    r = np.array([[12.0, 0, 0, 0.8, 0, 0],      # (12, 16): |.| = 20: on the disc, held
                  [12.0, 0, 0, 0.9, 0, 0],      # (12, 18): torsion dominates
                  [-19.0, 0, 0, 0.5, 0, 0],     # (19, 10): axial dominates
                  [0.0, 0, 0, 0.0, 0, 0]])
    code, s_N, s_Nm = friction_shortfall(r, np.full(4, 40.0), MU, 0.05)
    assert list(code) == [NONE, TORSION, AXIAL, NONE]
    np.testing.assert_allclose(s_Nm[1], 0.9 - 0.05 * 16.0, rtol=1e-12)     # 16 = sqrt(400 - 144)
    np.testing.assert_allclose(s_N[2], 19.0 - np.sqrt(400.0 - 100.0), rtol=1e-12)
    assert np.isnan(s_N[[0, 1, 3]]).all() and np.isnan(s_Nm[[0, 2, 3]]).all()


@pytest.mark.parametrize("law, params", [("linear", None),
                                         ("exponential", {"stiffening": 115.0})])
def test_ring_torsion_and_axial_force_beyond_capacity(law, params):
    model = _ring(law=law, params=params)
    f0 = model.f0
    assert np.allclose(f0, f0[0])
    cap = MU * f0.sum()                         # N
    assert np.isclose(arm_radius(model.geometry), R)
    # torsion and axial force, each 0.9 then 1.2 of the capacity, back to 0 between
    W = np.zeros((8, 6))
    W[1, 3], W[3, 3] = 0.9 * cap * R, 1.2 * cap * R
    W[5, 0], W[7, 0] = -0.9 * cap, -1.2 * cap
    sol = solve(model, W)
    assert list(sol.converged) == [True] * 3 + [False] + [True] * 3 + [False]
    code, s_N, s_Nm = explain(model, W, sol.converged)
    assert code[3] == TORSION and code[7] == AXIAL
    assert (code[sol.converged] == NONE).all()
    np.testing.assert_allclose(s_Nm[3], 0.2 * cap * R, rtol=1e-9)
    np.testing.assert_allclose(s_N[7], 0.2 * cap, rtol=1e-9)
    assert np.isnan(s_N[3]) and np.isnan(s_Nm[7])


def test_pull_off_a_partial_cuff_beyond_the_strap():
    g = cuff_geometry([-0.025, 0.0, 0.025], R, 0.025, 75.0, 35.0, 3)     # 75 to 145 degrees
    model = build_model(g, np.full(g.n, 5e4), 2e5, strap_tension=10.0, friction_coefficient=MU)
    push = g.b[:, 1:3].mean(axis=0)
    pull = -push / np.linalg.norm(push)
    W = np.zeros((2, 6))
    W[1, 1:3] = 40.0 * pull - model.W_pre[1:3]     # with the strap's: 40 N straight off
    r = W[1] + model.W_pre
    assert np.all(g.b[:, 1:3] @ r[1:3] < 0)         # opposite to every push
    sol = solve(model, W)
    assert sol.converged[0] and not sol.converged[1]
    code, s_N, s_Nm = explain(model, W, sol.converged)
    assert code[1] == PULL
    np.testing.assert_allclose(s_N[1], np.linalg.norm(r[[1, 2, 4, 5]] * [1, 1, 1 / R, 1 / R]),
                               rtol=1e-6)


def test_frictionless_samples_with_an_axial_force_end_quickly():
    model = _ring(mu=0.0)
    rng = np.random.default_rng(1)
    W = np.zeros((400, 6))
    W[:, :3] = rng.uniform(-20, 20, (400, 3))
    W[::2, 0] = 0.0                      # half of them: no axial force, no torsion
    t0 = time.perf_counter()
    sol = solve(model, W)
    elapsed = time.perf_counter() - t0
    assert not sol.converged[1::2].any()
    code, s_N, _ = explain(model, W, sol.converged)
    assert (code[1::2] == AXIAL).all()
    np.testing.assert_allclose(s_N[1::2], np.abs(W[1::2, 0]), rtol=1e-9)
    # the others: the full ring holds any radial force by normal forces alone
    assert sol.converged[::2].all()
    assert np.allclose(sol.tangential[::2], 0.0)
    assert elapsed < 5.0


def test_not_converged_is_the_last_reason():
    model = _ring()
    W = np.zeros((1, 6))
    code, s_N, s_Nm = explain(model, W, np.array([False]))
    assert code[0] == NOT_CONVERGED and REASONS[code[0]] == "not converged"
    assert np.isnan(s_N[0]) and np.isnan(s_Nm[0])


def test_simulate_writes_the_reasons_and_the_summary_names_the_worst(tmp_path):
    import pandas as pd

    from phri_cli.main import phri
    from phri_spring.io.config import load_config
    from phri_spring.workflows.common import cuff_wrench

    root = REPO
    raw = yaml.safe_load((root / "configs" / "human_upper_arm.yaml").read_text())
    raw["interface"]["friction_coefficient"] = 0.5
    cfg_path = tmp_path / "mu.yaml"
    cfg_path.write_text(yaml.safe_dump(raw, sort_keys=False))
    cfg = load_config(cfg_path)
    # cuff wrenches: quiet, a torsion of 9 N*m (far beyond friction), an axial pull of 200 N
    W = np.zeros((6, 6))
    W[2, 3] = 9.0
    W[4, 0] = 200.0
    A = cuff_wrench(cfg, np.eye(6))
    W_lc = np.linalg.solve(A.T, W.T).T
    log = tmp_path / "log.csv"
    df = pd.DataFrame(W_lc, columns=["Fx", "Fy", "Fz", "Mx", "My", "Mz"])
    df.insert(0, "time", np.arange(6) / 100.0)
    df.to_csv(log, index=False, float_format="%.17g")
    for arm in ("compliant", "rigid"):
        out = tmp_path / f"{arm}.parquet"
        res = CliRunner().invoke(phri, ["simulate", str(cfg_path), str(log), "-o", str(out),
                                        "--arm", arm], catch_exceptions=False)
        assert res.exit_code == 0, res.output
        table = pd.read_parquet(out)
        reason = table["no_equilibrium_reason"].astype(str).to_numpy()
        ok = table["converged"].to_numpy()
        assert list(ok) == [True, True, False, True, False, True]
        assert reason[2] == "torsion beyond friction capacity"
        assert reason[4] == "axial force beyond friction capacity"
        assert (reason[ok] == "").all()
        assert table["no_equilibrium_shortfall_Nm"].to_numpy()[2] > 0
        assert table["no_equilibrium_shortfall_N"].to_numpy()[4] > 0
        assert "2 of 6 samples (33.3%) have no equilibrium" in res.output
        assert "worst: axial force beyond friction capacity at t = 0.04 s" in res.output \
            or "worst: torsion beyond friction capacity at t = 0.02 s" in res.output
    # without the key: the paper model's columns only
    raw["interface"].pop("friction_coefficient")
    cfg_path.write_text(yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "bonded.csv"
    res = CliRunner().invoke(phri, ["simulate", str(cfg_path), str(log), "-o", str(out)],
                             catch_exceptions=False)
    assert res.exit_code == 0, res.output
    assert not any("no_equilibrium" in c for c in pd.read_csv(out).columns)


# the coupled event solver's Newton overflows on its way to giving up on the sample beyond
# capacity (the coupled friction path is being reworked on another branch)
@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")
def test_coupled_ring_axial_force_beyond_capacity():
    # a coupled ring whose compliance couples no normal dof to a tangential one: an axial
    # force leaves every normal force at the strap's f0 (symmetry), so friction holds at
    # most mu n f0 of it, as for the spring ring
    from phri_spring.physics.continuum.coupled import build_coupled_model

    n = 8
    g = cuff_geometry([0.0], R, 0.025, 0.0, 360.0 / n, n)
    d2 = np.sum((g.points[:, None, :] - g.points[None, :, :]) ** 2, axis=-1)
    rot = np.diag([1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-3])
    C = 2e-5 * np.kron(np.eye(n), rot) + 1e-5 * np.kron(np.exp(-d2 / 0.03 ** 2), rot)
    model = build_coupled_model(g, np.linalg.inv(C), 2e5, strap_tension=20.0,
                                friction_coefficient=MU)
    bonded = solve(build_coupled_model(g, np.linalg.inv(C), 2e5, strap_tension=20.0),
                   np.zeros((1, 6)))
    cap = MU * bonded.forces.sum()
    W = np.zeros((4, 6))
    W[1, 0], W[3, 0] = 0.9 * cap, 1.2 * cap
    sol = solve(model, W)
    assert list(sol.converged) == [True, True, True, False]
    code, s_N, s_Nm = explain(model, W, sol.converged)
    assert list(code) == [NONE, NONE, NONE, AXIAL]
    np.testing.assert_allclose(s_N[3], 0.2 * cap, rtol=1e-6)


def test_the_capacity_of_a_coupled_arm_uses_its_bonded_normal_forces():
    # the reasons' capacity takes the normal forces of bonded ties (docs/model.md 12.7); the
    # coupled arm without friction runs its lift-off cone, which a push that lifts patches
    # off tells apart
    from phri_spring.physics.continuum.coupled import build_coupled_model
    from phri_spring.physics.contact.no_equilibrium import _bonded_normal_sum

    n = 8
    g = cuff_geometry([0.0], R, 0.025, 0.0, 360.0 / n, n)
    d2 = np.sum((g.points[:, None, :] - g.points[None, :, :]) ** 2, axis=-1)
    rot = np.diag([1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-3])
    C = 2e-5 * np.kron(np.eye(n), rot) + 1e-5 * np.kron(np.exp(-d2 / 0.03 ** 2), rot)
    K = np.linalg.inv(C)
    W = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0], [0.0, 200.0, 0.0, 0.0, 0.0, 0.0]])
    bonded = solve(build_coupled_model(g, K, 2e5, strap_tension=20.0, lift_off=False), W)
    released = solve(build_coupled_model(g, K, 2e5, strap_tension=20.0), W)
    assert (~bonded.contact[1]).any()          # the push lifts patches off
    assert abs(released.normal[1].sum() - bonded.forces[1].sum()) > 1e-3
    for model in (build_coupled_model(g, K, 2e5, strap_tension=20.0, friction_coefficient=MU),
                  build_coupled_model(g, K, 2e5, strap_tension=20.0)):
        np.testing.assert_allclose(_bonded_normal_sum(model, W), bonded.forces.sum(axis=1),
                                   rtol=1e-12)
