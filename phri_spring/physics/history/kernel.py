"""The sample-by-sample equilibrium of a spring model whose tissue has a history.

One loop over the samples of a log, in order: a quasi-linear viscoelastic tissue
(:mod:`phri_spring.physics.history.relaxation`) and a muscle activation that scales the tissue's
stiffness make every sample's answer depend on the samples before it, so the samples
cannot be solved independently as the elastic model's are. The loop is written in plain
scalar Python so that numba (the ``fast`` extra) can compile it; without numba the same
function runs as Python (:mod:`phri_spring.physics.history.model`).

Per sample n, with c1 = G_inf + sum_i g_i b_i and the memory offset
C0_e = sum_i g_i (a_i h_i,e - b_i F^e_e,n-1) <= 0 (docs/model.md section 15), the tissue of
element e carries T(d_t) = max(0, c1 s F0(d_t) + C0_e), s the activation scale and F0 the
elastic law, in series with the cuff spring k_c,e; its shear spring (tissue eta s k_t with
the same memory, cuff eta k_c) carries k'_s x + w Cs0_e. Each sample minimises a convex
energy: damped Newton with an exact line search on the directional derivative.
"""

from __future__ import annotations

import math

import numpy as np

try:
    from numba import njit as _njit
except ImportError:  # the same loop, interpreted: correct, but one sample at a time in Python
    NUMBA = False

    def _jit(fn):
        return fn
else:
    NUMBA = True

    def _jit(fn):
        # cache: the compiled loop is kept on disk (next to the module, or numba's user
        # cache when that is read-only), so only the first run of an install compiles;
        # the helpers are inlined into the one loop, so a run loads one cached function
        if fn.__name__ == "solve_history":
            return _njit(cache=True, nogil=True, error_model="numpy")(fn)
        return _njit(inline="always", error_model="numpy")(fn)

__all__ = ["solve_history", "NUMBA"]


@_jit
def _element(gap, C0, cs, kt, kc, beta, law_exp, kp, w):
    """(force [N], tangent [N/m]) of one series element at total compression gap [m]."""
    if not law_exp:
        v = kp * gap + w * C0
        if v > 0.0:
            return v, kp
        return 0.0, 0.0
    if gap <= 0.0:
        return 0.0, 0.0
    # T(d) = cs F0(d) + C0 with F0 = (kt / beta) expm1(beta d), or kt d for beta = 0
    if beta > 0.0:
        Tg = cs * kt / beta * math.expm1(beta * gap) + C0
    else:
        Tg = cs * kt * gap + C0
    if Tg <= 0.0:
        return 0.0, 0.0
    if math.isinf(kc):
        if beta > 0.0:
            return Tg, cs * kt * math.exp(beta * gap)
        return Tg, cs * kt
    # d + T(d) / kc = gap on [0, gap]: safeguarded Newton
    lo = 0.0
    hi = gap
    d = gap * kc / (kc + cs * kt)
    T = 0.0
    Tp = cs * kt
    for _ in range(100):
        if beta > 0.0:
            E = math.exp(beta * d)
            T = cs * kt / beta * (E - 1.0) + C0
            Tp = cs * kt * E
        else:
            T = cs * kt * d + C0
            Tp = cs * kt
        Tc = T if T > 0.0 else 0.0
        phi = d + Tc / kc - gap
        if phi > 0.0:
            hi = d
        else:
            lo = d
        if abs(phi) <= 1e-15 * gap or hi - lo <= 1e-15 * gap:
            break
        slope = 1.0 + (Tp / kc if T > 0.0 else 0.0)
        nd = d - phi / slope
        if not (lo < nd < hi):
            nd = 0.5 * (lo + hi)
        d = nd
    if T <= 0.0:
        return 0.0, 0.0
    return T, 1.0 / (1.0 / Tp + 1.0 / kc)


@_jit
def _lu6(M, piv):
    """LU factors of a 6 x 6 M in place (partial pivoting; row swaps in piv)."""
    for c in range(6):
        p = c
        best = abs(M[c, c])
        for r in range(c + 1, 6):
            if abs(M[r, c]) > best:
                best = abs(M[r, c])
                p = r
        piv[c] = p
        if p != c:
            for k in range(6):
                tmp = M[c, k]
                M[c, k] = M[p, k]
                M[p, k] = tmp
        piv_v = M[c, c]
        for r in range(c + 1, 6):
            fct = M[r, c] / piv_v
            M[r, c] = fct
            if fct != 0.0:
                for k in range(c + 1, 6):
                    M[r, k] -= fct * M[c, k]


@_jit
def _lu_solve6(M, piv, x, out):
    """out = M^-1 x from :func:`_lu6`'s factors (x is overwritten)."""
    for c in range(6):
        p = piv[c]
        if p != c:
            tmp = x[c]
            x[c] = x[p]
            x[p] = tmp
        for r in range(c + 1, 6):
            x[r] -= M[r, c] * x[c]
    for c in range(5, -1, -1):
        acc = x[c]
        for k in range(c + 1, 6):
            acc -= M[c, k] * out[k]
        out[c] = acc / M[c, c]


