"""Friction on the spring arms with a nonlinear tissue law (docs/model.md section 12.6).

With friction, an element of the spring model is a normal spring and a tangential tie.
With the linear law the normal spring is k_e and a state of the interface (which
elements are stuck, sliding or released) is affine in the wrench. With a nonlinear law
the normal spring is the element's series element (the tissue law F_e in series with
its cuff spring k_c,e, :class:`~phri_spring.physics.laws.SeriesElement`): its
force f_e(g) at a total compression g solves g = d_t + F_e(d_t) / k_c,e for the
tissue's share d_t, and its tangent is 1 / (1 / F_e'(d_t) + 1 / k_c,e). The tangential
tie is the bonded nonlinear model's shear spring, k_s,e = eta k_e with k_e the element's
stiffness at small compression: the law stiffens the normal response only.

:class:`NormalResponse` evaluates f and its tangent through the law's ``force_tangent``
alone (any registered law), warm-started from the share of the last evaluation, so that
an element costs a Newton step or two on its split per call. :func:`block_nonlinear`
solves rows of a log in one state (no sliding element) together: a Newton iteration on
the six equilibrium equations per row, vectorised over the rows, and the same checks as
the linear blocks (stuck elements pressing and inside their cone, released ones not
penetrating).
"""

from __future__ import annotations

import numpy as np

from .states import RELEASED, STUCK
from ..contact.spd6 import spd_solve_batched

__all__ = ["NormalResponse", "block_nonlinear", "frictionless_unheld", "BLOCK_RTOL"]

#: Newton steps on an element's split (tissue share) per evaluation before the law's own
#: safeguarded inversion takes over
_SPLIT_STEPS = 8
#: a split step this small against the compression ends the split's Newton iteration
_SPLIT_RTOL = 1e-9
#: Newton steps of a block's rows before the rows left are handed to the event solver
_BLOCK_STEPS = 25
#: Newton steps after which a block ends before its first row not yet solved
_SLOW_AFTER = 4
#: how far past its cone a doubtful element's linearised first step must go for the
#: block to be skipped (the step's error is second order in the load step; a wrong call
#: only costs time: the event solver then takes the sample)
_PROBE_MARGIN = 0.05
#: rows up to this many are solved by LAPACK's 6x6 solves, more by the vectorised Cholesky
_SMALL_BATCH = 64
#: a block row is solved when its equilibrium residual is below this share of its forces
BLOCK_RTOL = 1e-12


