"""Equilibrium of the spring model with a nonlinear tissue law: damped Newton on a convex energy.

With a tissue law F_e (:mod:`phri_spring.physics.tissue_laws`) in series with
each element's linear cuff spring, the equilibrium of docs/model.md section 4
minimises

    Pi(u) = sum_e psi_e(delta0_e + b_e . u) + 1/2 u^T K_s u - (W + W_pre)^T u,

psi_e the series element's stored energy (0 for a lifted element). psi_e is
convex and once continuously differentiable for a monotone law and K_s is
positive definite, so Pi is strictly convex: one minimiser, and Newton's method
with a backtracking (Armijo) line search reaches it from any start. The step
uses the Hessian K_s + sum_e f_e'(g_e) b_e b_e^T, whose element tangents jump
where an element lifts off; the line search keeps the iteration monotone in Pi
across those kinks. A row is converged when the residual of the six equilibrium
equations, sum_e f_e b_e + K_s u - r, is below 1e-10 of the forces in them.

Every row of a block is iterated at once. A law with history (``has_state``)
is solved one sample after another, its state advanced after each.
"""

from __future__ import annotations

import numpy as np

__all__ = ["solve_newton", "NEWTON_ITERATIONS", "RESIDUAL_RTOL"]

#: most Newton steps per sample (on top of the linear solve that starts it)
NEWTON_ITERATIONS = 60
#: a row is converged when |residual| <= RESIDUAL_RTOL * (force scale of its equations)
RESIDUAL_RTOL = 1e-10
_ARMIJO = 1e-4
_HALVINGS = 40


def _state(model, u, r):
    """Tissue compression d_t, residual, energy and residual scale of displacements u (m, 6).

    The series split d_t of every element's compression is computed once here; the force,
    energy and (in the Newton step) tangent all follow from it.
    """
    el = model.element
    b = model.geometry.b
    g = model.delta0 + u @ model.bT
    dt = el.tissue_compression(g)
    f, psi = el.from_share(dt)
    Ku = u @ model.K_s
    res = f @ b + Ku - r
    scale = (np.abs(f) @ np.abs(b) + np.abs(Ku) + np.abs(r)).max(axis=1)
    Pi = psi.sum(axis=1) + 0.5 * np.einsum("mi,mi->m", u, Ku) - np.einsum("mi,mi->m", r, u)
    return dt, res, Pi, scale


def _newton_rows(model, r, u, max_steps):
    """Damped Newton from u (m, 6), in place, for right-hand sides r (m, 6): its, converged."""
    m = len(r)
    its = np.zeros(m, dtype=np.int64)
    conv = np.zeros(m, dtype=bool)
    dt, res, Pi, scale = _state(model, u, r)   # dt: the tissue's share of each compression
    active = np.arange(m)
    for step_no in range(max_steps + 1):
        ok = np.abs(res[active]).max(axis=1) <= RESIDUAL_RTOL * np.maximum(scale[active], 1e-300)
        conv[active[ok]] = True
        active = active[~ok]
        if active.size == 0 or step_no == max_steps:
            break
        H = (model.element.tangent_from_share(dt[active]) @ model.bb).reshape(-1, 6, 6) + model.K_s
        d = -np.linalg.solve(H, res[active][:, :, None])[:, :, 0]
        slope = np.einsum("mi,mi->m", res[active], d)         # < 0: a descent direction
        alpha = np.ones(active.size)
        pending = np.arange(active.size)
        for _ in range(_HALVINGS):
            rows = active[pending]
            un = u[rows] + alpha[pending, None] * d[pending]
            dtn, resn, Pin, scn = _state(model, un, r[rows])
            # Armijo's sufficient decrease, or, where the energy is flat to round-off, a
            # smaller residual (near the minimum Pi cannot resolve the step any more)
            good = (Pin <= Pi[rows] + _ARMIJO * alpha[pending] * slope[pending]) | (
                (Pin <= Pi[rows] + 1e-13 * np.abs(Pi[rows]))
                & (np.abs(resn).max(axis=1) < np.abs(res[rows]).max(axis=1)))
            acc = rows[good]
            u[acc], dt[acc], res[acc], Pi[acc], scale[acc] = (un[good], dtn[good], resn[good],
                                                              Pin[good], scn[good])
            pending = pending[~good]
            if pending.size == 0:
                break
            alpha[pending] *= 0.5
        its[active] += 1
        if pending.size:   # no step lowers the energy: those rows stop, not converged
            active = np.setdiff1d(active, active[pending])
    return its, conv


def solve_newton(model, r, u0, *, max_iterations: int = NEWTON_ITERATIONS, state=None):
    """Equilibria of a spring model with a nonlinear element law for right-hand sides r.

    Parameters
    ----------
    model : SpringModel
        With ``model.element`` a :class:`~phri_spring.physics.tissue_laws.SeriesElement`.
    r : ndarray, shape (m, 6)
        W + W_pre [N, N*m].
    u0 : ndarray, shape (m, 6)
        Starting displacements (e.g. the linear model's solution) [m, rad].
    max_iterations : int
        Most Newton steps per sample.
    state : optional
        The law's state before the first row (laws with history only).

    Returns
    -------
    u : ndarray, shape (m, 6)
    its : ndarray of int, shape (m,)
        Newton steps each row took.
    converged : ndarray of bool, shape (m,)
    state
        The law's state after the last row (None for a law without history).
    """
    r = np.atleast_2d(np.asarray(r, dtype=float))
    u = np.array(u0, dtype=float, copy=True).reshape(len(r), 6)
    law = model.element.law
    if law is None or not law.has_state:
        its, conv = _newton_rows(model, r, u, max_iterations)
        return u, its, conv, state
    # history: one sample after another, the law's state advanced by each
    its = np.zeros(len(r), dtype=np.int64)
    conv = np.zeros(len(r), dtype=bool)
    state = law.initial_state() if state is None else state
    for i in range(len(r)):
        law.state = state
        ui = u[i:i + 1]
        it_i, ok = _newton_rows(model, r[i:i + 1], ui, max_iterations)
        u[i], its[i], conv[i] = ui[0], it_i[0], ok[0]
        state = law.advance(state, model.element.tissue_compression(model.delta0 + u[i] @ model.bT))
    law.state = state
    return u, its, conv, state
