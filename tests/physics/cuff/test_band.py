"""The elastic band strap, ``strap.model: band`` (docs/model.md section 3.1).

References are worked by hand from the geometry: the band's unit wrench h and path length
on a circle, the ellipse's arc length by quadrature of its polar outline and its smallest
radius of curvature b^2 / a, and a symmetric cuff pulled away from its shell, where the
band's tension balances the pull with the shear springs and the edge elements in contact.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from phri_spring.errors import ConfigError, ModelInputError
from phri_spring.io.config import config_from_dict
from phri_spring.physics.contact.band_solve import band_model
from phri_spring.physics.contact.solver import Solver, solve
from phri_spring.physics.cuff.band import band_path, laplace_pressure
from phri_spring.physics.cuff.geometry import cuff_geometry, section_geometry
from phri_spring.physics.limb.sections import EllipseSection
from phri_spring.physics.springs.model import build_model
from phri_spring.workflows.common import model_from_config
from support.helpers import harmony_dict

R = 0.045
ROWS = [-0.025, 0.0, 0.025]
# seven locations 35 deg apart from 75 deg: the shell spans 57.5 .. 302.5 deg, the band
# the 115 deg around +y
GEOM = cuff_geometry(ROWS, R, 0.025, 75.0, 35.0, 7)
K_T, K_C, ETA = 400.0, 1e6, 0.5


def _band(stiffness, tension=15.0, law="linear", arm="compliant"):
    spring = build_model(GEOM, K_T, K_C, arm=arm, shear_ratio=ETA, strap_tension=tension,
                         strap_model="band", law=law)
    return band_model(spring, stiffness, 0.05, tension)


def test_band_path_on_a_circle_by_hand():
    path = band_path(GEOM)
    edge = math.radians(57.5)
    assert path.h == pytest.approx([0.0, 2 * math.sin(edge), 0.0, 0.0, 0.0, 0.0], abs=1e-12)
    assert path.length == pytest.approx(R * math.radians(115.0), rel=1e-12)
    assert path.min_radius == pytest.approx(R, rel=1e-12)
    # Laplace's law on a circle: p = T / (w R)
    assert laplace_pressure(20.0, 0.05, path.min_radius) == pytest.approx(20.0 / (0.05 * R))


def test_band_path_on_an_ellipse():
    a, b = 0.05, 0.04          # the major axis along y: the band's path crosses its end
    geom = section_geometry(ROWS, EllipseSection(a, b), 0.025, 75.0, 35.0, 7)
    path = band_path(geom)

    def r(th):
        return a * b / math.hypot(b * math.cos(th), a * math.sin(th))

    def speed(th, d=1e-6):
        return math.hypot(r(th), (r(th + d) - r(th - d)) / (2 * d))
    length = quad(speed, math.radians(302.5), math.radians(417.5), epsabs=1e-12)[0]
    assert path.length == pytest.approx(length, rel=1e-5)
    # the smallest radius of curvature of an ellipse, at the end of its major axis
    assert path.min_radius == pytest.approx(b * b / a, rel=1e-3)
    p = laplace_pressure(10.0, 0.05, path.min_radius)
    assert p == pytest.approx(10.0 * a / (0.05 * b * b), rel=1e-3)


def test_zero_wrench_gives_the_preload_tension():
    sol = solve(_band(500.0), np.zeros(6))
    assert sol.converged and sol.strap_tension == pytest.approx(15.0, rel=1e-8)


@pytest.mark.parametrize("F", [20.0, 80.0, 300.0])
def test_pull_away_from_the_shell_by_hand(F):
    """No preload: the cuff pulled along -y by F. Elements with cos(theta) > 0 (the shell's
    edge locations, 75 and 285 deg) press, the others lift; with K_yy the y stiffness of the
    shear springs (k_s (1 - n_y^2)) and of the pressing elements (k n_y^2), u_y =
    (-F + T h_y) / K_yy and T = k_b (-h_y u_y): T = k_b h_y F / (K_yy + k_b h_y^2)."""
    k_strap = 800.0
    model = _band(k_strap, tension=0.0)
    sol = solve(model, [0.0, -F, 0.0, 0.0, 0.0, 0.0])
    k = 1.0 / (1.0 / K_T + 1.0 / K_C)
    theta = np.radians(75.0 + 35.0 * np.arange(7))
    ny2 = np.cos(theta) ** 2
    K_yy = 3 * (ETA * k * np.sum(1 - ny2) + k * np.sum(ny2[np.cos(theta) > 0]))
    h_y = 2 * math.sin(math.radians(57.5))
    k_b = k_strap / (R * math.radians(115.0))
    T = k_b * h_y * F / (K_yy + k_b * h_y ** 2)
    assert sol.converged
    assert sol.strap_tension == pytest.approx(T, rel=1e-8)
    assert sol.u[1] == pytest.approx((-F + T * h_y) / K_yy, rel=1e-8)
    assert np.array_equal(sol.contact, np.tile(np.cos(theta) > 0, 3))


def test_balance_of_forces():
    """K_s u + sum_e f_e b_e = W + T h: the band's tension enters the cuff's equilibrium."""
    model = _band(300.0)
    rng = np.random.default_rng(3)
    W = rng.normal(size=(40, 6)) * [20, 40, 20, 1, 1, 1]
    sol = solve(model, W)
    assert sol.converged.all()
    lhs = sol.u @ model.K_s.T + sol.forces @ model.b
    rhs = W + sol.strap_tension[:, None] * model.band_h
    assert np.allclose(lhs, rhs, atol=1e-8 * np.abs(W).max())
    # the band's tension is its law at the answer: k_b (stretch - h . u), >= 0
    assert np.allclose(sol.strap_tension,
                       model.band_k * np.maximum(model.band_stretch - sol.u @ model.band_h, 0),
                       atol=1e-7)


def test_zero_stiffness_is_the_constant_tension_strap():
    """With no stiffness the band's tension stays T: the strap pulling at the shell's edges
    with a constant tension (the handles model), sample for sample; a tiny stiffness (solved
    by the tension's iteration) approaches it."""
    handles = build_model(GEOM, K_T, K_C, shear_ratio=ETA, strap_tension=15.0,
                          strap_model="handles")
    rng = np.random.default_rng(7)
    W = rng.normal(size=(30, 6)) * [20, 40, 20, 1, 1, 1]
    ref = solve(handles, W)
    for stiffness, tol in ((0.0, 1e-12), (1e-6, 1e-6)):
        sol = solve(_band(stiffness), W)
        assert sol.converged.all()
        assert np.allclose(sol.forces, ref.forces, atol=tol)
        assert np.allclose(sol.strap_tension, 15.0, atol=tol)


def test_pulls_of_any_size_converge_and_a_slack_band_carries_nothing():
    model = _band(500.0)
    F = np.concatenate([-np.geomspace(1, 2000, 12), np.geomspace(1, 2000, 12)])
    W = np.zeros((len(F), 6))
    W[:, 1] = F
    sol = solve(model, W)
    assert sol.converged.all()
    assert (sol.strap_tension >= 0).all()
    assert sol.strap_tension[-1] == 0.0                     # pushed into the limb: slack
    assert np.all(np.diff(sol.strap_tension[:12]) > 0)      # harder pulls, tauter band


def test_a_nonlinear_law_and_the_rigid_arm():
    spring = build_model(GEOM, K_T, K_C, shear_ratio=ETA, strap_tension=15.0,
                         strap_model="band", law="exponential",
                         law_parameters={"stiffening": 150.0})
    W = np.array([[0, -60, 5, 0, 0.5, 0], [3, 40, -5, 0.2, 0, 0.1]], float)
    for model in (band_model(spring, 500.0, 0.05, 15.0), _band(500.0, arm="rigid")):
        sol = solve(model, W)
        assert sol.converged.all()
        T = model.band_k * np.maximum(model.band_stretch - sol.u @ model.band_h, 0)
        assert np.allclose(sol.strap_tension, T, atol=1e-7)


_MIRROR = np.array([1, 1, -1, -1, -1, 1.0])   # the wrench reflected in z -> -z


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-80, 80), min_size=6, max_size=6))
def test_mirrored_loads_give_mirrored_answers(w):
    """The cuff is symmetric under z -> -z (theta -> -theta): the mirrored wrench gives the
    same tension and each element's force at its mirror location (j <-> 6 - j)."""
    model = _band(400.0)
    W = np.array(w) * [1, 1, 1, 0.02, 0.02, 0.02]
    sol = solve(model, np.stack([W, W * _MIRROR]))
    assert sol.converged.all()
    assert sol.strap_tension[1] == pytest.approx(sol.strap_tension[0], rel=1e-7, abs=1e-9)
    f = sol.forces.reshape(2, 3, 7)
    assert np.allclose(f[1], f[0][:, ::-1], atol=1e-7)


