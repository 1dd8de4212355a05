"""The reduced neo-Hookean model's algebra (phri_spring.physics.hyperelastic.reduced, coupled_hyper).

No FE here (tests/workflows/test_hyper_arm.py identifies one): the monomials against their
definition and finite differences, the fit against polynomials it must reproduce exactly,
the 6-unknown Newton iteration against scipy's root finder on the same equations, the
model with zero corrections against the linear coupled model's own active-set solve, and
the solver paths (batch, per sample, single-sample Solver) against each other.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.optimize import root

from phri_spring.physics.hyperelastic import reduced as hr
from phri_spring.physics.continuum.coupled import build_coupled_model
from phri_spring.physics.hyperelastic.coupled import HyperCoupledModel
from phri_spring.physics.contact.solver import Solver, solve, solve_per_sample
from phri_spring.physics.response.stiffness import interface_stiffness
from support.helpers import harmony_geometry  # noqa: E402

K = len(hr.EXPONENTS)
GEOM = harmony_geometry()


def _spd(n, rng, scale):
    A = rng.standard_normal((n, n))
    return scale * (A @ A.T / n + np.eye(n))


def _surface():
    """A synthetic positive definite surface stiffness K_t and its normal output N (no FE)."""
    rng = np.random.default_rng(3)
    n = GEOM.n
    Kt = _spd(6 * n, rng, 1.0)
    dof = np.arange(6 * n) % 6
    s = np.where(dof < 3, 2.0e3, 2.0)        # N/m for translations, N*m/rad for rotations
    Kt = Kt * np.sqrt(np.outer(s, s))
    # reported normal force: the patch force along its normal n_e (cuff frame dofs of K_t)
    N = np.stack([GEOM.normals[e] @ Kt[6 * e:6 * e + 3] for e in range(n)])
    return Kt, N


@pytest.fixture(scope="module")
def linear_model():
    """A rigid-cuff coupled model on :func:`_surface`."""
    Kt, N = _surface()
    return build_coupled_model(GEOM, Kt, np.inf, poisson_ratio=0.45, strap_tension=15.0,
                               normal_output=N)


def _reduction(lin, rng, size, max_force=70.0, max_moment=2.5):
    scale = np.array([5e-3, 5e-3, 5e-3, 0.2, 0.2, 0.2])
    n = lin.n
    coef = dict(wrench=size * rng.standard_normal((K, 6)) * [1, 1, 1, 0.05, 0.05, 0.05],
                normal=size * 0.1 * rng.standard_normal((K, n)),
                patch=size * 0.1 * rng.standard_normal((K, 6 * n)))
    D = np.array([max_force] * 3 + [max_moment] * 3)
    return hr.HyperReduction(scale=scale, range_map=hr.linear_bonded(lin)["H"] / D[:, None],
                             info={}, **coef)


def test_features_are_the_monomials():
    x = np.random.default_rng(0).standard_normal((7, 6))
    expected = np.prod(x[:, None, :] ** hr.EXPONENTS[None], axis=2)
    np.testing.assert_allclose(hr.features(x), expected, rtol=1e-13, atol=1e-13)
    assert len({tuple(e) for e in hr.EXPONENTS}) == K == 84      # 1 + 6 + 21 + 56
    assert hr.EXPONENTS.sum(axis=1).max() == hr.DEGREE


@settings(max_examples=30, deadline=None)
@given(arrays(float, (3, 6), elements=st.floats(-2, 2)))
def test_feature_derivatives_are_finite_differences(x):
    _, d = hr.features(x, derivative=True)
    h = 1e-6
    for l_ in range(6):
        e = np.zeros(6)
        e[l_] = h
        fd = (hr.features(x + e) - hr.features(x - e)) / (2 * h)
        np.testing.assert_allclose(d[:, :, l_], fd, rtol=0, atol=1e-7)


def test_fit_reproduces_a_cubic_exactly(linear_model):
    rng = np.random.default_rng(1)
    L = hr.linear_bonded(linear_model)
    red = _reduction(linear_model, rng, 1.0)
    U = rng.uniform(-1, 1, (200, 6)) * red.scale
    U[np.argmax(np.abs(U), axis=0), np.arange(6)] = red.scale   # scale = the largest |u_k|
    phi = hr.features(U / red.scale)
    R = L["W_pre"] + U @ L["H"].T + phi @ red.wrench
    F = L["f0"] + U @ L["N"].T + phi @ red.normal
    P = L["P0"] + U @ L["G"].T + phi @ red.patch
    fit = hr.fit_reduction(U, R, F, P, L, 70.0, 2.5)
    np.testing.assert_allclose(fit.scale, red.scale, rtol=1e-15)
    for name in ("wrench", "normal", "patch"):
        np.testing.assert_allclose(getattr(fit, name), getattr(red, name), rtol=0,
                                   atol=1e-8 * np.abs(getattr(red, name)).max())
        assert fit.info[f"fit_rms_{name}"] < 1e-9


def test_newton_solves_the_equations_scipy_solves(linear_model):
    rng = np.random.default_rng(2)
    red = _reduction(linear_model, rng, 2.0)
    H = hr.linear_bonded(linear_model)["H"]
    W = rng.standard_normal((40, 6)) * [15, 15, 15, 0.5, 0.5, 0.5]
    u, phi, its, conv = hr.solve_poses(red, H, W, red.start(H, W))
    assert conv.all() and its.max() <= 8
    for i in range(len(W)):
        def g(v, i=i):
            return v @ H.T + hr.features(v[None] / red.scale)[0] @ red.wrench - W[i]
        ref = root(g, np.linalg.solve(H, W[i]), tol=1e-13)
        assert np.abs(g(ref.x)).max() < 1e-8
        np.testing.assert_allclose(u[i], ref.x, rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(phi, hr.features(u / red.scale), rtol=1e-14, atol=1e-14)


def test_a_pose_outside_the_identified_range_is_not_converged(linear_model):
    red = _reduction(linear_model, np.random.default_rng(4), 0.0)
    H = hr.linear_bonded(linear_model)["H"]
    W = np.array([[0, 0, 60.0, 0, 0, 0], [0, 0, 71.0, 0, 0, 0], [0, 0, 0, 0, 2.6, 0]])
    _, _, _, conv = hr.solve_poses(red, H, W, red.start(H, W))
    assert conv.tolist() == [True, False, False]          # range 70 N, 2.5 N*m


def test_zero_corrections_are_the_linear_coupled_model(linear_model):
    # the bonded linear answer, against the linear model's own active-set solve (every
    # patch pressing at these loads, so its contact program is the bonded one)
    red = _reduction(linear_model, np.random.default_rng(5), 0.0)
    model = HyperCoupledModel(linear=linear_model, reduction=red)
    W = np.random.default_rng(6).standard_normal((25, 6)) * [2, 2, 2, 0.05, 0.05, 0.05]
    ref = solve(linear_model, W)
    assert ref.contact.all()
    got = solve(model, W)
    assert got.converged.all()
    np.testing.assert_allclose(got.u, ref.u, rtol=0, atol=1e-10 * np.abs(ref.u).max())
    np.testing.assert_allclose(got.forces, ref.forces, rtol=0, atol=1e-9)
    P = linear_model.patch_forces(ref.u, ref.contact)
    np.testing.assert_allclose(model.patch_forces(got.u), P, rtol=0, atol=1e-9)


def test_solver_paths_agree_and_report_the_range(linear_model):
    red = _reduction(linear_model, np.random.default_rng(7), 1.0)
    model = HyperCoupledModel(linear=linear_model, reduction=red)
    rng = np.random.default_rng(8)
    W = rng.standard_normal((30, 6)) * [20, 20, 20, 0.6, 0.6, 0.6]
    W[5] = [0, 500.0, 0, 0, 0, 0]                         # far outside the range
    batch, per = solve(model, W), solve_per_sample(model, W)
    assert not batch.converged[5] and np.isnan(batch.forces[5]).all()
    ok = batch.converged
    assert ok.sum() >= 25
    np.testing.assert_array_equal(per.converged, ok)
    np.testing.assert_allclose(per.forces[ok], batch.forces[ok], rtol=0, atol=1e-10)
    solver = Solver(model)
    for i in range(len(W)):
        f = solver.forces(W[i])
        assert solver.last_converged == ok[i]
        np.testing.assert_allclose(f, batch.forces[i], rtol=0, atol=1e-10)
    # equilibrium: the reduced resultant carries the wrench
    L = hr.linear_bonded(linear_model)
    g = batch.u[ok] @ L["H"].T + hr.features(batch.u[ok] / red.scale) @ red.wrench - W[ok]
    assert np.abs(g).max() < 1e-6


def test_tangent_stiffness_is_the_derivative_of_the_equilibrium(linear_model):
    red = _reduction(linear_model, np.random.default_rng(9), 1.5)
    model = HyperCoupledModel(linear=linear_model, reduction=red)
    W0 = np.array([3.0, -20.0, 5.0, 0.2, -0.1, 0.3])
    Kt = interface_stiffness(model, W0)
    h = np.array([1e-3] * 3 + [1e-5] * 3)
    dU = np.empty((6, 6))
    for j in range(6):
        e = np.zeros(6)
        e[j] = h[j]
        dU[:, j] = (solve(model, W0 + e).u - solve(model, W0 - e).u) / (2 * h[j])
    np.testing.assert_allclose(np.linalg.inv(Kt), dU, rtol=1e-5,
                               atol=1e-7 * np.abs(dU).max())


def test_a_compliant_cuff_is_refused(linear_model):
    Kt, N = _surface()
    compliant = build_coupled_model(GEOM, Kt, 1e5, poisson_ratio=0.45, normal_output=N)
    red = _reduction(linear_model, np.random.default_rng(10), 0.0)
    with pytest.raises(ValueError, match="rigid cuff"):
        HyperCoupledModel(linear=compliant, reduction=red)


def test_held_out_error_sees_what_the_cubic_cannot_follow(linear_model):
    """Exact cubic data: the held-out error is round-off. Data with a steep non-cubic part
    (x^8, as an Ogden layer with a large exponent stiffens): the rays left out are missed by
    more than the fit's own residual says, and by more than 5 % of the peak force."""
    rng = np.random.default_rng(3)
    L = hr.linear_bonded(linear_model)
    red = _reduction(linear_model, rng, 1.0)
    rays, fr = 96, np.array([1 / 3, 2 / 3, 1.0])   # 84 rays fitted per fold >= 56 cubic terms
    ends = rng.standard_normal((rays, 6))
    ends /= np.abs(ends).max(axis=1, keepdims=True)
    U = np.vstack([np.zeros((1, 6)), (ends[:, None, :] * fr[None, :, None]).reshape(-1, 6)])
    U *= red.scale
    groups = np.r_[-1, np.repeat(np.arange(rays), 3)]
    x = U / red.scale
    phi = hr.features(x)
    R = L["W_pre"] + U @ L["H"].T + phi @ red.wrench
    F = L["f0"] + U @ L["N"].T + phi @ red.normal
    P = L["P0"] + U @ L["G"].T + phi @ red.patch
    exact = hr.fit_reduction(U, R, F, P, L, 70.0, 2.5, groups=groups)
    assert exact.info["held_out_normal_pct"] < 1e-6
    steep = 2.0 * np.abs(F).max() * (x[:, :1] ** 8) * np.ones((1, F.shape[1]))
    F2 = F + steep
    fit = hr.fit_reduction(U, R, F2, P, L, 70.0, 2.5, groups=groups)
    resid_pct = 100 * fit.info["fit_rms_normal"] / np.abs(F2).max()
    assert fit.info["held_out_normal_pct"] > 5.0
    assert fit.info["held_out_normal_pct"] > resid_pct
