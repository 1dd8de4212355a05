"""Equilibrium of the spring model with a nonlinear tissue law: damped Newton on a convex energy.

With a tissue law F_e (:mod:`phri_spring.physics.laws`) in series with
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

Every row of a block is iterated at once (a tissue with a history, relaxing or
activated, is :class:`~phri_spring.physics.history.model.HistoryModel`'s, which solves
the samples in order).

Starts. :func:`solve_newton` starts from given displacements (the solver passes the
answer of the linear model tangent to the law at the preload). On a log,
:func:`solve_newton_warm` solves every :data:`WARM_STRIDE`-th sample that way first
and starts each sample between from its solved neighbours: displacements, tissue
shares and tangents interpolated between them, plus one linearised step for the part
of its wrench the interpolation misses. The start moves only the path, never the
answer (Pi has one minimiser and every row is held to the same residual test).
"""

from __future__ import annotations

import numpy as np

from ..contact.active_set import solve_warm
from ..contact.spd6 import spd_factor_batched, spd_solve_batched, spd_solve_factored

__all__ = ["solve_newton", "solve_newton_warm", "NEWTON_ITERATIONS", "RESIDUAL_RTOL"]

#: most Newton steps per sample (on top of the linear solve that starts it)
NEWTON_ITERATIONS = 60
#: a row is converged when ``|residual| <= RESIDUAL_RTOL`` * (force scale of its equations)
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


#: Newton steps of the fast mixed iteration before a row is handed to the damped one
MIXED_ITERATIONS = 12


def _mixed_rows(model, r, u, dt0=None, steps=None, tol2=None):
    """Undamped Newton on displacements and tissue shares together, in place on u (m, 6).

    The series element's split d = d_t + F(d_t) c is not solved exactly at every step
    (that costs a transcendental inversion per element and trial): d_t is an unknown of
    its own, and each step linearises both the split and the equilibrium. Eliminating
    the share's correction element by element leaves the same 6x6 tangent as the damped
    iteration, with the split's residual h = d - d_t - F(d_t) c folded into the
    forces, q = F + k_s h (k_s = F' / (1 + c F'), the series tangent). A row is
    converged when the equilibrium with q is met to RESIDUAL_RTOL and the split's own
    force error k_s h is below that too; q is then the element force to round-off.
    There is no line search, so convergence is not guaranteed: rows that have not
    converged after MIXED_ITERATIONS steps (or overflow) are returned as such and the
    caller solves them by the damped Newton on the energy.

    Parameters
    ----------
    dt0 : ndarray, shape (m, n), optional
        Starting tissue shares (taken over and changed in place); None: linearised about
        the preload.
    steps : int, optional
        Newton steps at most (None: MIXED_ITERATIONS). A caller may stop early and
        resume the rows left (``left``) together with those of other blocks, so that the
        few rows of a block that need more steps do not each cost a pass over the block.
    tol2 : ndarray, shape (m,), optional
        Squared residual tolerances of resumed rows (None: 1e-10 of the start's force scale).

    Returns
    -------
    conv : ndarray of bool, shape (m,)
    its : ndarray of int, shape (m,)
    f : ndarray, shape (m, n)
        Element forces of the converged rows (undefined elsewhere).
    left : (rows, dt, tol2) or None
        The rows still iterating after ``steps`` steps (indices into r), their tissue
        shares and tolerances; their displacements are where the iteration stopped, in u.
    """
    steps = MIXED_ITERATIONS if steps is None else steps
    law = model.element.law
    c = np.broadcast_to(model.element._c_cuff, (model.n,))
    b, bT, bb, Ks = model.geometry.b, model.bT, model.bb, model.K_s
    abs_b = np.abs(b)
    Ks_col = Ks.reshape(36, 1)
    m = len(r)
    f_out = np.empty((m, model.n))
    its = np.zeros(m, dtype=np.int64)
    conv = np.zeros(m, dtype=bool)
    g = u @ bT
    g += model.delta0
    # the tissue shares linearised about the preload (docs/model.md 11.1): exact at zero
    # wrench; an element out of contact has d_t = 0, so F = 0 and its split residual h = d
    if dt0 is None:
        _, dt_pre, kt_pre = model.newton_start()
        dt = g - model.delta0
        dt /= 1.0 + kt_pre * c
        dt += dt_pre
    else:
        dt = dt0          # the caller's start, taken over
    np.minimum(dt, g, out=dt)
    np.maximum(dt, 0.0, out=dt)
    idx = np.arange(m)
    u_act = u
    full = True            # no row has left yet: q is computed straight into f_out
    with np.errstate(over="ignore", invalid="ignore"):
        for step in range(steps + 1):
            F, Ft = law.force_tangent(dt)
            denom = c * Ft
            denom += 1.0
            ks = Ft / denom
            ks *= g > 0.0
            h = c * F
            np.subtract(g, h, out=h)
            h -= dt
            corr = ks * h
            q = np.add(F, corr, out=f_out if full else F)
            Ku = u_act @ Ks
            res = q @ b
            res += Ku
            res -= r
            if tol2 is None:
                # the force scale of the equations, taken at the start: it moves by a few
                # per cent at most over the iteration, and sets a tolerance of 1e-10 of it
                # (the row maximum of a column-major copy: numpy reduces a short last axis
                # an order of magnitude slower than it copies it)
                scale = np.abs(q) @ abs_b
                scale += np.abs(Ku)
                scale += np.abs(r)
                scale = np.asfortranarray(scale).max(axis=1)
                tol2 = np.square(RESIDUAL_RTOL * np.maximum(scale, 1e-300))
            # sums of squares bound the largest entries: a slightly stricter test
            ok = (np.einsum("ij,ij->i", res, res) <= tol2) & (
                np.einsum("ij,ij->i", corr, corr) <= tol2)
            if ok.any():
                done = idx[ok]
                conv[done] = True
                if not full:
                    f_out[done] = q[ok]
                keep = ~ok
                if not keep.any():
                    idx = idx[:0]
                    break
                if step == steps:       # the last pass: only what ``left`` returns
                    idx, dt, tol2 = idx[keep], dt[keep], tol2[keep]
                    break
                idx, u_act, r, tol2 = idx[keep], u_act[keep], r[keep], tol2[keep]
                g, dt, ks, h, denom, res = g[keep], dt[keep], ks[keep], h[keep], denom[keep], res[keep]
                full = False
            if step == steps:
                break
            its[idx] += 1
            Hf = bb.T @ ks.T
            Hf += Ks_col
            du = spd_solve_batched(Hf, res)
            u_act = u_act - du
            u[idx] = u_act
            dg = du @ bT
            g -= dg
            h -= dg
            h /= denom
            dt += h
            # the share stays within [0, d] (0 for an element out of contact, d < 0)
            np.minimum(dt, g, out=dt)
            np.maximum(dt, 0.0, out=dt)
    left = (idx, dt, tol2) if idx.size else None
    return conv, its, f_out, left


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


