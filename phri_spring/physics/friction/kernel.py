"""The spring arms' friction path, compiled (numba, the ``fast`` extra).

With friction on the spring model every element is independent given the cuff's
displacement u, so a sample is six equations in u: the semismooth Newton method of
:func:`~phri_spring.physics.friction.events.solve_event_elements` (each element's return
mapping, the consistent tangent, a backtracking line search). This module writes that
method in scalar code that numba compiles, and solves a log sample after sample with it,
each sample from the one before: compiled, a sample costs a few microseconds, which the
numpy path (affine or Newton blocks between the events, docs/model.md 12.3) reaches only
where nothing slides for long stretches. Where the Newton method does not settle a
sample, the loop runs the numpy path's fallbacks itself (every touching element gripping,
the Newton method again from there, two half increments; a damped least-squares step
where the tangent is singular), so that a log with many samples without an equilibrium
costs microseconds per sample too, and flags what none of them settles. It covers the
linear springs and the exponential law (the human preset's) with or without a cuff
spring; any other law, or an install without numba, takes the numpy path.
"""

from __future__ import annotations

import math

import numpy as np

from .states import RELEASED, SLIDING, STUCK

try:
    from numba import njit as _njit
except ImportError:  # the same loop, interpreted (the tests compare it with the compiled)
    NUMBA = False

    def _jit(fn):
        return fn

    def _entry(fn):
        return fn
else:
    NUMBA = True

    def _jit(fn):
        # not inline="always": the loop's helpers inlined at every call site took twice
        # as long to compile for no measurable gain
        return _njit(error_model="numpy")(fn)

    def _entry(fn):
        # cache: compiled once per install (next to the module, or numba's user cache)
        return _njit(cache=True, nogil=True, error_model="numpy")(fn)

__all__ = ["NUMBA", "supports", "law_arrays", "solve_elements", "load"]

#: as the event solver (friction/events.py): most Newton steps, steps without halving the
#: residual before a sample's iteration gives up, a step this long means a mode without
#: stiffness. Copied, not imported: numba's cache keys the compiled loop on this file, and
#: would not see a value changed there
_MAX_STEPS = 60
_STALL = 6
_HUGE_STEP = 0.1
#: a split step this small against the compression ends the series element's iteration
_SPLIT_RTOL = 1e-13


def supports(form) -> bool:
    """Whether the compiled loop covers this form: the spring model (diagonal), mu > 0,
    linear springs or the exponential law."""
    if not (form.diagonal and form.mu > 0 and np.isfinite(form.mu)):
        return False
    normal = form.normal_response
    return normal is None or getattr(normal.law, "name", None) == "exponential"


def law_arrays(form):
    """(law_exp, k0, beta, c) (n,) each: the normal springs' law for the compiled loop
    (the linear springs: k0 = 1/C_nn, beta = 0, c = 0)."""
    n = form.n
    normal = form.normal_response
    if normal is None:
        kn = 1.0 / np.diag(form.C).reshape(n, 3)[:, 0]
        return False, np.ascontiguousarray(kn), np.zeros(n), np.zeros(n)
    law = normal.law
    k0 = np.broadcast_to(np.asarray(law.k0, dtype=float), (n,)).copy()
    beta = np.broadcast_to(np.asarray(law.params["stiffening"], dtype=float), (n,)).copy()
    return True, k0, beta, np.ascontiguousarray(normal.c, dtype=float)


@_jit
def _tissue(d, k0, beta):
    """(F, F') of the exponential law at d >= 0."""
    if beta > 0.0:
        x = beta * d
        if x > 700.0:       # exp overflows (as numpy's does, without raising)
            return np.inf, np.inf
        em = math.expm1(x)
        return k0 / beta * em, k0 * (1.0 + em)
    return k0 * d, k0


@_jit
def _normal(g, d0, law_exp, k0, beta, c):
    """(force, series tangent, tissue share) of one element at total compression g > 0,
    its split warm-started at d0."""
    if not law_exp:
        return k0 * g, k0, g
    if c == 0.0:
        F, Ft = _tissue(g, k0, beta)
        return F, Ft, g
    # d + F(d) c = g on [0, g]: Newton, kept inside the bracket it narrows
    lo = 0.0
    hi = g
    d = d0
    if not (0.0 <= d <= g):
        d = g / (1.0 + k0 * c)
    F, Ft = _tissue(d, k0, beta)
    for _ in range(100):
        phi = d + F * c - g
        if phi > 0.0:
            hi = d
        else:
            lo = d
        step = phi / (1.0 + Ft * c)
        nd = d - step
        if not (lo <= nd <= hi):
            nd = 0.5 * (lo + hi)
        if abs(nd - d) <= _SPLIT_RTOL * g:
            F = F + Ft * (nd - d)
            d = nd
            break
        d = nd
        F, Ft = _tissue(d, k0, beta)
    return F, Ft / (1.0 + Ft * c), d