def test_bad_stiffness_or_width_is_refused():
    spring = build_model(GEOM, K_T, K_C, strap_model="band")
    with pytest.raises(ModelInputError, match="tension per unit strain"):
        band_model(spring, -1.0, 0.05, 15.0)
    with pytest.raises(ModelInputError, match="axial width"):
        band_model(spring, 100.0, 0.0, 15.0)
    with pytest.raises(ModelInputError, match="uncovered skin"):
        band_path(GEOM, handle_angles_deg=(0.0, 360.0))


def _cfg(**strap):
    d = harmony_dict()
    d["strap"] = {"tension": 15.0, **strap}
    return d


@pytest.mark.parametrize("strap, key", [
    ({"model": "band", "width": 0.05}, "strap.stiffness"),
    ({"model": "band", "stiffness": 300.0}, "strap.width"),
    ({"model": "hoop", "width": 0.05}, "strap.width"),
    ({"model": "handles", "stiffness": 300.0}, "strap.stiffness"),
    ({"model": "band", "width": 0.05, "stiffness": -3.0}, "strap.stiffness"),
    ({"model": "band", "width": -0.05, "stiffness": 3.0}, "strap.width"),
])
def test_bad_config_names_the_key(strap, key):
    with pytest.raises(ConfigError) as exc:
        config_from_dict(_cfg(**strap))
    assert exc.value.key == key and "\n" not in str(exc.value)


