"""The coupled tissue model's contact solver (docs/model.md section 10).

The surface stiffness here is not the built-in FE's (tests/physics/continuum/test_fe_tissue.py checks
that one) but matrices with known structure:

- a block-diagonal K_t (normal k_t, tangential eta k_t per patch), with which the
  coupled model must be the spring model to round-off;
- a "kernel" surface compliance C_t = c0 I + beta G (x) I3 with a Gaussian kernel
  G_ef = exp(-|p_e - p_f|^2 / l^2): symmetric positive definite, coupling every
  patch to its neighbours, and invariant under any reflection of the cuff that
  maps patches onto patches (it depends on distances only).

The equilibrium is checked against the quadratic program it solves, with scipy's
SLSQP as an independent solver, and against the program's KKT conditions.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize

from support.coupled_reference import kernel_K
from phri_spring.physics.contact import active_set
from phri_spring.physics.continuum import coupled as coupled_module
from phri_spring.physics.cuff.geometry import cuff_geometry
from phri_spring.physics.springs.model import build_model, tissue_element_stiffness
from phri_spring.physics.contact.solver import Solver, solve, solve_per_sample
from phri_spring.physics.springs.stiffness import shear_ratio_from_poisson
from phri_spring.synthetic.wrench import smooth_random_log


def build_coupled_model(*args, **kwargs):
    """The coupled model with every tie bonded, lifted or not: these tests check the
    program of docs/model.md 10.3 and its active-set solver, which the arm's default
    (lift-off released, tests/physics/continuum/test_coupled_lift_off.py) is compared against."""
    return coupled_module.build_coupled_model(*args, lift_off=False, **kwargs)

HARMONY = dict(rows=[-0.025, 0.0, 0.025], radius=0.045, width=0.025, start=75.0, step=35.0,
               count=7)


def _geometry(rows=HARMONY["rows"], count=7, start=75.0, step=35.0):
    return cuff_geometry(rows, 0.045, 0.025, start, step, count)


def _diagonal_K(g, k_t, eta):
    K = np.zeros((3 * g.n, 3 * g.n))
    for e in range(g.n):
        nn = np.outer(g.normals[e], g.normals[e])
        K[3 * e:3 * e + 3, 3 * e:3 * e + 3] = k_t[e] * nn + eta * k_t[e] * (np.eye(3) - nn)
    return K


def _logs(n, seed, scale=3.0):
    _, W = smooth_random_log(n, seed=seed)
    rng = np.random.default_rng(seed)
    rough = rng.normal(size=(n // 3, 6)) * np.array([80, 80, 80, 3, 3, 3])
    return np.vstack([W * scale, rough])


@pytest.mark.parametrize("strap", ["hoop", "handles"])
def test_diagonal_surface_stiffness_is_the_spring_model(strap):
    rng = np.random.default_rng(7)
    g = _geometry()
    k_t = tissue_element_stiffness(rng.uniform(3500, 5000, g.n), g.areas)
    k_c = rng.uniform(3e4, 1e6, g.n)
    spring = build_model(g, k_t, k_c, strap_model=strap, strap_tension=20.0)
    coupled = build_coupled_model(g, _diagonal_K(g, k_t, shear_ratio_from_poisson(0.45)), k_c,
                                  strap_model=strap, strap_tension=20.0)
    W = _logs(1500, seed=3)
    a, b = solve(spring, W), solve(coupled, W)
    assert a.converged.all() and b.converged.all()
    assert (~a.contact).any()  # the logs lift contacts off
    peak = np.abs(a.forces).max()
    np.testing.assert_allclose(b.forces, a.forces, rtol=0, atol=1e-12 * peak)
    np.testing.assert_array_equal(b.contact, a.contact)
    np.testing.assert_allclose(coupled.shear_components(b.u, b.contact),
                               spring.shear_components(a.u), rtol=0, atol=1e-12 * peak)
    np.testing.assert_allclose(coupled.W_pre, spring.W_pre, rtol=0, atol=1e-12)


def test_rigid_cuff_and_rotations_reduce_too():
    # 6 dofs per patch with stiff, uncoupled rotations and a rigid cuff: still the spring
    # model with k_e = k_t (the patch rotations then carry moments the spring model
    # lacks, so compare only where the rotational stiffness is tiny)
    g = _geometry()
    k_t = np.full(g.n, 40e3)
    eta = shear_ratio_from_poisson(0.45)
    K3 = _diagonal_K(g, k_t, eta)
    K6 = np.zeros((6 * g.n, 6 * g.n))
    for e in range(g.n):
        K6[6 * e:6 * e + 3, 6 * e:6 * e + 3] = K3[3 * e:3 * e + 3, 3 * e:3 * e + 3]
        K6[6 * e + 3:6 * e + 6, 6 * e + 3:6 * e + 6] = 1e-9 * np.eye(3)
    spring = build_model(g, k_t, np.inf)
    coupled = build_coupled_model(g, K6, np.inf)
    W = _logs(300, seed=5)
    a, b = solve(spring, W), solve(coupled, W)
    np.testing.assert_allclose(b.forces, a.forces, rtol=0, atol=1e-6)


def _qp_reference(model, w):
    """min 1/2 P^T C P - delta^T P  s.t.  T^T P = w + W_pre, P_n >= 0, by SLSQP."""
    C, d, T, N = model.C, model.delta, model.T, model.normal_dofs
    r = np.asarray(w) + model.W_pre
    scale = 1.0 / np.abs(np.diag(C)).mean()
    P0 = np.linalg.lstsq(T.T, r, rcond=None)[0]
    res = minimize(lambda P: scale * (0.5 * P @ C @ P - d @ P), P0,
                   jac=lambda P: scale * (C @ P - d), method="SLSQP",
                   constraints=[{"type": "eq", "fun": lambda P: T.T @ P - r,
                                 "jac": lambda P: T.T}],
                   bounds=[(0, None) if i in set(N) else (None, None) for i in range(len(d))],
                   options={"maxiter": 1000, "ftol": 1e-14})
    # status 8 ("positive directional derivative in the line search") is SLSQP's way of
    # saying it cannot improve further at this precision: accept it when feasible
    assert res.status in (0, 8), res.message
    assert np.abs(T.T @ res.x - r).max() < 1e-6 * (1 + np.abs(r).max())
    return res.x[N]


@pytest.mark.parametrize("dofs", [3, 6])
def test_equilibrium_matches_an_independent_qp_solver(dofs):
    g = _geometry()
    model = build_coupled_model(g, kernel_K(g, dofs=dofs), np.linspace(5e4, 5e5, g.n),
                                strap_tension=15.0)
    W = _logs(30, seed=11)[::5]   # 8 samples, several with patches lifted off
    sol = solve(model, W)
    assert sol.converged.all()
    for i, w in enumerate(W):
        ref = _qp_reference(model, w)
        np.testing.assert_allclose(sol.forces[i], ref, rtol=0, atol=2e-5 * max(1, ref.max()))


def test_kkt_equilibrium_complementarity():
    g = _geometry()
    model = build_coupled_model(g, kernel_K(g), 2e5, strap_model="handles", strap_tension=30)
    W = _logs(600, seed=13)
    sol = solve(model, W)
    assert sol.converged.all()
    P = model.patch_forces(sol.u, sol.contact).reshape(len(W), -1)
    r = W + model.W_pre
    # equilibrium of the cuff: T^T P = W + W_pre, to round-off
    np.testing.assert_allclose(P @ model.T, r, rtol=0, atol=1e-9 * np.abs(r).max())
    # normal forces are the reported forces, compressive only
    np.testing.assert_allclose(P[:, model.normal_dofs], sol.forces, rtol=0, atol=1e-9)
    assert np.all(sol.forces >= 0)
    # an open patch does not penetrate: (T u + delta)_n - (C_t P)_n <= 0
    gap = (sol.u @ model.T.T + model.delta - P @ model.C_t.T)[:, model.normal_dofs]
    open_ = ~sol.contact
    assert open_.any()
    assert np.all(gap[open_] <= 1e-9 * np.abs(gap).max())
    # a pressing patch is tied: the cuff spring closes the gap exactly
    tied = (sol.u @ model.T.T + model.delta - P @ model.C.T)[:, model.normal_dofs]
    np.testing.assert_allclose(tied[sol.contact], 0, atol=1e-12)


def test_mirror_loads_give_mirror_forces():
    g = _geometry()
    model = build_coupled_model(g, kernel_K(g), 3e5, strap_tension=15.0)
    W = _logs(200, seed=17)
    f = solve(model, W).forces.reshape(-1, 3, 7)
    # the middle row's plane x = 0 mirrors rows A <-> C: (x, y, z) -> (-x, y, z)
    Mx = np.diag([-1.0, 1.0, 1.0])
    Wm = np.hstack([W[:, :3] @ Mx.T, -(W[:, 3:] @ Mx.T)])
    fm = solve(model, Wm).forces.reshape(-1, 3, 7)
    np.testing.assert_allclose(fm, f[:, ::-1, :], atol=1e-9 * np.abs(f).max())


def test_linear_while_no_patch_lifts_off():
    g = _geometry()
    model = build_coupled_model(g, kernel_K(g), 3e5, strap_tension=40.0)
    rng = np.random.default_rng(2)
    for _ in range(20):
        w1, w2 = rng.normal(size=(2, 6)) * np.array([2, 2, 2, 0.05, 0.05, 0.05])
        sol = solve(model, np.array([np.zeros(6), w1, w2, w1 + w2]))
        assert sol.contact.all()
        f = sol.forces
        np.testing.assert_allclose(f[3] - f[0], (f[1] - f[0]) + (f[2] - f[0]),
                                   atol=1e-10 * np.abs(f).max())


def test_zero_wrench_carries_the_spring_model_preload():
    g = _geometry()
    k_c = np.linspace(5e4, 5e5, g.n)
    coupled = build_coupled_model(g, kernel_K(g), k_c, strap_tension=15.0)
    spring = build_model(g, 40e3, k_c, strap_tension=15.0)
    sol = solve(coupled, np.zeros(6))
    np.testing.assert_allclose(sol.forces, spring.f0, rtol=1e-12)
    np.testing.assert_allclose(sol.u, 0, atol=1e-15)


def test_batch_per_sample_single_and_safeguard_agree(monkeypatch):
    g = _geometry()
    model = build_coupled_model(g, kernel_K(g, dofs=6), 1e5, strap_model="handles",
                                strap_tension=10.0)
    W = _logs(900, seed=19)
    ref = solve(model, W)
    assert ref.converged.all()
    peak = np.abs(ref.forces).max()
    np.testing.assert_allclose(solve_per_sample(model, W[:200]).forces, ref.forces[:200],
                               rtol=0, atol=1e-10 * peak)
    one = Solver(model)
    np.testing.assert_allclose([one.forces(w) for w in W[:200]], ref.forces[:200], rtol=0,
                               atol=1e-10 * peak)
    # the safeguard alone (non-negative least squares) finds the same answers
    monkeypatch.setattr(active_set, "PLAIN_ITERATIONS", 1)
    res = solve(model, W, initial_active=np.zeros(g.n, bool))
    assert res.converged.all()
    assert (res.iterations > 1).any()
    np.testing.assert_allclose(res.forces, ref.forces, rtol=0, atol=1e-9 * peak)


@settings(max_examples=40, deadline=None)
@given(rows=st.integers(1, 3), count=st.integers(3, 9), step=st.floats(20.0, 40.0),
       c0=st.floats(5e-6, 5e-5), beta=st.floats(0.0, 5e-5), ell=st.floats(0.01, 0.06),
       k_c=st.floats(3e4, 1e7), tension=st.floats(0.0, 40.0),
       strap=st.sampled_from(["hoop", "handles"]), seed=st.integers(0, 1000))
def test_random_cuffs_converge_to_the_kkt_point(rows, count, step, c0, beta, ell, k_c, tension,
                                                 strap, seed):
    g = cuff_geometry(np.linspace(-0.025, 0.025, rows), 0.045, 0.02, 90.0 - step * count / 2,
                      step, count)
    model = build_coupled_model(g, kernel_K(g, c0, beta, ell), k_c, strap_model=strap,
                                strap_tension=tension)
    rng = np.random.default_rng(seed)
    W = rng.normal(size=(40, 6)) * np.array([60, 60, 60, 2, 2, 2])
    sol = solve(model, W)
    assert sol.converged.all()
    P = model.patch_forces(sol.u, sol.contact).reshape(len(W), -1)
    r = W + model.W_pre
    np.testing.assert_allclose(P @ model.T, r, rtol=0, atol=1e-8 * (1 + np.abs(r).max()))
    assert np.all(sol.forces >= 0)
    gap = (sol.u @ model.T.T + model.delta - P @ model.C_t.T)[:, model.normal_dofs]
    assert np.all(gap[~sol.contact] <= 1e-8 * (1e-12 + np.abs(gap).max()))


@pytest.mark.parametrize("K, match", [
    (np.eye(5), "expected shape"),
    (np.full((63, 63), np.nan), "finite"),
    (np.triu(np.ones((63, 63))) + np.eye(63), "symmetric"),
    (-np.eye(63), "positive definite"),
])
def test_bad_surface_stiffness_is_rejected(K, match):
    with pytest.raises(ValueError, match=match):
        build_coupled_model(_geometry(), K, 1e5)


def _own_normal_output(g, K):
    """N_e = n_e^T K_t,e: the force along n_e of patch e's own skin motion (3 dofs a patch)."""
    N = np.zeros((g.n, 3 * g.n))
    for e in range(g.n):
        N[e, 3 * e:3 * e + 3] = g.normals[e] @ K[3 * e:3 * e + 3, 3 * e:3 * e + 3]
    return N