@_jit
def _evaluate(u, r, Tn, Tt, dn, kt, mu, law_exp, k0, beta, c, z0, dsh,
              Pn, kN, Pt, tn, dr, cls, R, held):
    """Each element's return mapping at u (into Pn, kN, Pt, tn = |trial force|, dr = its
    direction where sliding, cls; the splits dsh warm start and are updated) and the
    residual R = sum forces - r; returns max |R|. ``held`` (n,) int8, or an empty array:
    the numpy path's block instead of the return mapping, the state held: an element
    released in it stays released, every other is tied (its normal spring pressing only
    where compressed), whatever its force; the block's checks come after."""
    n = Tn.shape[0]
    block = held.shape[0] > 0
    for k in range(6):
        R[k] = -r[k]
    for e in range(n):
        g = dn[e]
        a0 = -z0[e, 0]
        a1 = -z0[e, 1]
        for k in range(6):
            g += Tn[e, k] * u[k]
            a0 += Tt[e, 0, k] * u[k]
            a1 += Tt[e, 1, k] * u[k]
        # tied: in a held state every element not released in it; else one compressed
        tied = held[e] != RELEASED if block else g > 0.0
        f = 0.0
        kk = 0.0
        t0 = 0.0
        t1 = 0.0
        tn[e] = 0.0
        cls[e] = RELEASED
        if tied:
            if g > 0.0:
                f, kk, d = _normal(g, dsh[e], law_exp, k0[e], beta[e], c[e])
                dsh[e] = d
            t0 = kt[e] * a0
            t1 = kt[e] * a1
            tt = math.sqrt(t0 * t0 + t1 * t1)
            tn[e] = tt
            cls[e] = STUCK
            if tt > mu * f and not block:
                cls[e] = SLIDING
                dr[e, 0] = t0 / tt
                dr[e, 1] = t1 / tt
                t0 = mu * f * dr[e, 0]
                t1 = mu * f * dr[e, 1]
        elif not block:
            dsh[e] = 0.0
        Pn[e] = f
        kN[e] = kk
        Pt[e, 0] = t0
        Pt[e, 1] = t1
        for k in range(6):
            R[k] += Tn[e, k] * f + Tt[e, 0, k] * t0 + Tt[e, 1, k] * t1
    res = 0.0
    for k in range(6):
        v = abs(R[k])
        if v != v:
            return np.inf
        if v > res:
            res = v
    return res


@_jit
def _tangent(Tn, Tt, kt, mu, Pn, kN, tn, dr, cls, K):
    """The consistent tangent d R / d u (6, 6) of the state at the last evaluation."""
    n = Tn.shape[0]
    for i in range(6):
        for j in range(6):
            K[i, j] = 0.0
    for e in range(n):
        if cls[e] == RELEASED:
            continue
        kn = kN[e]
        for i in range(6):
            for j in range(6):
                K[i, j] += kn * Tn[e, i] * Tn[e, j]
        if cls[e] == STUCK:
            ke = kt[e]
            for i in range(6):
                for j in range(6):
                    K[i, j] += ke * (Tt[e, 0, i] * Tt[e, 0, j] + Tt[e, 1, i] * Tt[e, 1, j])
        else:
            # d(mu Pn d)/du = mu kN d Tn^T + mu Pn / |trial| kt (I - d d^T) Tt
            d0 = dr[e, 0]
            d1 = dr[e, 1]
            a = mu * kn
            b = mu * Pn[e] / tn[e] * kt[e]
            for j in range(6):
                pd = d0 * Tt[e, 0, j] + d1 * Tt[e, 1, j]
                r0 = a * d0 * Tn[e, j] + b * (Tt[e, 0, j] - d0 * pd)
                r1 = a * d1 * Tn[e, j] + b * (Tt[e, 1, j] - d1 * pd)
                for i in range(6):
                    K[i, j] += Tt[e, 0, i] * r0 + Tt[e, 1, i] * r1


