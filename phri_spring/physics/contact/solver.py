"""Equilibrium of the cuff on the arm in the spring model (docs/model.md sections 4 and 9).

The cuff displacement u* is the unique minimiser of the strictly convex,
piecewise quadratic energy (docs/model.md section 4; the network of the paper's
Fig. 2, Yousaf et al., section II-C)

    Pi(u) = sum_e 1/2 k_e [delta0_e + b_e . u]_+^2 + 1/2 u^T K_s u - (W + W_pre) . u

Method
------
For a fixed active set S (elements in contact) the minimiser solves the 6x6
system (sum_{e in S} k_e b_e b_e^T + K_s) u = W + W_pre - sum_{e in S} k_e delta0_e b_e,
and the compression g_e = delta0_e + b_e . u is the contact indicator. The loop
over contact sets is the shared kernel of :mod:`phri_spring.physics.contact.active_set`
(vectorised over samples, cached factorisations, a neighbour warm start);
:class:`SpringSystem` supplies the spring model's pieces, including its
safeguard: the same Newton direction with an exact line search on Pi, which
makes the method globally convergent. A sample is converged when its active set
is consistent with its displacement (the KKT conditions hold); samples that do
not converge within ``max_iterations``, or whose result is not finite, are
flagged and their forces are NaN.
"""

from __future__ import annotations

import numpy as np

from .spd6 import SYM6_FULL, SYM6_UPPER, spd_solve_batched as _spd_solve_batched
from .solution import Solution
from ..friction.states import interface_mu
from ..springs.outputs import (compression, energy, forces_from_compression, normal_forces,
                             shear_forces)
from .active_set import (PLAIN_ITERATIONS, SET_RTOL, ContactSystem, FactorCache, iterate,
                         key_groups, solve_warm)
from .paths import HUGE, make_system, nonlinear_finish, solve_direct, solve_friction
from .single import Solver
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # annotations only: model.py imports this module for its contact system
    from ..springs.model import SpringModel

__all__ = ["Solution", "solve", "solve_segments", "solve_per_sample", "Solver", "SpringSystem", "FactorCache",
           "compression", "normal_forces", "shear_forces", "energy",
           "PLAIN_ITERATIONS", "make_system"]

#: samples per internal block (bounds the (samples x elements) temporaries)
_BLOCK_ENTRIES = 1 << 21
#: values of g = delta0 + b u computed at a time: a block stays in the processor's cache
#: from its product to its last use, and a product this small is done without first
#: clearing its output
_ROW_BLOCK_VALUES = 1 << 16


