"""The physics of docs/model.md sections 1-5 against values derived by hand.

Every expected number below is derived in a comment from the spec, or computed
by ``reference_model`` (an independent implementation), never read back from
the package.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from support import reference_model as ref
from support.helpers import HARMONY_CONFIG, harmony_dict, harmony_geometry
from phri_spring.errors import ConfigError
from phri_spring.io.config import config_from_dict, load_config
from phri_spring.physics.cuff.geometry import cuff_geometry
from phri_spring.physics.cuff.loadcell import (cuff_to_loadcell, loadcell_to_cuff,
                                          rotation_from_euler_xyz)
from phri_spring.physics.springs.model import build_model
from phri_spring.physics.contact.solver import Solver, shear_forces, solve
from phri_spring.physics.springs.stiffness import indenter_to_element
from phri_spring.workflows.common import cuff_wrench, model_from_config

ETA_045 = 1.0 / (2.0 * 1.45)          # default shear ratio, nu = 0.45


def ring(count, start=0.0, radius=0.05, row_width=0.02, x=0.0):
    """One row at axial position x, ``count`` locations evenly spread over the full circle."""
    return cuff_geometry([x], radius, row_width, start, 360.0 / count, count)


# --------------------------------------------------------------------------- geometry
def test_harmony_geometry_by_hand():
    g = harmony_geometry()
    assert g.labels == tuple(f"{r}{j}" for r in "ABC" for j in range(7))   # row-major
    R, w = 0.045, 0.025
    for e, lab in enumerate(g.labels):
        x = {"A": -0.025, "B": 0.0, "C": 0.025}[lab[0]]
        th = math.radians(75.0 + 35.0 * int(lab[1:]))
        c, s = math.cos(th), math.sin(th)
        np.testing.assert_allclose(g.points[e], [x, R * c, R * s], atol=1e-15)
        np.testing.assert_allclose(g.normals[e], [0.0, -c, -s], atol=1e-15)
        # p x n with p = (x, Rc, Rs), n = -(0, c, s):
        #   (Rc(-s) - Rs(-c), Rs*0 - x(-s), x(-c) - Rc*0) = (0, x s, -x c)
        np.testing.assert_allclose(g.b[e], [0.0, -c, -s, 0.0, x * s, -x * c], atol=1e-15)
    # A_e = w R radians(35) = 0.025 * 0.045 * 0.6108652 = 6.872234e-4 m^2
    np.testing.assert_allclose(g.areas, 6.872233929727672e-4, rtol=1e-12)
    np.testing.assert_allclose(g.areas, w * R * math.radians(35.0), rtol=1e-12)


def test_angular_width_defaults_to_step_and_can_be_set():
    g = cuff_geometry([0.0], 0.05, 0.02, 10.0, 40.0, 3, 25.0)
    np.testing.assert_allclose(g.areas, 0.02 * 0.05 * math.radians(25.0), rtol=1e-12)
    np.testing.assert_allclose(np.degrees(g.theta), [10.0, 50.0, 90.0], atol=1e-12)


# --------------------------------------------------------------------------- springs
def test_indenter_conversion_harmony_by_hand():
    # A_e = 0.025 * 0.045 * 35 pi/180, A_ind = pi 0.009^2 / 4
    # A_e / A_ind = (0.025 * 0.045 * 35 / 180) * 4 / 0.009^2 = 0.000875 / 0.000081 = 875/81
    # k_t = 4242 * 875 / 81 = 45824.074 N/m
    k_hand = 4242.0 * 875.0 / 81.0
    assert k_hand == pytest.approx(45824.074074, rel=1e-9)
    area = 0.025 * 0.045 * math.radians(35.0)
    assert float(indenter_to_element(4242.0, area, 0.009)) == pytest.approx(k_hand, rel=1e-12)
    # the same through the config: with an infinitely stiff cuff the compliant
    # element stiffness is the tissue's alone
    cfg = harmony_dict()
    cfg["cuff"]["stiffness"] = math.inf
    model = model_from_config(config_from_dict(cfg), "compliant")
    np.testing.assert_allclose(model.k, k_hand, rtol=1e-12)
    # basis: element uses the value as given
    cfg["tissue"]["basis"] = "element"
    model = model_from_config(config_from_dict(cfg), "compliant")
    np.testing.assert_allclose(model.k, 4242.0, rtol=1e-12)
    # another indenter diameter: area ratio scales with 1/d^2
    cfg["tissue"]["basis"] = "indenter"
    cfg["tissue"]["indenter_diameter"] = 0.018
    model = model_from_config(config_from_dict(cfg), "compliant")
    np.testing.assert_allclose(model.k, k_hand / 4.0, rtol=1e-12)


def test_series_and_rigid_stiffness():
    g = harmony_geometry()
    # 1 / (1/2000 + 1/6000) = 6000 / 4 = 1500 N/m
    m = build_model(g, 2000.0, 6000.0, arm="compliant")
    np.testing.assert_allclose(m.k, 1500.0, rtol=1e-12)
    np.testing.assert_allclose(m.k_shear, ETA_045 * 1500.0, rtol=1e-12)
    m = build_model(g, 2000.0, 6000.0, arm="rigid")
    np.testing.assert_allclose(m.k, 6000.0, rtol=1e-12)
    m = build_model(g, 2000.0, math.inf, arm="compliant")       # a rigid cuff drops out
    np.testing.assert_allclose(m.k, 2000.0, rtol=1e-12)
    m = build_model(g, 2000.0, 6000.0, arm="compliant", shear_ratio=0.7)
    np.testing.assert_allclose(m.k_shear, 0.7 * 1500.0, rtol=1e-12)
    m = build_model(g, 2000.0, 6000.0, arm="compliant", poisson_ratio=0.0)
    np.testing.assert_allclose(m.k_shear, 0.5 * 1500.0, rtol=1e-12)


def test_infinitely_stiff_element_rejected():
    g = harmony_geometry()
    kc = np.full(g.n, 1e5)
    kc[9] = math.inf
    with pytest.raises(ValueError, match="B2"):
        build_model(g, 2000.0, kc, arm="rigid")
    with pytest.raises(ValueError):
        build_model(g, math.inf, math.inf, arm="compliant")
    # through the config: a .inf cuff is fine for the compliant arm, an error for the rigid one
    cfg = harmony_dict()
    cfg["cuff"]["stiffness"] = math.inf
    c = config_from_dict(cfg)
    model_from_config(c, "compliant")
    with pytest.raises(ConfigError) as exc:
        model_from_config(c, "rigid")
    assert "cuff.stiffness" in str(exc.value)


def test_shear_matrix_full_ring_closed_form():
    # One row at x = 0, N >= 3 locations evenly spread over the circle, uniform k_s.
    # For u = t_y e_y: d = (0, t, 0), P d = t (0, s^2, -cs), p x Pd = (-R s t, 0, 0);
    #   sums over the ring: sum s^2 = N/2, sum cs = sum s = 0  ->  K_yy = k_s N/2, no coupling.
    # For u = t_x e_x: d tangential, sum k_s = N k_s, moment sum (0, R s, -R c) t = 0.
    # For w_x: d = w R (0, -s, c) tangential, moment p x d = (w R^2, 0, 0) -> K = N k_s R^2.
    # For w_y: d = w (R s, 0, 0) (axial), moment (0, R^2 s^2, -R^2 cs) w -> K = N k_s R^2 / 2.
    N, R, k = 8, 0.05, 3000.0
    g = ring(N, start=10.0, radius=R)
    m = build_model(g, k, math.inf, arm="compliant", strap_tension=0.0)
    ks = ETA_045 * k
    expected = ks * np.diag([N, N / 2, N / 2, N * R * R, N * R * R / 2, N * R * R / 2])
    np.testing.assert_allclose(m.K_s, expected, atol=1e-9 * ks)


def test_single_angular_location_is_singular():
    # One angular location: every point sits on one line; a rotation about the
    # radial line through the elements moves them along their normals only.
    g = cuff_geometry([-0.02, 0.0, 0.02], 0.045, 0.025, 90.0, 30.0, 1, 30.0)
    with pytest.raises(ValueError, match="singular"):
        build_model(g, 4000.0, 1e5)
    # one row, two locations: the rotation about the line through both points
    # leaves both in place (d_e = 0): K_s has a null vector
    g = cuff_geometry([0.0], 0.045, 0.025, 30.0, 100.0, 2)
    with pytest.raises(ValueError, match="singular"):
        build_model(g, 4000.0, 1e5)
    # through the config: a ConfigError naming the file and the geometry
    cfg = harmony_dict()
    cfg["geometry"]["angles"] = {"start": 90.0, "step": 30.0, "count": 1, "width": 30.0}
    cfg["cuff"]["stiffness"] = 1e5
    with pytest.raises(ConfigError) as exc:
        model_from_config(config_from_dict(cfg, path="cfg.yaml"), "compliant")
    assert "cfg.yaml" in str(exc.value) and "geometry" in str(exc.value)


# --------------------------------------------------------------------------- closed forms
@pytest.mark.parametrize("arm", ["compliant", "rigid"])
def test_lateral_force_full_contact_closed_form(arm):
    # A full ring (one row at x = 0, N locations 360/N apart), uniform k, hoop strap.
    # Hoop: f0_e = T * 2 pi / N (one row), and W_pre = sum f0 b_e = 0 by symmetry.
    # While every element stays in contact the active set is full and
    #   (sum_e k b b^T + K_s) u = W + W_pre - sum_e k delta0 b = W    (k delta0 = f0)
    # With b_e = (0, -c, -s, 0, 0, 0) (x = 0): sum k b b^T = k diag(0, N/2, N/2, 0, 0, 0),
    # and K_s = k_s diag(N, N/2, N/2, ...) with no coupling (test above). A force F e_y:
    #   u = t e_y,   t = F / (k N/2 (1 + eta)) = 2F / (k N (1 + eta))
    #   f_e = f0 + k b_e . u = f0 - c_e 2F / (N (1 + eta))
    # Full contact holds while 2F / (N (1 + eta)) < f0 = 2 pi T / N, i.e. F < pi T (1 + eta).
    N, T, F = 10, 15.0, 20.0
    kt, kc = 3000.0, 9000.0
    k = kt * kc / (kt + kc) if arm == "compliant" else kc
    g = ring(N, start=7.0)
    m = build_model(g, kt, kc, arm=arm, strap_tension=T)
    th = np.radians(7.0 + 36.0 * np.arange(N))
    f0 = T * 2 * math.pi / N
    eta = ETA_045
    t = 2 * F / (k * N * (1 + eta))
    sol = solve(m, np.array([0.0, F, 0.0, 0.0, 0.0, 0.0]))
    assert sol.converged
    np.testing.assert_allclose(sol.u, [0.0, t, 0.0, 0.0, 0.0, 0.0], atol=1e-12 * (1 + t))
    np.testing.assert_allclose(sol.forces, f0 - np.cos(th) * 2 * F / (N * (1 + eta)),
                               rtol=1e-10, atol=1e-10)
    assert sol.contact.all()
    # the same force along z: c -> s
    sol = solve(m, np.array([0.0, 0.0, F, 0.0, 0.0, 0.0]))
    np.testing.assert_allclose(sol.forces, f0 - np.sin(th) * 2 * F / (N * (1 + eta)),
                               rtol=1e-10, atol=1e-10)
    # shear forces for u = t e_y: s_e = k_s P_e d = k_s t (0, s^2, -c s)
    u = np.array([0.0, t, 0.0, 0.0, 0.0, 0.0])
    s_exp = eta * k * t * np.stack([0 * th, np.sin(th) ** 2, -np.cos(th) * np.sin(th)], axis=1)
    np.testing.assert_allclose(shear_forces(m, u), s_exp, atol=1e-12)
    # an axial force is carried by shear alone: t_x = F / (N k_s), normal forces unchanged
    sol = solve(m, np.array([F, 0.0, 0.0, 0.0, 0.0, 0.0]))
    np.testing.assert_allclose(sol.u, [F / (N * eta * k), 0, 0, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(sol.forces, f0, rtol=1e-10)
    # torsion too: w_x = M / (N k_s R^2)
    M, R = 0.8, 0.05
    sol = solve(m, np.array([0.0, 0.0, 0.0, M, 0.0, 0.0]))
    np.testing.assert_allclose(sol.u, [0, 0, 0, M / (N * eta * k * R * R), 0, 0], atol=1e-12)
    np.testing.assert_allclose(sol.forces, f0, rtol=1e-10)


def test_lateral_force_with_lift_off_closed_form():
    # No preload, one row at x = 0, N = 8 locations at 22.5 + 45 j degrees, uniform k.
    # A force F e_y moves the cuff toward +y: elements with cos(theta) < 0 (112.5 ... 247.5)
    # are compressed (b.u = -c t > 0), the others lift off. With the active set
    # S = {c < 0}: sum_S k c^2 = k * 2 (cos^2 22.5 + cos^2 67.5) = 2k, sum_S c s = 0,
    # and K_s (always on, all 8 elements): k_s N/2 = 4 eta k along y, no coupling. So
    #   t = F / (2k + 4 eta k) = F / (2k (1 + 2 eta)),  f_e = -c_e F / (2 (1 + 2 eta)) on S.
    # The forces do not depend on k.
    F = 50.0
    for k in (2000.0, 5e5):
        g = ring(8, start=22.5)
        m = build_model(g, k, math.inf, arm="compliant", strap_tension=0.0)
        th = np.radians(22.5 + 45.0 * np.arange(8))
        sol = solve(m, np.array([0.0, F, 0.0, 0.0, 0.0, 0.0]))
        expected = np.maximum(-np.cos(th), 0.0) * F / (2 * (1 + 2 * ETA_045))
        np.testing.assert_allclose(sol.forces, expected, rtol=1e-10, atol=1e-10)
        np.testing.assert_array_equal(sol.contact, np.cos(th) < 0)
        # the one-sample solver agrees
        np.testing.assert_allclose(Solver(m).forces([0.0, F, 0.0, 0.0, 0.0, 0.0]), expected,
                                   rtol=1e-10, atol=1e-10)


# --------------------------------------------------------------------------- preload
def test_hoop_preload_gives_zero_displacement_at_zero_load():
    # Harmony config: f0_e = T radians(35) w_r / (3 w_r) = 15 * 0.6108652 / 3 = 3.0543262 N
    for arm in ("compliant", "rigid"):
        model = model_from_config(load_config(HARMONY_CONFIG), arm)
        sol = solve(model, np.zeros(6))
        assert sol.converged
        np.testing.assert_allclose(sol.u, 0.0, atol=1e-15)
        np.testing.assert_allclose(sol.forces, 15 * math.radians(35.0) / 3, rtol=1e-12)
        np.testing.assert_allclose(model.f0, 15 * math.radians(35.0) / 3, rtol=1e-12)
        np.testing.assert_allclose(model.delta0 * model.k, model.f0, rtol=1e-12)
    # unequal rows: f0_e = T * span * w_r / sum(w)
    g = cuff_geometry([-0.02, 0.0, 0.03], [0.04, 0.045, 0.05], [0.01, 0.02, 0.03], 60.0, 40.0, 6,
                      30.0)
    kc = np.linspace(2e4, 8e5, g.n)
    m = build_model(g, 3000.0, kc, strap_tension=12.0)
    f0 = 12.0 * math.radians(30.0) * np.repeat([0.01, 0.02, 0.03], 6) / 0.06
    np.testing.assert_allclose(m.f0, f0, rtol=1e-12)
    sol = solve(m, np.zeros(6))
    np.testing.assert_allclose(sol.u, 0.0, atol=1e-14)
    np.testing.assert_allclose(sol.forces, f0, rtol=1e-10)
    # W_pre = sum f0_e b_e (hand: b from the geometry)
    np.testing.assert_allclose(m.W_pre, f0 @ g.b, rtol=1e-12, atol=1e-12)


def test_handles_preload_wrench_by_hand():
    # Harmony geometry, default handles at the cuff's edges 75 - 17.5 = 57.5 deg and
    # 285 + 17.5 = 302.5 deg, x = 0, R = 0.045. With t = (0, -sin, cos):
    #   t_b - t_a = (0, -sin 302.5 + sin 57.5, cos 302.5 - cos 57.5) = (0, 2 sin 57.5, 0)
    #   p x t = (x, Rc, Rs) x (0, -s, c) = (R, -x c, -x s)  ->  moments (0, 0, 0) at x = 0
    # so W_pre = (0, 2 T sin 57.5, 0, 0, 0, 0) = (0, 25.3017 N, 0, 0, 0, 0) for T = 15 N.
    g = harmony_geometry()
    m = build_model(g, 4000.0, 1e5, strap_model="handles", strap_tension=15.0)
    np.testing.assert_allclose(m.W_pre, [0, 2 * 15 * math.sin(math.radians(57.5)), 0, 0, 0, 0],
                               atol=1e-12)
    np.testing.assert_allclose(m.delta0, 0.0)
    # explicit handles at 60 and 300 deg and axial position x = 0.01:
    #   force (0, 2 T sin 60, 0); moment (R - R, -x (c_b - c_a), -x (s_b - s_a))
    #   = (0, 0, 2 x T sin 60)
    m = build_model(g, 4000.0, 1e5, strap_model="handles", strap_tension=10.0,
                    handle_angles_deg=(60.0, 300.0), handle_axial_position=0.01)
    s60 = math.sin(math.radians(60.0))
    np.testing.assert_allclose(m.W_pre, [0, 20 * s60, 0, 0, 0, 0.01 * 20 * s60], atol=1e-12)
    # at zero load the handles press the cuff toward +y: elements on the -y side carry it,
    # and the forces match the reference model
    rm = ref.build(ref.make_geometry({"A": -0.025, "B": 0.0, "C": 0.025}, 0.045, 0.025, 75,
                                     35, 7), 4000.0, 1e5, strap_model="handles", tension=10.0,
                   handle_angles=(60.0, 300.0), axial_position=0.01)
    sol = solve(m, np.zeros(6))
    np.testing.assert_allclose(sol.forces, ref.solve_forces(rm, np.zeros(6))[0], atol=1e-9)
    # the total normal force along +y balances 20 sin 60 minus what shear carries
    assert sol.forces.sum() > 0


# --------------------------------------------------------------------------- load cell
def test_pure_force_at_offset_produces_moment():
    # F_lc = (0, 0, 10) N at p = (0, -0.07, 0):
    #   p x F = (p_y F_z - p_z F_y, p_z F_x - p_x F_z, p_x F_y - p_y F_x) = (-0.7, 0, 0)
    p = (0.0, -0.07, 0.0)
    np.testing.assert_allclose(loadcell_to_cuff([0, 0, 10, 0, 0, 0], None, p),
                               [0, 0, 10, -0.7, 0, 0], atol=1e-14)
    # F_lc = (10, 0, 0): p x F = (0, 0, -p_y F_x) = (0, 0, 0.7)
    np.testing.assert_allclose(loadcell_to_cuff([10, 0, 0, 0, 0, 0], None, p),
                               [10, 0, 0, 0, 0, 0.7], atol=1e-14)
    # the same through a config
    cfg = config_from_dict(harmony_dict())
    np.testing.assert_allclose(cuff_wrench(cfg, np.array([[0, 0, 10, 0, 0, 0.0]])),
                               [[0, 0, 10, -0.7, 0, 0]], atol=1e-14)


def test_units_lbf_and_newton_millimetre():
    # 1 lbf = 0.45359237 kg * 9.80665 m/s^2 = 4.4482216152605 N; 1000 N*mm = 1 N*m
    lbf = 0.45359237 * 9.80665
    cfg = harmony_dict()
    cfg["load_cell"].update(force_unit="lbf", moment_unit="N*mm", position=[0.0, 0.0, 0.1])
    c = config_from_dict(cfg)
    w = cuff_wrench(c, np.array([[2.0, 0, 0, 1000.0, 0, -500.0]]))
    # F = 2 lbf along x; M = (1, 0, -0.5) N*m + p x F with p = (0, 0, 0.1):
    #   p x F = (0*0 - 0.1*0, 0.1*F_x - 0, 0) = (0, 0.1 * 2 lbf, 0)
    np.testing.assert_allclose(w, [[2 * lbf, 0, 0, 1.0, 0.2 * lbf, -0.5]], rtol=1e-12)


def test_cuff_on_robot_negates():
    cfg = harmony_dict()
    cfg["load_cell"]["convention"] = "cuff_on_robot"
    c = config_from_dict(cfg)
    w = cuff_wrench(c, np.array([[0, 0, 10.0, 0.1, 0, 0]]))
    np.testing.assert_allclose(w, [[0, 0, -10.0, -0.1 + 0.7, 0, 0]], atol=1e-14)


def test_euler_xyz_is_extrinsic_and_matches_scipy():
    rng = np.random.default_rng(3)
    for _ in range(20):
        angles = rng.uniform(-180, 180, 3)
        np.testing.assert_allclose(rotation_from_euler_xyz(angles),
                                   Rotation.from_euler("xyz", angles, degrees=True).as_matrix(),
                                   atol=1e-12)
    # a case where extrinsic and intrinsic orders differ:
    # extrinsic x 90 then y 90 sends the load cell's y axis: Rx(90) y = z, Ry(90) z = x
    R = rotation_from_euler_xyz([90, 90, 0])
    np.testing.assert_allclose(R @ [0, 1, 0], [1, 0, 0], atol=1e-12)
    intrinsic = Rotation.from_euler("XYZ", [90, 90, 0], degrees=True).as_matrix()
    assert not np.allclose(R, intrinsic)
    # z 90: the load cell's x axis is the cuff's y axis (v_cuff = R v_lc)
    cfg = harmony_dict()
    cfg["load_cell"].update(euler_xyz_deg=[0, 0, 90], position=[0, 0, 0])
    c = config_from_dict(cfg)
    np.testing.assert_allclose(cuff_wrench(c, np.array([[5.0, 0, 0, 0, 0, 0]])),
                               [[0, 5.0, 0, 0, 0, 0]], atol=1e-12)


def test_rotation_matrix_in_config():
    cfg = harmony_dict()
    del cfg["load_cell"]["euler_xyz_deg"]
    R = Rotation.from_euler("zyx", [30, -20, 10], degrees=True).as_matrix()
    cfg["load_cell"]["rotation"] = R.tolist()
    c = config_from_dict(cfg)
    w = np.array([[1.0, -2.0, 3.0, 0.1, 0.2, -0.3]])
    np.testing.assert_allclose(cuff_wrench(c, w), ref.loadcell_to_cuff(w, cfg["load_cell"]),
                               atol=1e-12)


def test_loadcell_round_trips():
    rng = np.random.default_rng(11)
    for _ in range(25):
        R = Rotation.random(random_state=rng).as_matrix()
        p = rng.uniform(-0.2, 0.2, 3)
        sign = rng.choice([1.0, -1.0])
        fs = rng.choice([1.0, 0.45359237 * 9.80665])
        ms = rng.choice([1.0, 1e-3])
        w = rng.normal(size=(7, 6)) * [50, 50, 50, 5, 5, 5]
        W = loadcell_to_cuff(w, R, p, sign, fs, ms)
        lc = {"rotation": R, "position": p,
              "convention": "robot_on_cuff" if sign > 0 else "cuff_on_robot",
              "force_unit": "N" if fs == 1.0 else "lbf",
              "moment_unit": "N*m" if ms == 1.0 else "N*mm"}
        np.testing.assert_allclose(W, ref.loadcell_to_cuff(w, lc), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(cuff_to_loadcell(W, R, p, sign, fs, ms), w, rtol=1e-10,
                                   atol=1e-10)
        np.testing.assert_allclose(loadcell_to_cuff(cuff_to_loadcell(W, R, p, sign, fs, ms),
                                                    R, p, sign, fs, ms), W, rtol=1e-10,
                                   atol=1e-10)


# --------------------------------------------------------------------------- model vs reference
def test_bundled_config_matches_reference_model():
    cfg = harmony_dict()
    rng = np.random.default_rng(5)
    W = np.vstack([np.zeros(6), rng.normal(size=(30, 6)) * [30, 30, 30, 2, 2, 2],
                   [[0, 0, 55.6, 0, 0, 0], [0, -55.6, 0, 0, 0, 0], [300, 0, 0, 0, 0, 0]]])
    for arm in ("compliant", "rigid"):
        model = model_from_config(load_config(HARMONY_CONFIG), arm)
        rm = ref.model_from_config(cfg, arm)
        np.testing.assert_allclose(model.k, rm.k, rtol=1e-12)
        np.testing.assert_allclose(model.K_s, rm.Ks, rtol=1e-10, atol=1e-10 * np.abs(rm.Ks).max())
        np.testing.assert_allclose(model.W_pre, rm.W_pre, atol=1e-12)
        sol = solve(model, W)
        assert sol.converged.all()
        np.testing.assert_allclose(sol.forces, ref.solve_forces(rm, W), atol=1e-6)


def test_reference_model_self_check():
    """The reference's minimiser agrees with brute-force active-set enumeration."""
    rng = np.random.default_rng(8)
    g = ref.make_geometry({"A": -0.02, "B": 0.02}, [0.04, 0.05], 0.02, 100.0, 40.0, 5)
    for strap in ("hoop", "handles"):
        m = ref.build(g, rng.uniform(2e3, 3e4, 10), rng.uniform(1e4, 1e6, 10), tension=15.0,
                      strap_model=strap)
        for _ in range(15):
            W = rng.normal(size=6) * [80, 80, 80, 4, 4, 4]
            u1, u2 = ref.solve_one(m, W), ref.solve_bruteforce(m, W)
            np.testing.assert_allclose(m.forces(u1), m.forces(u2), atol=1e-9)
            # equilibrium of the reference itself
            res = m.geom.b.T @ m.forces(u1) + m.Ks @ u1 - W - m.W_pre
            assert np.abs(res).max() < 1e-9 * (np.abs(W).max() + 1.0)