@_jit
def _gauss6(M, b, x):
    """x = M^-1 b by Gaussian elimination with partial pivoting (M and b are overwritten);
    False where M is singular. The history kernel has its own 6 x 6 elimination: sharing
    one across the two files would leave numba's on-disk cache of either loop stale when
    the shared one changed (the cache is keyed on the loop's own file)."""
    for col in range(6):
        p = col
        best = abs(M[col, col])
        for row in range(col + 1, 6):
            if abs(M[row, col]) > best:
                best = abs(M[row, col])
                p = row
        if not best > 0.0:
            return False
        if p != col:
            for k in range(6):
                tmp = M[col, k]
                M[col, k] = M[p, k]
                M[p, k] = tmp
            tmp = b[col]
            b[col] = b[p]
            b[p] = tmp
        for row in range(col + 1, 6):
            fct = M[row, col] / M[col, col]
            if fct != 0.0:
                for k in range(col, 6):
                    M[row, k] -= fct * M[col, k]
                b[row] -= fct * b[col]
    for row in range(5, -1, -1):
        acc = b[row]
        for k in range(row + 1, 6):
            acc -= M[row, k] * x[k]
        x[row] = acc / M[row, row]
    return True


@_jit
def _solve6(K, R, du, M, b):
    """du = -K^-1 R, the event solver's step: where K is singular or the step is longer
    than _HUGE_STEP, the damped least-squares step (K^T K + lam I) du = -K^T R with lam
    1e-12 of K^T K's mean diagonal, which leaves the cuff where it is along a mode
    without stiffness, as the least-norm step does. False where no finite step is found."""
    for i in range(6):
        b[i] = -R[i]
        for k in range(6):
            M[i, k] = K[i, k]
    ok = _gauss6(M, b, du)
    if ok:
        for k in range(6):
            if not abs(du[k]) < _HUGE_STEP:
                ok = False
    if not ok:
        lam = 0.0
        for i in range(6):
            for j in range(6):
                acc = 0.0
                for k in range(6):
                    acc += K[k, i] * K[k, j]
                M[i, j] = acc
            lam += M[i, i]
            acc = 0.0
            for k in range(6):
                acc -= K[k, i] * R[k]
            b[i] = acc
        lam *= 1e-12 / 6.0
        if not (lam > 0.0 and math.isfinite(lam)):
            return False
        for i in range(6):
            M[i, i] += lam
        if not _gauss6(M, b, du):
            return False
    for k in range(6):
        if not math.isfinite(du[k]):
            return False
    return True


@_jit
def _newton(ri, tol, Tn, Tt, dn, kt, mu, law_exp, k0, beta, c, cls, z, u, dsh,
            z0, uc, Pn, kN, Pt, tn, dr, cc, R, K, du, ut, hist, held, f_tol, x_tol, M, b,
            from_uc):
    """One sample at wrench ri from the state (cls, z, u; the splits dsh are its warm start
    and are changed): the event solver's semismooth Newton method, or with a state
    ``held`` (n,) the numpy path's block in that state (settled only if its checks pass:
    tied elements pressing, to x_tol, and inside their cones, to f_tol; released ones not
    penetrating); started at u, or with ``from_uc`` at uc. Returns (settled, Newton steps,
    the last residual); the answer is in uc, Pn, Pt, dr, cc, z0."""
    n = Tn.shape[0]
    # a released element lands where its skin was at the last sample
    for e in range(n):
        if cls[e] == RELEASED:
            for a in range(2):
                acc = 0.0
                for k in range(6):
                    acc += Tt[e, a, k] * u[k]
                z0[e, a] = acc
        else:
            z0[e, 0] = z[e, 0]
            z0[e, 1] = z[e, 1]
    if not from_uc:
        for k in range(6):
            uc[k] = u[k]
    res = _evaluate(uc, ri, Tn, Tt, dn, kt, mu, law_exp, k0, beta, c, z0, dsh,
                    Pn, kN, Pt, tn, dr, cc, R, held)
    its = 0
    ok = True
    while its < _MAX_STEPS and res > tol:
        if its >= _STALL and res > 0.5 * hist[its - _STALL]:
            ok = False
            break
        hist[its] = res
        its += 1
        _tangent(Tn, Tt, kt, mu, Pn, kN, tn, dr, cc, K)
        if not _solve6(K, R, du, M, b):
            ok = False
            break
        step = 1.0
        while True:
            for k in range(6):
                ut[k] = uc[k] + step * du[k]
            new = _evaluate(ut, ri, Tn, Tt, dn, kt, mu, law_exp, k0, beta, c, z0, dsh,
                            Pn, kN, Pt, tn, dr, cc, R, held)
            if new < res or step < 1e-4:
                break
            step *= 0.5
        for k in range(6):
            uc[k] = ut[k]
        res = new
    settled = ok and res <= tol * 10
    for k in range(6):
        settled = settled and math.isfinite(uc[k])
    if settled and held.shape[0] > 0:
        for e in range(n):
            g = dn[e]
            for k in range(6):
                g += Tn[e, k] * uc[k]
            if cc[e] == STUCK:
                if tn[e] > mu * Pn[e] + f_tol or g < -x_tol:
                    settled = False
            elif g > x_tol:
                settled = False
    return settled, its, res