class NormalResponse:
    """The normal force of every element as a function of its total compression.

    Parameters
    ----------
    element : phri_spring.physics.laws.series.SeriesElement
        The model's series elements (a tissue law, possibly with a rigid cuff).
    """

    def __init__(self, element):
        self.law = element.law
        k_cuff = np.asarray(element.k_cuff, dtype=float)
        with np.errstate(divide="ignore"):
            self.c = np.broadcast_to(1.0 / k_cuff, (self.law.n,)).copy()   # 0: rigid cuff
        self.rigid_cuff = bool(np.all(self.c == 0.0))

    def preload_scale(self, dn) -> float:
        """The largest element force [N] at the preload compressions dn (n,) [m]: the force
        scale of the equilibrium's round-off when the preload's forces cancel on the cuff
        (a hoop around the arm). Made once."""
        if getattr(self, "_preload_scale", None) is None:
            self._preload_scale = float(np.abs(self.evaluate(dn)[0]).max(initial=0.0))
        return self._preload_scale

    def share_from_force(self, f) -> np.ndarray:
        """The tissue's share d_t [m] that carries normal forces f [N] (0 where f <= 0)."""
        f = np.maximum(np.asarray(f, dtype=float), 0.0)
        return np.where(f > 0, self.law.compression_at(f), 0.0)

    def memo_from_force(self, f, g):
        """A start for :meth:`evaluate` near compressions g [m] where the elements carry f [N]."""
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            dt = self.share_from_force(f)
            _, Ft = self.law.force_tangent(dt)
            s = 1.0 / (1.0 + Ft * self.c)
            return np.maximum(g, 0.0), dt, s, Ft * s * (np.asarray(g) > 0)

    def evaluate(self, g, memo=None):
        """(f, k, memo) at total compressions g (..., n) [m]: the force [N] (0 where g <= 0),
        the series tangent [N/m] (0 where g <= 0) and what the next call starts from
        (compressions, tissue shares, d d_t / d g and the tangent there). ``memo`` is a
        previous call's (of the same shape), or None."""
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return self.response(np.asarray(g, dtype=float), memo)

    def response(self, g, memo=None):
        """:meth:`evaluate` for the solvers' inner loops: g a float array, and no
        ``np.errstate`` of its own (they hold one around the whole iteration)."""
        gp = np.maximum(g, 0.0)
        law, c = self.law, self.c
        if self.rigid_cuff:
            dt = gp
            F, Ft = law.force_tangent(dt)
        else:
            if memo is None:
                dt = gp / (1.0 + law.k0 * c)
            else:   # the last share moved along the split's tangent
                dt = gp - memo[0]
                dt *= memo[2]
                dt += memo[1]
                np.maximum(dt, 0.0, out=dt)
                np.minimum(dt, gp, out=dt)
            # h(d_t) = d_t + F(d_t) c - g increases with d_t: Newton on it, kept in
            # [0, g]. It converges quadratically, so once a step is below _SPLIT_RTOL
            # of the compression the error left is far below round-off, and the force
            # moves by its tangent times that step
            small = _SPLIT_RTOL * gp.max()
            F, Ft = law.force_tangent(dt)
            for _ in range(_SPLIT_STEPS):
                step = F * c
                step += dt
                step -= gp
                step /= 1.0 + Ft * c
                new = dt - step
                np.maximum(new, 0.0, out=new)
                np.minimum(new, gp, out=new)
                if not np.abs(step).max() > small:
                    F = F + Ft * (new - dt)
                    dt = new
                    break
                dt = new
                F, Ft = law.force_tangent(dt)
            else:
                dt = law.series_share(gp, c)
                F, Ft = law.force_tangent(dt)
        s = Ft * c
        s += 1.0
        np.divide(1.0, s, out=s)
        k = Ft * s
        on = g > 0
        F = np.where(on, F, 0.0)
        k *= on
        return F, k, (gp, dt, s, k)


