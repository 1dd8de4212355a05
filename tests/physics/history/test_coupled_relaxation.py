"""Relaxing tissue on the coupled arm (docs/model.md section 15.1).

The reference solves the same layer independently: while every patch presses and sticks,
each sample is a linear system (the patches tied to the cuff through their cuff springs,
the layer's patch forces the hereditary integral of its elastic forces, summed over the
whole sampled history with the exact weights of a response linear between samples:
tests/support/reference_qlv.py's formula, not the recursion). Without relaxation the model
is the elastic coupled arm; a load held long is carried by the relaxed layer, G_inf K_t.
"""

import dataclasses

import numpy as np

from support.coupled_reference import kernel_K
from phri_spring.physics.contact.solver import solve
from phri_spring.physics.continuum.coupled import build_coupled_model
from phri_spring.physics.cuff.geometry import cuff_geometry
from phri_spring.physics.history.continuum import CoupledRelaxation
from phri_spring.physics.history.model import activation_scale
from phri_spring.physics.history.relaxation import Prony
from phri_spring.synthetic.wrench import smooth_random_log


def _model(k_c=2e5, dofs=3):
    g = cuff_geometry([-0.025, 0.0, 0.025], 0.045, 0.025, 75.0, 35.0, 7)
    return build_coupled_model(g, kernel_K(g, dofs=dofs), k_c, strap_tension=20.0)


def _log(m, seed, scale):
    _, W = smooth_random_log(m, seed=seed)
    t = 0.01 * np.arange(m) + np.cumsum(np.random.default_rng(seed).uniform(0, 0.02, m))
    return W * scale, t


def _hereditary_reference(model, prony, W, t, s):
    """Patch forces (m, N) of a layer that presses and sticks everywhere, by the exact
    hereditary sum over the history (O(m^2)) and one linear solve per sample."""
    N = model.n * model.dofs
    Ct, T, delta = model.C_t, model.T, model.delta
    Cc = np.diag(np.diag(model.C - model.C_t))
    Fe = np.zeros((len(W), N))
    P = np.zeros((len(W), N))
    for k in range(len(W)):
        # P_k = c1 F^e_k + R_k: R_k the history's part (F^e before sample k)
        R = np.zeros(N)
        c1 = prony.relaxed
        for g, tau in zip(prony.g, prony.tau):
            for i in range(1, k + 1):
                dt = t[i] - t[i - 1]
                w = tau * (np.exp(-(t[k] - t[i]) / tau) - np.exp(-(t[k] - t[i - 1]) / tau)) / dt
                if i < k:
                    R += g * w * (Fe[i] - Fe[i - 1])
                else:        # the last step's weight multiplies F^e_k - F^e_{k-1}
                    c1 += g * w
                    R -= g * w * Fe[k - 1]
        # tied dofs: T u + delta = C_c P + C_t F^e / s,  F^e = (P - R) / c1;  T^T P = r
        A = np.zeros((N + 6, N + 6))
        b = np.zeros(N + 6)
        A[:N, :N] = Cc + Ct / (c1 * s[k])
        A[:N, N:] = -T
        b[:N] = delta + Ct @ R / (c1 * s[k])
        A[N:, :N] = T.T
        b[N:] = W[k] + model.W_pre
        x = np.linalg.solve(A, b)
        P[k] = x[:N]
        Fe[k] = (P[k] - R) / c1
    return P


def _patch_forces(sol, model):
    parts = [sol.normal[..., None], sol.tangential]
    if sol.moments is not None:
        parts.append(sol.moments)
    return np.concatenate(parts, axis=2).reshape(len(sol.normal), -1)


def test_the_layer_relaxes_as_the_hereditary_integral_says():
    model = _model()
    prony = Prony([0.35, 0.2], [0.05, 0.8])
    W, t = _log(160, 3, 0.2)
    a = np.clip(0.5 + 0.5 * np.sin(t * 4.0), 0.0, 1.0)
    sol = CoupledRelaxation(model, prony, 2.0).solve_log(W, t, a)
    assert sol.converged.all() and sol.contact.all()      # pressing everywhere
    ref = _hereditary_reference(model, prony, W, t, activation_scale(a, 2.0))
    got = _patch_forces(sol, model)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-8 * np.abs(ref).max())


def test_no_relaxation_is_the_elastic_coupled_arm():
    model = _model(dofs=6)
    W, t = _log(300, 5, 1.0)                  # with lift-off
    sol = CoupledRelaxation(model, Prony([0.0], [1.0])).solve_log(W, t)
    ref = solve(model, W)
    assert (~ref.contact).any()
    np.testing.assert_array_equal(sol.converged, ref.converged)
    ok = ref.converged
    np.testing.assert_allclose(sol.forces[ok], ref.forces[ok], rtol=0, atol=1e-9)


def test_a_load_held_long_is_carried_by_the_relaxed_layer():
    model = _model()
    prony = Prony([0.3, 0.25], [0.1, 1.0])
    W = np.tile([0.0, -25.0, 6.0, 0.0, 0.2, 0.0], (4, 1))
    sol = CoupledRelaxation(model, prony).solve_log(W, [0.0, 0.01, 500.0, 1000.0])
    relaxed = dataclasses.replace(model, C_t=model.C_t / prony.relaxed,
                                  C=model.C - model.C_t + model.C_t / prony.relaxed)
    ref = solve(relaxed, W[-1:])
    np.testing.assert_allclose(sol.forces[-1], ref.forces[0], rtol=0, atol=1e-9)
    # the first sample found the tissue rested too (the same relaxed answer)
    np.testing.assert_allclose(sol.forces[0], ref.forces[0], rtol=0, atol=1e-9)


def test_chunks_continue_the_history():
    model = _model()
    prony = Prony([0.4], [0.3])
    W, t = _log(120, 9, 1.0)
    whole = CoupledRelaxation(model, prony).solve_log(W, t)
    m = CoupledRelaxation(model, prony)
    parts = [m.solve_log(W[a:b], t[a:b]).forces for a, b in [(0, 17), (17, 80), (80, 120)]]
    np.testing.assert_allclose(np.vstack(parts), whole.forces, rtol=0, atol=1e-12,
                               equal_nan=True)


def test_with_lift_off_the_contact_laws_hold_at_every_sample():
    from support.helpers import check_friction_laws
    from phri_spring.physics.continuum.coupled import LIFT_OFF_MU

    model = _model()
    W, t = _log(300, 11, 1.0)
    sol = CoupledRelaxation(model, Prony([0.3, 0.2], [0.05, 0.8])).solve_log(W, t)
    assert sol.converged.mean() > 0.95 and (~sol.contact).any()
    check_friction_laws(model, W, sol, LIFT_OFF_MU)   # balance, cone, released carry nothing