def _block_rows(n: int) -> int:
    """Rows of a block of :data:`_ROW_BLOCK_VALUES` values of an (m, n) array (>= 256)."""
    return max(256, _ROW_BLOCK_VALUES // max(int(n), 1))


def _row_blocks(m: int, n: int):
    """(lo, hi) of the consecutive row blocks of an (m, n) array (see :func:`_block_rows`)."""
    step = _block_rows(n)
    for lo in range(0, m, step):
        yield lo, min(m, lo + step)


# --------------------------------------------------------------------------- the spring system
def _exact_step(k, g, h, a0, q) -> float:
    """Exact minimiser alpha >= 0 of Pi(u + alpha d).

    phi'(alpha) = sum_e k_e [g_e + alpha h_e]_+ h_e + a0 + alpha q is piecewise
    linear and non-decreasing, with phi'(0) < 0 along a descent direction.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        bp = -g / h
    bp = np.sort(bp[(h != 0) & (bp > 0) & np.isfinite(bp)])
    edges = np.concatenate([[0.0], bp])
    # slope pieces on each segment [edges[i], edges[i+1]]: active set at the segment's start+
    for i in range(len(edges)):
        lo = edges[i]
        hi = edges[i + 1] if i + 1 < len(edges) else np.inf
        probe = lo + (0.5 * (hi - lo) if np.isfinite(hi) else 1.0 + lo)
        act = (g + probe * h) > 0
        A = np.sum(k[act] * g[act] * h[act]) + a0
        C = np.sum(k[act] * h[act] ** 2) + q
        alpha = -A / C
        if alpha <= hi:
            return float(max(alpha, lo))
    return float(edges[-1])  # pragma: no cover - unreachable for q > 0


class SpringSystem(ContactSystem):
    """The spring model as a :class:`~phri_spring.physics.contact.active_set.ContactSystem`.

    For contact set S: H_S = K_s + sum_{e in S} k_e b_e b_e^T and
    c_S = -sum_{e in S} k_e delta0_e b_e; the indicator is the compression
    g = delta0 + b u (the same for every set).

    Parameters
    ----------
    model : SpringModel
    cache : FactorCache, optional
        Factorisations of the contact sets met; a new one if not given. A cache
        belongs to one model: never share it between models.
    """

    sets_follow_indicator = True

    def __init__(self, model: SpringModel, cache: FactorCache | None = None):
        self.model = model
        self._linear = model.is_linear
        self.n = model.n
        self.cache = FactorCache() if cache is None else cache
        # a contact set's H_S (symmetric: its 21 upper entries) and c_S are sums over the set
        self._set_maps = np.hstack([model.bb[:, SYM6_UPPER], model.delta0_b])

    def factors(self, key, S_row: np.ndarray):
        """(H_S^-1 transposed, c_S) for contact set S: u = (r + c_S) @ Mt solves H_S u = r + c_S."""
        hk = key.item() if isinstance(key, np.generic) else key
        hit = self.cache.get(hk)
        if hit is None:
            model = self.model
            kS = model.k * S_row
            H = model.K_s + (model.b.T * kS) @ model.b
            Mt = np.ascontiguousarray(np.linalg.inv(H).T)
            c = -(kS * model.delta0) @ model.b
            hit = (Mt, c)
            self.cache.put(hk, hit)
        return hit

    def solve_sets(self, keys, S, r):
        m = len(keys)
        if m == 0:
            return np.empty((0, 6))
        if m == 1 or np.all(keys == keys[0]):
            Mt, c = self.factors(keys[0], S[0])
            u = r + c
            return u @ Mt
        uniq, first, inv = np.unique(keys, return_index=True, return_inverse=True)
        G = len(uniq)
        if G <= 4 or 20 * G <= m:
            out = np.empty((m, 6))
            for key, idx in key_groups(keys, (uniq, inv)):
                Mt, c = self.factors(key, S[idx[0]])
                out[idx] = (r[idx] + c) @ Mt
            return out
        # many distinct sets: assemble each distinct set's H_S and c_S once (rows with one
        # key share one set, as in the groups above), then solve every row's 6x6 at once
        model = self.model
        per_row = ((S[first] * model.k) @ self._set_maps)[inv]          # (m, 21 + 6)
        Hf = np.ascontiguousarray(per_row[:, SYM6_FULL].T)
        Hf += model.K_s.reshape(36, 1)
        rhs = r - per_row[:, 21:]
        return _spd_solve_batched(Hf, rhs)

    def indicator(self, u, S=None, keys=None, out=None):
        """Compression g = delta0 + b u [m], (m, n) (written into ``out`` if given)."""
        u = np.asarray(u, dtype=float)
        if u.ndim != 2:
            g = u @ self.model.bT
            g += self.model.delta0
            return g
        # straight into the caller's array if given: no extra pass, no fresh pages
        g = np.empty((len(u), self.n)) if out is None else out
        for lo, hi in _row_blocks(len(u), self.n):
            blk = g[lo:hi]
            np.matmul(u[lo:hi], self.model.bT, out=blk)
            blk += self.model.delta0
        return g

    def consistent(self, S, g, u):
        """Rows whose active set S agrees with the sign of the compression g, to round-off.

        The tolerance follows the round-off of g_e = delta0_e + b_e . u itself,
        ``SET_RTOL * (max_e |delta0_e| + sum_j max_e |b_ej| |u_j|)``, so that it also
        holds when every compression is zero (shear alone carrying the load).
        """
        model = self.model
        tol = (SET_RTOL * (np.abs(np.atleast_2d(u)) @ model.b_absmax + model.delta0_absmax))[:, None]
        wrong = (S & (g < -tol)) | (~S & (g > tol))
        return ~wrong.any(axis=-1)

    def safeguard(self, r, u, budget):
        """Globalised semismooth Newton with an exact line search on Pi, for one sample."""
        model = self.model
        k, b, d0, Ks = model.k, model.b, model.delta0, model.K_s
        its = 0
        while its < budget:
            g = d0 + b @ u
            S = g > 0
            H = Ks + (b.T * (k * S)) @ b
            grad = b.T @ (k * np.maximum(g, 0.0)) + Ks @ u - r
            d = -np.linalg.solve(H, grad)
            its += 1
            u_full = u + d
            g_full = d0 + b @ u_full
            if self.consistent(S[None], g_full[None], u_full)[0]:
                return u_full, None, its, True
            if not np.any(np.abs(d) > 1e-15 * (np.abs(u) + 1e-12)):
                return u_full, None, its, True
            alpha = _exact_step(k, g, b @ d, float((Ks @ u - r) @ d), float(d @ Ks @ d))
            u = u + alpha * d
        # budget spent without a consistent full step: not converged (reported, never hidden)
        return u, None, its, False

    def predict_sets(self, u, S):
        """Contact sets at displacements u: the compression's sign (the set does not matter)."""
        m = len(u)
        out = np.empty((m, self.n), dtype=bool)
        g = np.empty((min(m, _block_rows(self.n)), self.n))
        for lo, hi in _row_blocks(m, self.n):
            np.greater(self.indicator(u[lo:hi], out=g[:hi - lo]), 0.0, out=out[lo:hi])
        return out

    def forces(self, q, out=None, u=None):
        """Normal forces [N] from the indicator (compression) q; in place if ``out is q``.

        With a nonlinear tissue law, the element law's force of the compression.
        """
        if not self._linear:
            f = self.model.element.force(q)
            if out is None:
                return f
            out[...] = f
            return out
        return forces_from_compression(self.model, q, out=out)


# --------------------------------------------------------------------------- batch solver
def solve(model, wrench, *, max_iterations: int = 100, warm_start: bool = True,
          initial_active=None, out: np.ndarray | None = None,
          cache: FactorCache | None = None) -> Solution:
    """Solve the equilibrium for every sample of a wrench log.

    Parameters
    ----------
    model : SpringModel or CoupledModel
    wrench : array_like, shape (m, 6) or (6,)
        Wrench W applied by the robot to the cuff, cuff frame, about the cuff
        origin: (Fx, Fy, Fz [N], Mx, My, Mz [N*m]); finite (NaN or inf raise
        ValueError). A sample whose cuff displacement exceeds 1e100 m or rad (an
        absurd but finite input, whose forces would overflow) is reported as not
        converged, with NaN forces.
    max_iterations : int
        Most linear solves per sample (>= 1).
    warm_start : bool
        Start each sample from the contact set of a neighbouring sample (solved
        first on a strided subset of the log) instead of full contact.
    initial_active : array_like of bool, shape (n,) or (m, n), optional
        Initial contact set(s); overrides ``warm_start``.
    out : ndarray, shape (m, n), optional
        Array (float64, C-contiguous) to write the forces into. Reusing one
        array across the chunks of a long stream avoids faulting in fresh
        memory for every chunk, which dominates on fine meshes.
    cache : FactorCache, optional
        Factorisations of contact sets, kept across calls on the same model
        (e.g. the chunks of one stream); a fresh one per call if not given.

    Returns
    -------
    Solution
        Arrays with a leading sample axis (dropped for a single (6,) wrench).

    Examples
    --------
    >>> import numpy as np
    >>> from phri_spring.physics.cuff.geometry import cuff_geometry
    >>> from phri_spring.physics.springs.model import build_model
    >>> geom = cuff_geometry([0.0], 0.045, 0.025, 75.0, 35.0, 7)   # one row, 7 elements
    >>> model = build_model(geom, 50e3, 1e6, strap_tension=15.0)
    >>> sol = solve(model, np.zeros((1, 6)))                          # zero wrench
    >>> bool(np.allclose(sol.forces, model.f0))                       # the strap preload
    True
    >>> sol = solve(model, [0.0, -40.0, 0.0, 0.0, 0.0, 0.0])          # 40 N toward -y
    >>> int(sol.iterations) >= 1, bool(sol.converged)
    (True, True)
    """
    W = np.asarray(wrench, dtype=float)
    single = W.ndim == 1
    W = np.atleast_2d(W)
    if W.ndim != 2 or W.shape[1] != 6:
        raise ValueError(f"wrench: expected shape (m, 6) or (6,), got {np.shape(wrench)}")
    if not np.all(np.isfinite(W)):
        raise ValueError("wrench: expected finite numbers, got NaN or inf")
    if int(max_iterations) < 1:
        raise ValueError("max_iterations: expected >= 1")
    max_iterations = int(max_iterations)
    if getattr(model, "has_history", False):   # no times: every sample held long (rested)
        sol = model.solve_rested(W, max_iterations=max_iterations)
        return sol if not single else Solution(
            u=sol.u[0], forces=sol.forces[0], iterations=sol.iterations[0],
            converged=sol.converged[0], contact=sol.contact[0], tangential=sol.tangential[0])
    if hasattr(model, "solve_band"):   # an elastic band strap (contact/band_solve.py)
        return model.solve_band(W[0] if single else W, max_iterations=max_iterations, cache=cache)
    if interface_mu(model) is not None:
        return solve_friction(model, W, single, cache)
    if hasattr(model, "solve_wrenches"):
        return solve_direct(model, W, single, out, max_iterations)
    system = make_system(model, cache)
    linear = model.is_linear
    m, n = len(W), system.n
    with np.errstate(over="ignore", invalid="ignore"):
        r = W + model.W_pre
    finite_in = None
    if not np.isfinite(r).all():  # W + W_pre overflowed: solved as zero, reported as not converged
        finite_in = np.isfinite(r).all(axis=1)
        r = np.where(finite_in[:, None], r, model.W_pre)

    u = np.empty((m, 6))
    if out is None:
        forces = np.empty((m, n))
    else:
        forces = out
        if not (isinstance(out, np.ndarray) and out.shape == (m, n) and out.dtype == np.float64
                and out.flags.c_contiguous):
            raise ValueError(f"out: expected a C-contiguous float64 array of shape ({m}, {n})")
    its = np.empty(m, dtype=np.int64)
    conv = np.empty(m, dtype=bool)
    contact = np.empty((m, n), dtype=bool)
    block = max(256, _BLOCK_ENTRIES // max(n, 1))
    # a nonlinear law: each sample may start from its solved neighbours
    warm_newton = not linear and warm_start and initial_active is None
    carry = None  # warm start across blocks: the last solved sample's contact set
    with np.errstate(over="ignore", invalid="ignore"):
        for s in range(0, m, block):
            e = min(m, s + block)
            rb = r[s:e]
            mb = e - s
            qb = forces[s:e]  # indicators are computed in place, then turned into forces
            if warm_newton:
                from ..springs.newton import solve_newton_warm   # nonlinear laws only

                ub, fb, itb, cb = solve_newton_warm(model, system, rb, carry, max_iterations)
                np.matmul(ub, model.bT, out=qb)
                qb += model.delta0
            elif initial_active is not None:
                S0 = np.broadcast_to(np.asarray(initial_active, dtype=bool), (m, n))[s:e]
                ub, qb, _, itb, cb = iterate(system, rb, S0, max_iterations, q_out=qb)
            elif warm_start:
                ub, qb, itb, cb = solve_warm(system, rb, carry, max_iterations, q_out=qb)
            else:
                S0 = np.ones((mb, n), dtype=bool) if carry is None else np.broadcast_to(carry, (mb, n))
                ub, qb, _, itb, cb = iterate(system, rb, S0, max_iterations, q_out=qb)
            if not linear and not warm_newton:
                qb[:], fb = nonlinear_finish(model, rb, ub, itb, cb, max_iterations)
            u[s:e], its[s:e], conv[s:e] = ub, itb, cb
            # the settled set, read off the indicator before it becomes the forces in place
            np.greater(qb, 0.0, out=contact[s:e])
            carry = contact[e - 1]
            if linear:
                system.forces(qb, out=qb, u=ub)
            else:
                qb[:] = fb
            # a displacement beyond HUGE (or not finite) comes from an absurd input and is
            # not an answer: its forces and pressures overflow (one cheap test first)
            if not (ub.max() <= HUGE and ub.min() >= -HUGE):
                conv[s:e] &= np.abs(ub).max(axis=1) <= HUGE
    if finite_in is not None:
        conv &= finite_in

    if not conv.all():
        forces[~conv] = np.nan
        contact[~conv] = False
    if single:
        return Solution(u=u[0], forces=forces[0], iterations=its[0], converged=conv[0],
                        contact=contact[0])
    return Solution(u=u, forces=forces, iterations=its, converged=conv, contact=contact)



def solve_segments(model, wrench, bounds, *, max_iterations: int = 100) -> Solution:
    """:func:`solve` on consecutive segments W[bounds[i]:bounds[i+1]], each its own loading
    path from the strap's state (e.g. the trials of a comparison). Without friction a
    sample does not depend on the ones before, and this is one :func:`solve`."""
    W = np.atleast_2d(np.asarray(wrench, dtype=float))
    if interface_mu(model) is None:
        return solve(model, W, max_iterations=max_iterations)
    parts = [solve(model, W[a:b], max_iterations=max_iterations)
             for a, b in zip(bounds[:-1], bounds[1:]) if b > a]
    cat = {name: np.concatenate([getattr(p, name) for p in parts])
           for name in ("u", "forces", "iterations", "converged", "contact", "tangential")}
    for name in ("moments", "normal"):
        cat[name] = (None if getattr(parts[0], name) is None
                     else np.concatenate([getattr(p, name) for p in parts]))
    return Solution(**cat)



def solve_per_sample(model, wrench, *, max_iterations: int = 100) -> Solution:
    """The plain, unoptimised path: one sample at a time through the same kernel.

    Same method and stopping rule as :func:`solve` (the kernel of
    :mod:`~phri_spring.physics.contact.active_set`, with the safeguard), without
    vectorisation across samples, cached factorisations or warm start: every
    sample starts from full contact and factorises every set it meets. Kept as
    the reference the optimised path is tested and benchmarked against.
    """
    W = np.atleast_2d(np.asarray(wrench, dtype=float))
    if interface_mu(model) is not None:
        return _per_sample_friction(model, W)
    if hasattr(model, "solve_wrenches"):
        rows = [model.solve_wrenches(W[i:i + 1], max_iterations) for i in range(len(W))]
        u, f, its, conv, contact = (np.concatenate(a) for a in zip(*rows))
        return Solution(u=u, forces=f, iterations=its, converged=conv, contact=contact)
    system = make_system(model, FactorCache(maxsize=0))
    m, n = len(W), system.n
    u = np.zeros((m, 6))
    q = np.zeros((m, n))
    its = np.zeros(m, dtype=np.int64)
    conv = np.zeros(m, dtype=bool)
    full = np.ones((1, n), dtype=bool)
    for i in range(m):
        ui, qi, _, it_i, ok = iterate(system, W[i:i + 1] + model.W_pre, full, max_iterations)
        u[i], q[i], its[i], conv[i] = ui[0], qi[0], it_i[0], ok[0]
    f_nl = None
    if not model.is_linear:
        q, f_nl = nonlinear_finish(model, W + model.W_pre, u, its, conv, max_iterations)
    contact = (q > 0) & conv[:, None]
    forces = system.forces(q, u=u) if f_nl is None else f_nl
    forces[~conv] = np.nan
    return Solution(u=u, forces=forces, iterations=its, converged=conv, contact=contact)


def _per_sample_friction(model, W) -> Solution:
    """The plain path with friction: every sample by the event solver, no affine blocks."""
    from ..friction.path import initial_state, interface_form
    from ..friction.events import solve_event_coupled, solve_event_elements

    form = interface_form(model)
    event = solve_event_elements if form.diagonal else solve_event_coupled
    state = initial_state(form)
    m, n, d = len(W), form.n, form.d
    u, P = np.full((m, 6), np.nan), np.full((m, n * d), np.nan)
    its, conv = np.zeros(m, dtype=np.int64), np.zeros(m, dtype=bool)
    contact = np.zeros((m, n), dtype=bool)
    for i in range(m):
        ui, Pi, new, its[i], conv[i] = event(form, W[i] + model.W_pre, state)
        if conv[i]:
            u[i], P[i], state = ui, Pi, new
            contact[i] = new.cls > 0
    Pe = P.reshape(m, n, d)
    forces = (model.reported_normal(P, contact) if hasattr(model, "reported_normal")
              else np.maximum(Pe[:, :, 0], 0.0))
    forces[~conv] = np.nan
    return Solution(u=u, forces=forces, iterations=its, converged=conv,
                    contact=contact, tangential=Pe[:, :, 1:3].copy(),
                    moments=Pe[:, :, 3:6].copy() if d == 6 else None, normal=Pe[:, :, 0].copy())