def block_nonlinear(form, state, r, f_tol, x_tol, probe=None):
    """Rows r (m, 6) of the spring model in the state ``state`` (no sliding element) with a
    nonlinear normal response; returns (u, P, k, u_next, memo) as the linear blocks do: the
    first k rows keep the state, u_next is a start for the event at row k (None if k = m),
    memo the series elements' split at row k - 1 (the next sample's start; None if k = 0).

    Each row is solved by Newton's method on its six equilibrium equations, from the
    state's displacement moved by one linearised step; a row that is not solved within
    _BLOCK_STEPS, or whose answer leaves the state, ends the block there.

    ``probe`` (n,) bool: elements whose grip is in doubt (they slid at the last sample).
    Where the first row's linearised step already takes one of them past its cone by more
    than _PROBE_MARGIN, the block is not solved: (k = 0, u_next = that step's u).
    """
    el, normal = form.elements, form.normal_response
    n, mu = form.n, form.mu
    stuck = state.cls == STUCK
    rel = state.cls == RELEASED
    kt_s = el.kt * stuck
    # the stuck ties: sum_e Tt_e^T kt_e (Tt_e u - z_e) = Kt u - ct
    Kt = (kt_s @ el.TT).reshape(6, 6)
    z = state.z[:, 1:3]
    ct = el.TtT @ (kt_s[:, None] * z).ravel()
    Tn, TnT, dn, NN = el.Tn, el.TnT, el.dn, el.NN
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        memo = state.memo
        f0 = state.P[0::3]
        if memo is None:    # a path's start: its forces are the strap's, not yet solved
            g0 = Tn @ state.u + dn
            f0, _, memo = normal.response(g0, normal.memo_from_force(f0, g0))
        # the state's internal force and tangent: its forces balance the wrench it was
        # reached at, and the memo holds the tangent there (a first step needs no more)
        F0 = state.u @ Kt.T
        F0 += (f0 * stuck) @ Tn
        F0 -= ct
        K0 = Kt + ((memo[3] * stuck) @ NN).reshape(6, 6)
        try:
            u = state.u + np.linalg.solve(K0, (r - F0).T).T
        except np.linalg.LinAlgError:
            return np.zeros((0, 6)), np.zeros((0, 3 * n)), 0, state.u, None
        if probe is not None:
            # the first row's tie forces and, linearised, normal forces of the doubtful
            # elements: one clearly beyond its cone slides on (an event), and a block
            # would solve its rows only to fail the check
            at = probe & stuck
            pt = (el.Tt3[at] @ u[0]).reshape(-1, 2) - z[at]
            pt *= el.kt[at, None]
            fn = f0[at] + memo[3][at] * (Tn[at] @ (u[0] - state.u))
            if np.any(np.hypot(pt[:, 0], pt[:, 1]) > (1.0 + _PROBE_MARGIN) * mu * fn):
                return np.zeros((0, 6)), np.zeros((0, 3 * n)), 0, u[0], None
        scale = np.abs(r).max(axis=1) + np.abs(form.W_pre).max() + normal.preload_scale(dn)
        tol = BLOCK_RTOL * scale
        m = len(r)
        done = np.zeros(m, dtype=bool)
        # every row iterates until all are solved (a solved row's step is held at 0): at a
        # block's few rows one array operation costs what it costs, and rows taken out
        # and put back cost more than the rows themselves
        for its in range(_BLOCK_STEPS + 1):
            g = u @ TnT
            g += dn
            f, k, memo = normal.response(g, memo)
            f = f * stuck
            R = u @ Kt.T
            R += f @ Tn
            R -= ct
            R -= r
            done |= np.abs(R).max(axis=1) <= tol
            if done.all():
                break
            if its >= _SLOW_AFTER and done[0]:
                # the rows before the first unsolved one are solved: the block ends there
                # (a row this slow is usually one where the state changes)
                m = int(np.argmin(done))
                break
            H = ((k * stuck) @ NN).reshape(-1, 6, 6)
            H += Kt
            if m <= _SMALL_BATCH:
                try:
                    step = np.linalg.solve(H, R[:, :, None])[:, :, 0]
                except np.linalg.LinAlgError:
                    step = spd_solve_batched(H.reshape(-1, 36).T, R)
            else:
                step = spd_solve_batched(H.reshape(-1, 36).T, R)
            step[done] = 0.0
            u = u - step
    # the state's checks on the solved rows (a row left unsolved, or not finite, fails)
    u, g, f, done, x_tol, f_tol = u[:m], g[:m], f[:m], done[:m], x_tol[:m], f_tol[:m]
    Pt = (u @ el.TtT).reshape(m, n, 2) - z
    Pt *= kt_s[:, None]
    good = done
    if stuck.any():
        good &= np.all(g[:, stuck] >= -x_tol[:, None], axis=1)
        if mu < np.inf:
            tn = np.sqrt(Pt[:, stuck, 0] ** 2 + Pt[:, stuck, 1] ** 2)
            good &= np.all(tn <= mu * f[:, stuck] + f_tol[:, None], axis=1)
    if rel.any():
        good &= np.all(g[:, rel] <= x_tol[:, None], axis=1)
    bad = np.flatnonzero(~good)
    k = int(bad[0]) if bad.size else m
    P = np.zeros((k, n, 3))
    P[:, :, 0] = f[:k]
    P[:, :, 1:3] = Pt[:k]
    u_next = None
    if k < len(r):
        u_next = u[k] if k < m and np.all(np.isfinite(u[k])) else state.u
    memo_last = tuple(a[k - 1].copy() for a in memo) if k else None
    return u[:k], P.reshape(k, 3 * n), k, u_next, memo_last


def frictionless_unheld(form) -> np.ndarray:
    """The projector (6, 6) onto the wrenches the spring model's normal forces cannot carry
    at all (the complement of their span: for a cuff around the arm, the axial force and
    the torsion about the axis). With mu = 0 a wrench with a part there has no equilibrium."""
    Tn = form.elements.Tn
    return np.eye(6) - np.linalg.pinv(Tn) @ Tn