def test_normal_output_map_is_consistent_with_the_default():
    # N q with N_e = n_e^T K_t,e (the force along n_e of patch e's own skin motion) is what
    # the model reports without an output map when K_t is block diagonal; with a
    # perturbed N, the hoop preload is still what the patches report at zero wrench
    rng = np.random.default_rng(3)
    g = _geometry()
    k_t = rng.uniform(30e3, 60e3, g.n)
    K = _diagonal_K(g, k_t, shear_ratio_from_poisson(0.45))
    N = _own_normal_output(g, K)
    k_c = rng.uniform(5e4, 5e5, g.n)
    plain = build_coupled_model(g, K, k_c, strap_tension=15.0)
    mapped = build_coupled_model(g, K, k_c, strap_tension=15.0, normal_output=N)
    W = _logs(600, seed=23)
    a, b = solve(plain, W), solve(mapped, W)
    np.testing.assert_allclose(b.forces, a.forces, rtol=0, atol=1e-10 * np.abs(a.forces).max())
    np.testing.assert_allclose([Solver(mapped).forces(w) for w in W[:50]], a.forces[:50],
                               rtol=0, atol=1e-10 * np.abs(a.forces).max())
    N2 = N * (1 + 0.05 * rng.standard_normal(N.shape)) + 500.0 * rng.standard_normal(N.shape)
    perturbed = build_coupled_model(g, K, k_c, strap_tension=15.0, normal_output=N2)
    spring_f0 = build_model(g, k_t, k_c, strap_tension=15.0).f0
    np.testing.assert_allclose(solve(perturbed, np.zeros(6)).forces, spring_f0, rtol=1e-9)
    with pytest.raises(ValueError, match="normal output"):
        build_coupled_model(g, K, k_c, normal_output=N[:, :10])


def test_an_output_map_that_cannot_report_the_preload_is_refused():
    """With N_e = n_e^T K_t,e the patches report the hoop preload f0 at zero wrench. An
    output map under which one patch would have to pull to report its f0 (here: that
    patch's map reversed) cannot give the documented preload; it is refused by name
    instead of silently falling back to other patch forces."""
    rng = np.random.default_rng(4)
    g = _geometry()
    k_t = rng.uniform(30e3, 60e3, g.n)
    K = _diagonal_K(g, k_t, shear_ratio_from_poisson(0.45))
    N = _own_normal_output(g, K)
    N[4] *= -1.0
    with pytest.raises(ValueError, match=rf"patch {g.labels[4]} would have to pull"):
        build_coupled_model(g, K, 1e5, strap_tension=15.0, normal_output=N)
    # without a strap there is no preload to report: the same map is accepted
    build_coupled_model(g, K, 1e5, strap_tension=0.0, normal_output=N)