#: rows per pass of the mixed iteration at 21 elements (scaled by 21 / n): numpy's cost
#: per call small against the work, the (rows x elements) temporaries still in the cache
_MIXED_ROWS = 4096


def _pass_rows(n: int) -> int:
    """Rows per pass of the mixed iteration for a model of n elements."""
    return max(1, _MIXED_ROWS * 21 // max(n, 1))


def _solve_rows(model, r, u, max_iterations, forces_out=None):
    """The mixed iteration on every row, the damped one from u on the rows it leaves."""
    m = len(r)
    u_start = u.copy()
    conv = np.empty(m, dtype=bool)
    its = np.empty(m, dtype=np.int64)
    f = np.empty((m, model.n)) if forces_out is None else forces_out
    rows = _pass_rows(model.n)
    for s in range(0, m, rows):
        e = min(m, s + rows)
        conv[s:e], its[s:e], f[s:e], _ = _mixed_rows(model, r[s:e], u[s:e])
    if not conv.all():
        rest = np.flatnonzero(~conv)
        _damped_rows(model, r, rest, u_start[rest], u, its, conv, f, max_iterations)
    return its, conv


def _damped_rows(model, r, rows, u_start, u, its, conv, f, max_iterations):
    """The rows the mixed iteration left: the damped Newton from their starts u_start
    (len(rows), 6), written into u, its (steps added), conv and the forces f, in place."""
    its_r, conv_r = _newton_rows(model, r[rows], u_start, max_iterations)
    u[rows], its[rows], conv[rows] = u_start, its[rows] + its_r, conv_r
    f[rows] = model.element.force(model.delta0 + u_start @ model.bT)


def solve_newton(model, r, u0, *, max_iterations: int = NEWTON_ITERATIONS, forces_out=None):
    """Equilibria of a spring model with a nonlinear element law for right-hand sides r.

    Parameters
    ----------
    model : SpringModel
        With ``model.element`` a :class:`~phri_spring.physics.laws.SeriesElement`.
    r : ndarray, shape (m, 6)
        W + W_pre [N, N*m].
    u0 : ndarray, shape (m, 6)
        Starting displacements (e.g. the linear model's solution) [m, rad].
    max_iterations : int
        Most Newton steps per sample.
    forces_out : ndarray, shape (m, n), optional
        Filled with the element forces of the answers [N].

    Returns
    -------
    u : ndarray, shape (m, 6)
    its : ndarray of int, shape (m,)
        Newton steps each row took.
    converged : ndarray of bool, shape (m,)
    """
    r = np.atleast_2d(np.asarray(r, dtype=float))
    u = np.array(u0, dtype=float, copy=True).reshape(len(r), 6)
    its, conv = _solve_rows(model, r, u, max_iterations, forces_out)
    return u, its, conv


#: every WARM_STRIDE-th row of a log is solved first; the rows between start from them
WARM_STRIDE = 8


def _end_shares(model, fs):
    """Tissue shares and series tangents (0 where open) of solved rows with forces fs."""
    dts = model.element.law.compression_at(fs)
    return dts, model.element.tangent_from_share(dts)


def _between_view(a, idx, k0, k1):
    """The rows of a (m, ...) strictly between solved rows idx[k0] .. idx[k1] as a view
    (positions, segments, ...), position-major like :func:`_neighbour_start`'s rows; None
    unless every segment there is WARM_STRIDE rows long."""
    segs = k1 - k0
    if idx[k1] - idx[k0] != segs * WARM_STRIDE:
        return None
    blk = a[idx[k0]:idx[k1]].reshape(segs, WARM_STRIDE, *a.shape[1:])[:, 1:]
    return np.swapaxes(blk, 0, 1)


def _neighbour_start(model, r, idx, us, ends, k0, k1, rows_per_segment):
    """Starts of the rows between solved rows idx[k] and idx[k + 1], k0 <= k < k1.

    Segments k0..k1-1 each hold ``rows_per_segment`` rows, evenly spaced between their
    two solved ends; ``ends`` is :func:`_end_shares` of the solved rows. The rows come
    position-major (the first row of every segment, then the second, ...), so that the
    per-segment quantities broadcast over long contiguous runs. Displacements and tissue
    shares are interpolated between the ends; the part of the row's wrench the
    interpolation misses (noise, a step) is added through the segment's tangent (the mean
    of its ends' series tangents, one 6x6 factor for all its rows): a step of the
    linearised equilibrium and split, so a row on a smooth stretch of a log starts within
    the curvature of the law of its answer. The shares are not clipped to [0, d] here:
    :func:`_mixed_rows` does that.

    Returns
    -------
    rows (m,), u0 (m, 6), dt0 (m, n), and the rows' right-hand sides r[rows] (m, 6)
    """
    el = model.element
    sl = slice(k0, k1 + 1)
    dts, kts = ends[0][sl], ends[1][sl]
    span = idx[k0 + 1] - idx[k0]
    segs, per = k1 - k0, rows_per_segment
    w = (np.arange(1, per + 1) / span)[:, None, None]

    def between(a):
        """(rows_per_segment * segments, columns): a interpolated along each segment."""
        lo = a[:-1]
        out = (a[1:] - lo)[None] * w
        out += lo
        return out.reshape(-1, a.shape[1])

    rows = (idx[k0:k1][None, :] + np.arange(1, per + 1)[:, None]).ravel()
    u0, dt0 = between(us[sl]), between(dts)
    view = _between_view(r, idx, k0, k1)
    r_rows = r[rows] if view is None else view.reshape(-1, 6)    # (a copy either way)
    dr = r_rows - between(r[idx[sl]])
    kseg = kts[:-1] + kts[1:]
    kseg *= 0.5
    H = model.bb.T @ kseg.T
    H += model.K_s.reshape(36, 1)
    # right-hand sides as (component, position, segment): the factors (segments,)
    # broadcast along the contiguous last axis
    drT = np.ascontiguousarray(dr.reshape(per, segs, 6).transpose(2, 0, 1))
    du = np.stack(spd_solve_factored(spd_factor_batched(H), drT), axis=-1).reshape(-1, 6)
    u0 += du
    # the share takes the tissue's part of the extra compression: dg (1 - c k_s)
    dg = (du @ model.bT).reshape(per, segs, -1)
    kseg *= el._c_cuff
    np.subtract(1.0, kseg, out=kseg)
    dg *= kseg
    dt0 += dg.reshape(per * segs, -1)
    return rows, u0, dt0, r_rows


def _cold(model, system, r, carry, max_iterations):
    """Rows started from the tangent model's answer (its active set, then Newton)."""
    u, _, its, conv = solve_warm(system, r, carry, max_iterations)
    f = np.empty((len(r), model.n))
    u, itn, conv_n = solve_newton(model, r, u, max_iterations=max_iterations, forces_out=f)
    return u, f, its + itn, conv & conv_n


def solve_newton_warm(model, system, r, carry, max_iterations: int):
    """Equilibria of a log of right-hand sides r (m, 6) with a neighbour warm start.

    Rows 0, WARM_STRIDE, 2 WARM_STRIDE, ... and the last are solved first (by this
    function again, down to short logs, which start from the tangent model's answer:
    its active set by :func:`~phri_spring.physics.contact.active_set.solve_warm` on
    ``system``, then :func:`solve_newton`). Every other row starts from its two solved
    neighbours (:func:`_neighbour_start`), chunk by chunk so the temporaries stay in
    cache; the rows one Newton step does not settle go on together after all chunks;
    rows the mixed iteration leaves go to the damped Newton from their start;
    rows next to a neighbour that did not converge start from the tangent model.

    Returns
    -------
    u (m, 6), forces (m, n), iterations (m,), converged (m,)
        ``iterations`` counts the linear solves of the start (rows started from the
        tangent model) and the Newton steps.
    """
    m, n = len(r), model.n
    if m < 4 * WARM_STRIDE:
        return _cold(model, system, r, carry, max_iterations)
    idx = np.arange(0, m, WARM_STRIDE)
    if idx[-1] != m - 1:
        idx = np.append(idx, m - 1)
    us, fs, its_s, conv_s = solve_newton_warm(model, system, r[idx], carry, max_iterations)
    u = np.empty((m, 6))
    f = np.empty((m, n))
    its = np.empty(m, dtype=np.int64)
    conv = np.empty(m, dtype=bool)
    u[idx], f[idx], its[idx], conv[idx] = us, fs, its_s, conv_s
    # the rows between, segment by segment: every segment but the last holds
    # WARM_STRIDE - 1 rows; chunks of whole segments keep the temporaries in cache
    n_seg = len(idx) - 1
    per = max(1, _pass_rows(n) // (WARM_STRIDE - 1))
    groups = [(k, min(k + per, n_seg - 1), WARM_STRIDE - 1) for k in range(0, n_seg - 1, per)]
    groups.append((n_seg - 1, n_seg, idx[-1] - idx[-2] - 1))
    seg_ok = conv_s[:-1] & conv_s[1:]
    ends = _end_shares(model, fs)
    cold, retry, retry_u = [], [], []
    later = []      # (rows, starts, shares, tolerances) of the rows one step left
    first = min(1, MIXED_ITERATIONS)
    for k0, k1, per_seg in groups:
        if per_seg == 0:
            continue
        ok = np.tile(seg_ok[k0:k1], per_seg)     # rows position-major
        rows, u0, dt0, r_rows = _neighbour_start(model, r, idx, us, ends, k0, k1, per_seg)
        if not ok.all():      # an end that did not converge is no start: those start cold
            cold.append(rows[~ok])
            rows, u0, dt0, r_rows = rows[ok], u0[ok], dt0[ok], r_rows[ok]
        u_start = u0.copy()
        cr, itr, fr, left = _mixed_rows(model, r_rows, u0, dt0, steps=first)
        views = [_between_view(a, idx, k0, k1) for a in (u, f, its, conv)] if ok.all() \
            else [None]
        if views[0] is not None:      # strided writes instead of scatters through rows
            for v, x in zip(views, (u0, fr, itr, cr)):
                v[...] = x.reshape(v.shape)
        else:
            u[rows], f[rows], its[rows], conv[rows] = u0, fr, itr, cr
        if left is not None:
            li, dtl, toll = left
            later.append((rows[li], u_start[li], dtl, toll))
    if later:
        # most rows settle in one step; the few that do not (a load step, a contact
        # change) go on together, in chunks of their own, instead of one short pass each
        rows_l = np.concatenate([x[0] for x in later])
        start_l = np.concatenate([x[1] for x in later])
        dt_l = np.concatenate([x[2] for x in later])
        tol_l = np.concatenate([x[3] for x in later])
        chunk = _pass_rows(n)
        for s in range(0, len(rows_l), chunk):
            rr = rows_l[s:s + chunk]
            ur = u[rr]
            cr, itr, fr, _ = _mixed_rows(model, r[rr], ur, dt_l[s:s + chunk],
                                         steps=MIXED_ITERATIONS - first, tol2=tol_l[s:s + chunk])
            u[rr], conv[rr] = ur, cr
            its[rr] += itr
            f[rr[cr]] = fr[cr]
            if not cr.all():
                retry.append(rr[~cr])
                retry_u.append(start_l[s:s + chunk][~cr])
    if retry:
        _damped_rows(model, r, np.concatenate(retry), np.concatenate(retry_u), u, its, conv,
                     f, max_iterations)
    if cold:
        rows = np.concatenate(cold)
        u[rows], f[rows], its[rows], conv[rows] = _cold(model, system, r[rows], carry,
                                                        max_iterations)
    return u, f, its, conv
