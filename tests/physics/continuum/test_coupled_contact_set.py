"""The coupled model reports the contact set its solver settled on.

With the built-in FE, a patch reports the normal traction integrated over it (N q),
clipped at 0, while the contact program works with the patch's normal force P_n. The
two differ in sign near lift-off (a patch still pressing, P_n > 0, can have a net
normal traction <= 0 because the traction pulls at its rim), so "reported force > 0"
is not the contact set. Every consumer (``contacts_in_touch``, the interface stiffness,
``--shear``, the design studies' lift-off fraction) must use the solver's set.

The checks are independent of the code's own contact bookkeeping:

* equilibrium of the patch forces rebuilt from (u, contact), T^T P = W + W_pre, which
  holds to round-off only for the set the solver used (any other set gives other P);
* the contact conditions of the program (P_n >= 0 on the set, penetration <= 0 off it);
* the support of an independent solution of the program, scipy's Lawson-Hanson NNLS
  on the problem reduced to the normal forces, built here from the model's matrices.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import nnls

pytest.importorskip("skfem")

from phri_spring.io.config import load_config  # noqa: E402
from phri_spring.physics.continuum import tissue as fe_tissue  # noqa: E402
from phri_spring.physics.continuum.coupled import build_coupled_model  # noqa: E402
from phri_spring.physics.contact.solver import Solver, solve  # noqa: E402
from phri_spring.workflows.common import geometry_from_config  # noqa: E402

from support.helpers import REPO  # noqa: E402

HUMAN = REPO / "configs" / "human_upper_arm.yaml"


@pytest.fixture(scope="module")
def human_model():
    """The human preset's geometry on its 25 mm, 30 kPa layer, built-in FE (coarse level 1:
    the contact bookkeeping, not the mesh, is under test), its cuff and strap; every tie
    bonded (the program of docs/model.md 10.3, whose contact set is under test)."""
    cfg = load_config(HUMAN)
    g = geometry_from_config(cfg)
    ops = fe_tissue.condensed_surface_operators(g, 0.025, 3.0e4, 0.45, level=1)
    k_c = np.asarray(cfg.cuff_stiffness, dtype=float)
    return build_coupled_model(g, ops.K, k_c, strap_tension=15.0, normal_output=ops.N,
                               lift_off=False)


def _wrenches(n, seed):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 6)) * np.array([40.0, 40.0, 40.0, 2.0, 2.0, 2.0])


def _nnls_support(model, r):
    """Contact set of the program min 1/2 P^T C P - delta^T P s.t. T^T P = r, P_n >= 0,
    reduced to the normal forces f by eliminating the tied tangential dofs and u, solved
    by NNLS: written out here from C, T, delta, independently of the solver's code."""
    d = model.dofs
    N = np.arange(model.n) * d
    Tn = np.setdiff1d(np.arange(model.n * d), N)
    C, T, dl = model.C, model.T, model.delta
    # KKT of the equality-constrained part for fixed f: [C_TT  -T_T; -T_T^T 0] [P_T; u]
    #   = [dl_T - C_TN f; -(r - T_N^T f)]
    nt = len(Tn)
    A = np.zeros((nt + 6, nt + 6))
    A[:nt, :nt] = C[np.ix_(Tn, Tn)]
    A[:nt, nt:] = -T[Tn]
    A[nt:, :nt] = -T[Tn].T
    Ainv = np.linalg.inv(A)

    def state(f):
        rhs = np.concatenate([dl[Tn] - C[np.ix_(Tn, N)] @ f, -(r - T[N].T @ f)])
        x = Ainv @ rhs
        return x[:nt], x[nt:]

    # gradient in f: g(f) = C_NN f + C_NT P_T(f) - dl_N - T_N u(f) = M f + m (affine)
    def grad(f):
        PT, u = state(f)
        return C[np.ix_(N, N)] @ f + C[np.ix_(N, Tn)] @ PT - dl[N] - T[N] @ u

    m0 = grad(np.zeros(model.n))
    M = np.column_stack([grad(e) - m0 for e in np.eye(model.n)])
    M = 0.5 * (M + M.T)
    L = np.linalg.cholesky(M)
    f, _ = nnls(L.T, -np.linalg.solve(L, m0))
    return f, f > 1e-9 * max(f.max(), 1e-300)


def test_contact_set_is_the_solvers_not_the_sign_of_the_reported_force(human_model):
    model = human_model
    W = _wrenches(1500, seed=5)
    sol = solve(model, W)
    assert sol.converged.all()
    # equilibrium of the patch forces of the reported set, to round-off
    P = model.patch_forces(sol.u, sol.contact).reshape(len(W), -1)
    resid = P @ model.T - (W + model.W_pre)
    scale = np.abs(W + model.W_pre).max()
    assert np.abs(resid).max() <= 1e-9 * scale
    # contact conditions of the program: pressing on the set, no penetration off it
    Pn = P[:, model.normal_dofs]
    assert (Pn[sol.contact] >= -1e-9 * scale).all()
    assert (np.abs(Pn[~sol.contact]) <= 1e-9 * scale).all()
    # the case this is about happens: pressing patches that report 0 N
    pressing_at_zero = sol.contact & (sol.forces <= 0)
    assert pressing_at_zero.any(), "no sample with a pressing patch reporting 0 N: test is void"
    # the set of an independent solution of the same program
    rows = np.flatnonzero(pressing_at_zero.any(axis=1))[:25]
    for i in rows:
        f, S_ref = _nnls_support(model, W[i] + model.W_pre)
        clear = np.abs(f) > 1e-6 * f.max()          # away from the boundary of the set
        clear |= ~S_ref
        np.testing.assert_array_equal(sol.contact[i][clear], S_ref[clear], err_msg=f"row {i}")
        np.testing.assert_allclose(Pn[i], f, rtol=0, atol=1e-6 * f.max())


def test_single_sample_solver_reports_the_same_set(human_model):
    W = _wrenches(200, seed=6)
    batch = solve(human_model, W)
    solver = Solver(human_model)
    for i, w in enumerate(W):
        solver.forces(w)
        np.testing.assert_array_equal(solver.last_contact, batch.contact[i], err_msg=f"row {i}")


def test_interface_stiffness_uses_the_solvers_set(human_model):
    """The tangent stiffness of the reported set is the response of the model to a small
    extra wrench (finite difference), which only the set actually in force reproduces."""
    model = human_model
    W = _wrenches(1500, seed=5)
    sol = solve(model, W)
    i = int(np.flatnonzero((sol.contact & (sol.forces <= 0)).any(axis=1))[0])
    H = model.tangent_stiffness(sol.u[i], sol.contact[i])
    h = 1e-6
    for j in range(6):
        dw = np.zeros(6)
        dw[j] = h * (1.0 if j < 3 else 0.05)
        plus, minus = solve(model, W[i] + dw), solve(model, W[i] - dw)
        assert np.array_equal(plus.contact, sol.contact[i])
        assert np.array_equal(minus.contact, sol.contact[i])
        du = (plus.u - minus.u) / 2
        np.testing.assert_allclose(H @ du, dw, rtol=0, atol=1e-6 * np.abs(dw).max())