def test_refused_combinations_name_the_key():
    d = _cfg(model="band", width=0.05, stiffness=300.0)
    d["tissue"]["continuum"] = {"thickness": 0.02, "young_modulus": 3.0e4}
    cfg = config_from_dict(d)
    with pytest.raises(ConfigError) as exc:
        model_from_config(cfg, "coupled")
    assert exc.value.key == "strap.stiffness" and "coupled arm" in str(exc.value)
    d = _cfg(model="band", width=0.05, stiffness=300.0)
    d.setdefault("interface", {})["friction_coefficient"] = 0.5
    with pytest.raises(ConfigError) as exc:
        model_from_config(config_from_dict(d), "compliant")
    assert exc.value.key == "interface.friction_coefficient" and "band" in str(exc.value)


def test_the_single_sample_solver_follows_the_band():
    """``phri live``'s one-sample solver gives the batch's answer, sample by sample."""
    model = _band(500.0)
    W = np.array([[0, -60, 5, 0, 0.5, 0], [3, 40, -5, 0.2, 0, 0.1], [0, 0, 0, 0, 0, 0.0]])
    batch = solve(model, W)
    solver = Solver(model)
    for w, f in zip(W, batch.forces):
        assert np.allclose(solver.forces(w), f, atol=1e-9)
        assert solver.last_converged


def test_tangent_stiffness_is_the_derivative_of_the_answer():
    """model.tangent_stiffness (phri stiffness) against central differences of solves:
    K (u(W + e) - u(W - e)) = 2 e, with the band taut."""
    model = _band(500.0)
    W = np.array([0.0, -30.0, 2.0, 0.1, 0.0, 0.05])
    sol = solve(model, W)
    assert sol.strap_tension > 15.0
    K = model.tangent_stiffness(sol.u, sol.contact)
    for j in range(6):
        e = np.zeros(6)
        e[j] = 1e-3 if j < 3 else 1e-5
        du = solve(model, W + e).u - solve(model, W - e).u
        assert np.allclose(K @ du, 2 * e, atol=1e-8)


def test_sensor_patches_take_the_band():
    """A free layout (configs/harmony_24_panels.yaml): the band runs between the layout's
    extreme edges, holds its tension at zero wrench and stretches under a pull."""
    from phri_spring.io.config.yaml_loader import load_yaml
    from support.helpers import REPO

    path = REPO / "configs" / "harmony_24_panels.yaml"
    raw = load_yaml(path)
    raw["strap"] = {"tension": 15.0, "model": "band", "width": 0.05, "stiffness": 500.0}
    cfg = config_from_dict(raw, path=path, base_dir=path.parent)
    model = model_from_config(cfg, "compliant")
    sol = solve(model, np.array([[0.0] * 6, [0, -50.0, 0, 0, 0, 0]]))
    assert sol.converged.all()
    assert sol.strap_tension[0] == pytest.approx(15.0, rel=1e-7)
    assert sol.strap_tension[1] > 15.0