@_jit
def _commit(Tt, kt, cls, z, s, u, P, z0, uc, Pn, Pt, dr, cc):
    """The state after a settled sample (the return mapping's new ties and slips)."""
    n = Tt.shape[0]
    for e in range(n):
        cls[e] = cc[e]
        if cc[e] == SLIDING:
            for a in range(2):
                acc = 0.0
                for k in range(6):
                    acc += Tt[e, a, k] * uc[k]
                z[e, a] = acc - Pt[e, a] / kt[e]
                s[e, a] = dr[e, a]
        else:
            z[e, 0] = z0[e, 0]
            z[e, 1] = z0[e, 1]
        P[e, 0] = Pn[e]
        P[e, 1] = Pt[e, 0]
        P[e, 2] = Pt[e, 1]
    for k in range(6):
        u[k] = uc[k]


@_jit
def _copy_state(cls, z, s, u, P, cls_to, z_to, s_to, u_to, P_to):
    for e in range(cls.shape[0]):
        cls_to[e] = cls[e]
        for a in range(2):
            z_to[e, a] = z[e, a]
            s_to[e, a] = s[e, a]
        for a in range(3):
            P_to[e, a] = P[e, a]
    for k in range(6):
        u_to[k] = u[k]


@_entry
def solve_elements(r, scale, Tn, Tt, dn, kt, mu, law_exp, k0, beta, c,
                   cls, z, s, u, P, dsh, out_u, out_P, out_cls, out_solves, out_conv,
                   x_ratio):
    """Solve samples r (m, 6) in order; the state (cls (n,), z (n, 2) the ties' offsets,
    s (n, 2) slip directions, u (6,), P (n, 3), dsh (n,) the tissue shares) is updated in
    place after every sample. ``scale`` (m,): each sample's force scale (its tolerance is
    1e-13 of it, its state checks' 1e-9, and x_ratio times that for displacements [m]).

    A sample is solved as the numpy path solves it: the semismooth Newton method from the
    sample before; where that does not settle, every touching element gripping (the
    path's block), then the Newton method again from where that ended, then two half
    increments from the wrench the state balances. A sample none of them settles is
    flagged (NaN, not converged) and the next starts from the state before it.
    """
    m = r.shape[0]
    n = Tn.shape[0]
    z0 = np.empty((n, 2))
    Pn = np.empty(n)
    kN = np.empty(n)
    Pt = np.empty((n, 2))
    tn = np.empty(n)
    dr = np.empty((n, 2))
    cc = np.empty(n, dtype=np.int8)
    R = np.empty(6)
    K = np.empty((6, 6))
    du = np.empty(6)
    ut = np.empty(6)
    uc = np.empty(6)
    hist = np.empty(_MAX_STEPS + 1)
    d_start = np.empty(n)
    mid = np.empty(6)
    M = np.empty((6, 6))
    b = np.empty(6)
    free = np.empty(0, dtype=np.int8)     # no state held: the return mapping
    # the state before a failed sample's increments, restored if they fail
    cls_b = np.empty(n, dtype=cls.dtype)
    z_b = np.empty((n, 2))
    s_b = np.empty((n, 2))
    u_b = np.empty(6)
    P_b = np.empty((n, 3))
    for i in range(m):
        for e in range(n):
            d_start[e] = dsh[e]
        ri = r[i]
        tol = 1e-13 * scale[i]
        f_tol = 1e-9 * scale[i]
        x_tol = f_tol * x_ratio
        settled, its, _ = _newton(ri, tol, Tn, Tt, dn, kt, mu, law_exp, k0, beta, c, cls,
                                  z, u, dsh, z0, uc, Pn, kN, Pt, tn, dr, cc, R, K, du, ut,
                                  hist, free, f_tol, x_tol, M, b, False)
        if not settled:
            # the state held, every element that slid gripping (the numpy path's block)
            for e in range(n):
                dsh[e] = d_start[e]
            settled, its1, _ = _newton(ri, tol, Tn, Tt, dn, kt, mu, law_exp, k0, beta, c,
                                       cls, z, u, dsh, z0, uc, Pn, kN, Pt, tn, dr, cc, R,
                                       K, du, ut, hist, cls, f_tol, x_tol, M, b, False)
            its += its1
            finite = True
            for k in range(6):
                finite = finite and math.isfinite(uc[k])
            if not settled and finite:
                # the semismooth Newton again, from where gripping ended (the numpy path
                # starts its event at the block's answer)
                settled, its1, _ = _newton(ri, tol, Tn, Tt, dn, kt, mu, law_exp, k0, beta,
                                           c, cls, z, u, dsh, z0, uc, Pn, kN, Pt, tn, dr,
                                           cc, R, K, du, ut, hist, free, f_tol, x_tol, M,
                                           b, True)
                its += its1
        if not settled:
            for e in range(n):
                dsh[e] = d_start[e]
            # two half increments from the wrench the state balances
            for k in range(6):
                acc = 0.0
                for e in range(n):
                    acc += Tn[e, k] * P[e, 0] + Tt[e, 0, k] * P[e, 1] + Tt[e, 1, k] * P[e, 2]
                mid[k] = 0.5 * (acc + ri[k])
            _copy_state(cls, z, s, u, P, cls_b, z_b, s_b, u_b, P_b)
            ok1, its1, _ = _newton(mid, tol, Tn, Tt, dn, kt, mu, law_exp, k0, beta, c,
                                   cls, z, u, dsh, z0, uc, Pn, kN, Pt, tn, dr, cc, R, K,
                                   du, ut, hist, free, f_tol, x_tol, M, b, False)
            its += its1
            if ok1:
                _commit(Tt, kt, cls, z, s, u, P, z0, uc, Pn, Pt, dr, cc)
                settled, its2, _ = _newton(ri, tol, Tn, Tt, dn, kt, mu, law_exp, k0,
                                           beta, c, cls, z, u, dsh, z0, uc, Pn, kN, Pt,
                                           tn, dr, cc, R, K, du, ut, hist, free, f_tol,
                                           x_tol, M, b, False)
                its += its2
            if not settled:
                _copy_state(cls_b, z_b, s_b, u_b, P_b, cls, z, s, u, P)
                for e in range(n):
                    dsh[e] = d_start[e]
                for k in range(6):
                    out_u[i, k] = np.nan
                for e in range(n):
                    out_cls[i, e] = RELEASED
                    for a in range(3):
                        out_P[i, 3 * e + a] = np.nan
                out_conv[i] = False
                out_solves[i] = its if its > 1 else 1
                continue
        _commit(Tt, kt, cls, z, s, u, P, z0, uc, Pn, Pt, dr, cc)
        for e in range(n):
            out_cls[i, e] = cc[e]
            out_P[i, 3 * e] = Pn[e]
            out_P[i, 3 * e + 1] = Pt[e, 0]
            out_P[i, 3 * e + 2] = Pt[e, 1]
        for k in range(6):
            out_u[i, k] = uc[k]
        out_conv[i] = True
        out_solves[i] = its if its > 1 else 1


def load() -> None:
    """Load (or compile) the loop's machine code for the argument types of a run: one
    call on a sample of one element, the types :func:`~phri_spring.physics.friction.path.
    solve_path` passes."""
    n, z = 1, np.zeros
    solve_elements(z((1, 6)), np.ones(1), z((n, 6)), z((n, 2, 6)), z(n), np.ones(n), 0.5, True,
                   np.ones(n), z(n), z(n), np.full(n, RELEASED, dtype=np.int8), z((n, 2)),
                   z((n, 2)), z(6), z((n, 3)), z(n), z((1, 6)), z((1, 3 * n)),
                   z((1, n), dtype=np.int8), z(1, dtype=np.int64), np.ones(1, dtype=bool),
                   1e-6)
