"""`phri stiffness` as a library: the interface stiffness at the load cell.

Expected values are computed here, independently of the code under test: the
cuff-frame stiffness K_s + sum_e k_e b_e b_e^T written out from the formulas of
docs/model.md sections 1-3 (all elements in contact at zero wrench under the hoop
preload), the load-cell map J = dW_cuff / dW_lc by finite differences of
``physics.loadcell.loadcell_to_cuff``, and the displacement of the load-cell point
from the solver's cuff displacement by rigid-body kinematics.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from phri_spring.errors import ConfigError, UsageError
from phri_spring.io.config import load_config
from phri_spring.physics.cuff.loadcell import loadcell_to_cuff
from phri_spring.physics.contact.solver import solve
from phri_spring.workflows.common import ARMS, model_from_config
from phri_spring.workflows.stiffness.matrix import (PEOPLE_UNITS, SI_UNITS, interface_stiffness_report,
                                             to_people_units)

from support.stiffness_reference import (CFG, cfg_of, fd_loadcell_map, loadcell_point_displacement, rotation_xyz, spec_cuff_stiffness)  # noqa: F401


# --------------------------------------------------------------------------- tests
@pytest.mark.parametrize("arm", ["compliant", "rigid"])
def test_K_equals_independent_computation(arm):
    cfg = cfg_of()
    rep = interface_stiffness_report(cfg, arm)
    K_cuff = spec_cuff_stiffness(CFG, arm)
    np.testing.assert_allclose(rep.K_cuff, K_cuff, rtol=1e-11, atol=1e-9 * np.abs(K_cuff).max())
    R = rotation_xyz(CFG["load_cell"]["euler_xyz_deg"])
    J = fd_loadcell_map(R, np.array(CFG["load_cell"]["position"]))
    Jinv = np.linalg.inv(J)
    K_lc = Jinv @ K_cuff @ Jinv.T
    np.testing.assert_allclose(rep.K, K_lc, rtol=1e-9, atol=1e-9 * np.abs(K_lc).max())
    assert rep.contacts == rep.elements == 21
    assert rep.torsion == pytest.approx(K_cuff[3, 3], rel=1e-12)


def test_K_symmetric_positive_definite():
    rep = interface_stiffness_report(cfg_of())
    np.testing.assert_array_equal(rep.K, rep.K.T)
    assert np.linalg.eigvalsh(rep.K)[0] > 0
    assert np.linalg.eigvalsh(rep.K_cuff)[0] > 0


@pytest.mark.parametrize("convention", ["robot_on_cuff", "cuff_on_robot"])
def test_finite_difference_through_the_solver(convention):
    """A small wrench dW at the load cell moves the load-cell point by K^-1 dW."""
    data = copy.deepcopy(CFG)
    data["load_cell"]["convention"] = convention
    cfg = cfg_of(data)
    rep = interface_stiffness_report(cfg)
    model = model_from_config(cfg, "compliant")
    R = rotation_xyz(CFG["load_cell"]["euler_xyz_deg"])
    p = np.array(CFG["load_cell"]["position"])
    s = 1.0 if convention == "robot_on_cuff" else -1.0
    rng = np.random.default_rng(3)
    for _ in range(4):
        dW = rng.normal(size=6) * np.array([0.5, 0.5, 0.5, 0.02, 0.02, 0.02])   # N, N*m
        W = loadcell_to_cuff(dW, R, p, s)
        sol = solve(model, np.vstack([np.zeros(6), W]))
        assert sol.converged.all() and sol.contact.all()       # no lift-off: exactly linear
        du = loadcell_point_displacement(sol.u[1] - sol.u[0], R, p)
        # the reading's sign flips the work-conjugate displacement too
        np.testing.assert_allclose(s * du, np.linalg.solve(rep.K, dW), rtol=1e-7,
                                   atol=1e-9 * np.abs(du).max())


def test_units_of_the_log_do_not_change_K():
    data = copy.deepcopy(CFG)
    data["load_cell"].update(force_unit="lbf", moment_unit="N*mm", convention="cuff_on_robot")
    a = interface_stiffness_report(cfg_of()).K
    b = interface_stiffness_report(cfg_of(data)).K
    np.testing.assert_allclose(b, a, rtol=1e-13, atol=1e-13 * np.abs(a).max())


def test_people_units_conversion():
    rep = interface_stiffness_report(cfg_of())
    Kp = rep.people_units()
    K = rep.K
    deg = math.pi / 180.0
    np.testing.assert_allclose(Kp[:3, :3], K[:3, :3] / 1000.0, rtol=1e-15)     # N/m -> N/mm
    np.testing.assert_allclose(Kp[:3, 3:], K[:3, 3:] * deg, rtol=1e-15)        # N/rad -> N/deg
    np.testing.assert_allclose(Kp[3:, :3], K[3:, :3] / 1000.0, rtol=1e-15)     # N*m/m -> N*m/mm
    np.testing.assert_allclose(Kp[3:, 3:], K[3:, 3:] * deg, rtol=1e-15)        # -> N*m/deg
    np.testing.assert_allclose(to_people_units(K), Kp)
    assert SI_UNITS[0][0] == "N/m" and SI_UNITS[0][5] == "N/rad"
    assert SI_UNITS[5][0] == "N*m/m" and SI_UNITS[5][5] == "N*m/rad"
    assert PEOPLE_UNITS[1][2] == "N/mm" and PEOPLE_UNITS[2][4] == "N/deg"
    assert PEOPLE_UNITS[4][1] == "N*m/mm" and PEOPLE_UNITS[3][3] == "N*m/deg"
    # a rotational stiffness of 1 N*m/rad is pi/180 N*m/deg; 1000 N/m is 1 N/mm
    np.testing.assert_allclose(rep.rotational_Nm_per_deg, rep.rotational * deg)
    np.testing.assert_allclose(rep.translational_N_per_mm, rep.translational / 1000.0)
    assert rep.torsion_Nm_per_deg == pytest.approx(rep.K_cuff[3, 3] * deg)


def test_principal_values_and_directions():
    rep = interface_stiffness_report(cfg_of())
    np.testing.assert_allclose(rep.translational, np.linalg.eigvalsh(rep.K[:3, :3]), rtol=1e-12)
    np.testing.assert_allclose(rep.rotational, np.linalg.eigvalsh(rep.K[3:, 3:]), rtol=1e-12)
    for lam, d in zip(rep.translational, rep.translational_directions):
        assert np.linalg.norm(d) == pytest.approx(1.0)
        np.testing.assert_allclose(rep.K[:3, :3] @ d, lam * d, atol=1e-9 * lam)


def test_to_dict_layout():
    rep = interface_stiffness_report(cfg_of(), "rigid")
    d = rep.to_dict()
    assert d["rows"] == ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
    assert d["columns"] == ["x", "y", "z", "rx", "ry", "rz"]
    assert np.array(d["K"]).shape == (6, 6) and np.array(d["units"]).shape == (6, 6)
    assert d["arm"] == "rigid" and d["name"] == "stiffness test cuff"
    assert d["principal"]["translational_N_per_mm"] == pytest.approx(
        list(np.array(d["principal"]["translational_N_per_m"]) / 1000.0))


def test_unknown_arm_is_a_usage_error():
    with pytest.raises(UsageError, match="--arm"):
        interface_stiffness_report(cfg_of(), "wooden")


def test_infinitely_stiff_rigid_arm_is_a_config_error():
    data = copy.deepcopy(CFG)
    data["cuff"]["stiffness"] = float("inf")
    with pytest.raises(ConfigError, match="cuff.stiffness"):
        interface_stiffness_report(cfg_of(data), "rigid")
    # the compliant arm is fine: tissue springs only
    rep = interface_stiffness_report(cfg_of(data), "compliant")
    assert np.isfinite(rep.K).all()


def test_handles_strap_runs():
    data = copy.deepcopy(CFG)
    data["strap"] = {"tension": 15.0, "model": "handles"}
    rep = interface_stiffness_report(cfg_of(data))
    assert rep.strap_model == "handles"
    assert 0 < rep.contacts <= 21
    assert np.linalg.eigvalsh(rep.K)[0] > 0


@settings(max_examples=25, deadline=None)
@given(pos=st.lists(st.floats(-0.15, 0.15), min_size=3, max_size=3),
       ang=st.lists(st.floats(-180, 180), min_size=3, max_size=3))
def test_load_cell_pose_properties(pos, ang):
    """Translational principal values do not depend on where the load cell is; the cuff-frame
    stiffness does not depend on the load cell at all; K maps back to it."""
    data = copy.deepcopy(CFG)
    data["load_cell"] = {"position": pos, "euler_xyz_deg": ang}
    rep = interface_stiffness_report(cfg_of(data))
    base = interface_stiffness_report(cfg_of())
    np.testing.assert_allclose(rep.K_cuff, base.K_cuff, rtol=1e-12, atol=1e-6)
    np.testing.assert_allclose(rep.translational, base.translational, rtol=1e-9)
    J = fd_loadcell_map(rotation_xyz(ang), np.array(pos))
    np.testing.assert_allclose(J @ rep.K @ J.T, rep.K_cuff, rtol=1e-8,
                               atol=1e-9 * np.abs(rep.K_cuff).max())


@pytest.mark.parametrize("name", ["harmony_upper_arm.yaml", "human_upper_arm.yaml"])
def test_bundled_configs(name):
    from support.helpers import REPO

    cfg = load_config(REPO / "configs" / name)
    for arm in ("compliant", "rigid"):
        rep = interface_stiffness_report(cfg, arm)
        assert rep.contacts == 21
        assert np.linalg.eigvalsh(rep.K)[0] > 0


def test_arms_are_those_of_common():
    assert {"compliant", "rigid"} <= set(ARMS)