@_jit
def _residual(u, r, c, K, b, delta0, C0, cs, kt, kc, beta, law_exp, kp, w, f, fp, R, fb):
    """Forces f, tangents fp and residual R at u; returns the residual's force scale."""
    n = b.shape[0]
    scale = 0.0
    for j in range(6):
        acc = c[j] - r[j]
        for k in range(6):
            acc += K[j, k] * u[k]
        R[j] = acc
        sj = abs(c[j]) + abs(r[j])
        for k in range(6):
            sj += abs(K[j, k] * u[k])
        if sj > scale:
            scale = sj
    for k in range(6):
        fb[k] = 0.0
    for e in range(n):
        gap = delta0[e]
        for k in range(6):
            gap += b[e, k] * u[k]
        fe, fpe = _element(gap, C0[e], cs, kt[e], kc[e], beta[e], law_exp, kp[e], w[e])
        f[e] = fe
        fp[e] = fpe
        if fe != 0.0:
            for k in range(6):
                R[k] += fe * b[e, k]
                fb[k] += abs(fe * b[e, k])
    for k in range(6):
        if fb[k] > scale:
            scale = fb[k]
    return scale


@_jit
def solve_history(r, A, Bc, scale, b, Ms, PB, axes, delta0, kt, kc, eta, beta, law_exp, G_inf,
                  g, h, hs, Fe, Se, u, out_u, out_f, out_s, out_its, out_conv, max_it, rtol):
    """Solve samples r (m, 6) in order; the state (h, hs, Fe, Se, u) is updated in place.

    Parameters
    ----------
    r : (m, 6) wrench on the cuff plus the strap's [N, N*m]
    A, Bc : (m, T) recursion coefficients a_i, b_i of each sample's step
    scale : (m,) activation scale s of the tissue's stiffness [-]
    b : (n, 6) element rows; Ms : (n, 6, 6) B_e^T P_e B_e; PB : (n, 3, 6) P_e B_e;
        axes : (n, 2, 3) each element's meridian and circumferential unit vectors
    delta0, kt, kc, eta, beta : (n,) preload compression [m], tissue stiffness k0 [N/m], cuff
        stiffness [N/m] (inf: rigid cuff), shear ratio eta [-], stiffening [1/m]
    law_exp : bool, the exponential law (else linear)
    G_inf : float, g : (T,) relaxed fraction and Prony fractions
    h : (T, n), hs : (T, n, 3) memory terms; Fe : (n,), Se : (n, 3) elastic responses of
        the previous sample; u : (6,) its displacement (the start of the next)
    out_u (m, 6), out_f (m, n) normal forces, out_s (m, n, 2) shear forces along the axes,
    out_its (m,), out_conv (m,) : outputs
    """
    m = r.shape[0]
    n = b.shape[0]
    T = g.shape[0]
    C0 = np.zeros(n)
    Cs = np.zeros((n, 3))
    kp = np.zeros(n)
    w = np.zeros(n)
    K = np.zeros((6, 6))
    c = np.zeros(6)
    f = np.zeros(n)
    fp = np.zeros(n)
    R = np.zeros(6)
    fb = np.zeros(6)
    R1 = np.zeros(6)
    J = np.zeros((6, 6))
    du = np.zeros(6)
    ut = np.zeros(6)
    f1 = np.zeros(n)
    fp1 = np.zeros(n)
    last_cs = -1.0
    lu_cs = -1.0
    fpJ = np.zeros(n)
    piv = np.zeros(6, dtype=np.int64)
    for i in range(m):
        s = scale[i]
        c1 = G_inf
        for j in range(T):
            c1 += g[j] * Bc[i, j]
        cs = c1 * s
        for e in range(n):
            acc = 0.0
            a0 = 0.0
            a1 = 0.0
            a2 = 0.0
            for j in range(T):
                gj = g[j]
                aj = A[i, j]
                bj = Bc[i, j]
                acc += gj * (aj * h[j, e] - bj * Fe[e])
                a0 += gj * (aj * hs[j, e, 0] - bj * Se[e, 0])
                a1 += gj * (aj * hs[j, e, 1] - bj * Se[e, 1])
                a2 += gj * (aj * hs[j, e, 2] - bj * Se[e, 2])
            # the tissue never pulls on the skin: the offset is <= 0 (h <= F^e), round-off aside
            C0[e] = acc if acc < 0.0 else 0.0
            Cs[e, 0] = a0
            Cs[e, 1] = a1
            Cs[e, 2] = a2
        if cs != last_cs:
            last_cs = cs
            for e in range(n):
                kte = cs * kt[e]
                if math.isinf(kc[e]):
                    kp[e] = kte
                    w[e] = 1.0
                else:
                    kp[e] = kte * kc[e] / (kte + kc[e])
                    w[e] = kc[e] / (kte + kc[e])
            for j in range(6):
                for k in range(6):
                    acc = 0.0
                    for e in range(n):
                        acc += eta[e] * kp[e] * Ms[e, j, k]
                    K[j, k] = acc
        for j in range(6):
            acc = 0.0
            for e in range(n):
                we = w[e]
                acc += we * (PB[e, 0, j] * Cs[e, 0] + PB[e, 1, j] * Cs[e, 1]
                             + PB[e, 2, j] * Cs[e, 2])
            c[j] = acc
        ri = r[i]
        conv = False
        its = 0
        sc = _residual(u, ri, c, K, b, delta0, C0, cs, kt, kc, beta, law_exp, kp, w, f, fp, R, fb)
        while True:
            rmax = 0.0
            for k in range(6):
                if abs(R[k]) > rmax:
                    rmax = abs(R[k])
            if rmax <= rtol * sc or not math.isfinite(rmax):
                conv = math.isfinite(rmax)
                break
            if its == max_it:
                break
            its += 1
            # the Jacobian K + sum f'_e b_e b_e^T: refactored only when a tangent or K changed
            # (a sample whose contact set is the last one's reuses its factors)
            same = lu_cs == cs
            if same:
                for e in range(n):
                    if fp[e] != fpJ[e]:
                        same = False
                        break
            if not same:
                for j in range(6):
                    for k in range(j, 6):
                        acc = K[j, k]
                        for e in range(n):
                            if fp[e] != 0.0:
                                acc += fp[e] * b[e, j] * b[e, k]
                        J[j, k] = acc
                        J[k, j] = acc
                    for e in range(n):
                        fpJ[e] = fp[e]
                _lu6(J, piv)
                lu_cs = cs
            for k in range(6):
                R1[k] = -R[k]
            _lu_solve6(J, piv, R1, du)
            # exact line search on phi'(alpha) = R(u + alpha du) . du, increasing in alpha
            d0 = 0.0
            for k in range(6):
                d0 += R[k] * du[k]
            for k in range(6):
                ut[k] = u[k] + du[k]
            sc1 = _residual(ut, ri, c, K, b, delta0, C0, cs, kt, kc, beta, law_exp, kp, w, f1,
                            fp1, R1, fb)
            d1 = 0.0
            for k in range(6):
                d1 += R1[k] * du[k]
            if d1 > 0.0 and d0 < 0.0:
                lo = 0.0
                hi = 1.0
                plo = d0
                phi_ = d1
                for _ in range(60):
                    # regula falsi (Illinois) on the monotone phi'
                    alpha = (lo * phi_ - hi * plo) / (phi_ - plo)
                    if not (lo < alpha < hi):
                        alpha = 0.5 * (lo + hi)
                    for k in range(6):
                        ut[k] = u[k] + alpha * du[k]
                    sc1 = _residual(ut, ri, c, K, b, delta0, C0, cs, kt, kc, beta, law_exp, kp,
                                    w, f1, fp1, R1, fb)
                    da = 0.0
                    for k in range(6):
                        da += R1[k] * du[k]
                    if abs(da) <= 1e-12 * abs(d0):
                        break
                    if da > 0.0:
                        hi = alpha
                        phi_ = da
                        plo *= 0.5
                    else:
                        lo = alpha
                        plo = da
                        phi_ *= 0.5
                    if hi - lo <= 1e-14:
                        break
            # the point reached (its residual was the last one evaluated)
            for k in range(6):
                u[k] = ut[k]
                R[k] = R1[k]
            for e in range(n):
                f[e] = f1[e]
                fp[e] = fp1[e]
            sc = sc1
        out_its[i] = its
        out_conv[i] = conv
        for k in range(6):
            out_u[i, k] = u[k]
        # the answer's shear forces and the new memory
        for e in range(n):
            fe = f[e]
            out_f[i, e] = fe
            s0 = 0.0
            s1 = 0.0
            Fn = (fe - C0[e]) / c1
            for j in range(T):
                h[j, e] = A[i, j] * h[j, e] + Bc[i, j] * (Fn - Fe[e])
            Fe[e] = Fn
            for q in range(3):
                x = 0.0
                for k in range(6):
                    x += PB[e, q, k] * u[k]
                sq = eta[e] * kp[e] * x + w[e] * Cs[e, q]
                s0 += sq * axes[e, 0, q]
                s1 += sq * axes[e, 1, q]
                Sn = (sq - Cs[e, q]) / c1
                for j in range(T):
                    hs[j, e, q] = A[i, j] * hs[j, e, q] + Bc[i, j] * (Sn - Se[e, q])
                Se[e, q] = Sn
            out_s[i, e, 0] = s0
            out_s[i, e, 1] = s1
        if not conv:
            # an absurd or unsolvable sample: start the next from rest
            for k in range(6):
                u[k] = 0.0
