"""The coupled model's events by active sets (docs/model.md section 12.3): a sample where
patches slip, stick again, lift off or come back, solved on the small system of the
sliding patches' forces instead of the full semismooth Newton system.

For a given state (which patches are stuck, sliding on an open cone, sliding on a closed
one, released) the coupled equilibrium is linear except for the slip directions: with F
(2K,) the tangential forces of the K patches sliding on an open cone, the cached maps of
the state with those patches tied only on their normal and rotations
(:class:`~phri_spring.physics.friction.maps.StuckMaps`) give u, the tied forces, each
sliding patch's cone force R and its slip increment g, all affine in F
(:class:`SlidingMaps`). The Coulomb law of a sliding patch, F_e = mu R_e g_e / |g_e|, is
then 2K equations in 2K unknowns, solved by Newton's method (K is a few patches, so a
step is a 2K x 2K solve rather than one of the full system's 132 unknowns).

Which state holds is found as a return mapping does: first the path's state as it was,
then, where that is not consistent, the elastic predictor (every touching patch tied
where it is) and its corrections, patch by patch: a stuck patch beyond its cone slides,
a sliding one whose cone closes slides freely, a patch pulled off is released, a
released one pressed comes back. Every state accepted passes the checks of any answer
(equilibrium by construction, compression, the cone, no penetration, slip along the
force); where none is found within a few corrections the caller's semismooth Newton
(:func:`~phri_spring.physics.friction.events.solve_event_coupled`) takes the sample.
"""

from __future__ import annotations

import numpy as np

from .form import RELEASED, SLIDING, STUCK, PathState, lu_solve_or_none, relative
from .maps import MAPS_KEPT, stuck_maps

__all__ = ["SlidingMaps", "active_step"]

#: most states tried per start (the path's own state, then the elastic predictor)
_HOPS = 6
#: most Newton steps on the sliding patches' forces
_NEWTON = 12
#: the shortest fraction of a Newton step tried where the full one overshoots
_DAMP_MIN = 1.0 / 16


class SlidingMaps:
    """Of one state with K patches sliding on an open cone (``opn``, indices): how u, the
    tied forces P_D and, per sliding patch, its normal force P_n, its reading's integral f
    and its relative tangential motion rel_t respond to their tangential forces F (2K,),
    on top of the state's maps with F = 0 (``maps``, in which those patches are tied only
    on the normal and rotations).

    With G = C_DD^-1 (the tied compliance's inverse), the tied rows C_DD P_D + C_DS F =
    T_D u + delta_D - z_D and the cuff T_D^T P_D + T_S^T F = r give
    u = u_0 + Uf F and P_D = P_D,0 + Pf F with Uf = H^-1 (T_D^T G C_DS - T_S^T) and
    Pf = G T_D Uf - G C_DS (H = T_D^T G T_D)."""

    def __init__(self, form, maps, opn):
        d = form.d
        D = maps.D
        self.opn = opn
        self.Sd = (opn[:, None] * d + np.arange(1, 3)[None, :]).ravel()
        Sd = self.Sd
        C_DS = form.C[np.ix_(D, Sd)]
        self.Uf = maps.Hinv @ (maps.GT.T @ C_DS - form.T[Sd].T)            # (6, 2K)
        self.Pf = maps.GT @ self.Uf - maps.solve_tied(C_DS)                # (|D|, 2K)
        self.nS = np.searchsorted(D, opn * d)
        self.TS = form.T[Sd]
        self.CSD = form.C[np.ix_(Sd, D)]
        self.dS = form.delta[Sd]
        self.Mn = self.Pf[self.nS]
        self.Mg = self.TS @ self.Uf - self.CSD @ self.Pf - form.C[np.ix_(Sd, Sd)]
        K = opn.size
        # [P_n; f; rel_t] of the sliding patches = B_u u_0 + B_P P_D,0 + M F (+ delta_S)
        # (f only with a reading's cone)
        rows_u = [np.zeros((K, 6))]
        rows_P = [np.eye(D.size)[self.nS]]
        rows_M = [self.Mn]
        if form.cone_normal is None:
            self.CN, self.Mf = None, None
        else:
            cn = form.cone_normal[opn]
            self.CN = np.ascontiguousarray(cn[:, D])
            self.Mf = self.CN @ self.Pf + cn[:, Sd]
            rows_u.append(np.zeros((K, 6)))
            rows_P.append(self.CN)
            rows_M.append(self.Mf)
        rows_u.append(self.TS)
        rows_P.append(-self.CSD)
        rows_M.append(self.Mg)
        self.B_u = np.vstack(rows_u)
        self.B_P = np.vstack(rows_P)
        self.M = np.vstack(rows_M)
        self.g_rows = np.arange(self.M.shape[0] - 2 * K, self.M.shape[0])
        self.B_c = np.zeros(self.M.shape[0])
        self.B_c[self.g_rows] = self.dS
        self.I = np.eye(2 * K)
        self.rho = 1.0 / np.diag(form.C)[Sd]
        self.Dy3 = (self.I + self.rho[:, None] * self.Mg).reshape(K, 2, 2 * K)
        # the same as Python lists, for the scalar iteration of one sliding patch
        self.M_list = self.M.tolist()
        self.rho_list = self.rho.tolist()
        self.Dy_list = self.Dy3.reshape(2 * K, 2 * K).tolist()
        self.I2 = np.eye(2)[None]


#: a patch's code in a state tried: released, stuck, sliding on an open cone, sliding on a
#: closed one (free); the first two are the path's RELEASED and STUCK
_OPEN, _FREE = 2, 3


def _maps(form, cache, code):
    """The maps of the state ``code`` (n,) int8: (StuckMaps or False where the state holds
    no cuff, SlidingMaps or None, and the indices of the touching, stuck and free
    patches)."""
    key = b"active" + code.tobytes()      # apart from stuck_maps' keys
    hit = cache.get(key)
    if hit is None:
        cls = np.minimum(code, SLIDING)
        opn = code == _OPEN
        maps = stuck_maps(form, cache, cls, code >= _OPEN)
        sm = None if not maps or not opn.any() else SlidingMaps(form, maps, np.flatnonzero(opn))
        # the patches each check is on: touching, stuck, sliding freely
        hit = (maps, sm, np.flatnonzero(code != RELEASED), np.flatnonzero(code == STUCK),
               np.flatnonzero(code == _FREE))
        if len(cache) >= MAPS_KEPT:
            del cache[next(iter(cache))]
        cache[key] = hit
    return hit


def _newton_one(sm, base, F, mu, tol):
    """The Newton iteration of :func:`_solve` for one sliding patch (K = 1), in scalars:
    (F, g, yh, steps), a boolean mask where its cone closes, or None."""
    F0, F1 = float(F[0]), float(F[1])
    b = base.tolist()
    M = sm.M_list
    rho0, rho1 = sm.rho_list
    on_reading = sm.CN is not None
    gi = len(b) - 2
    steps, last, lam, prev = 0, np.inf, 1.0, None
    while True:
        v = [bi + Mi[0] * F0 + Mi[1] * F1 for bi, Mi in zip(b, M)]
        j = 1 if on_reading and v[1] < v[0] else 0      # the cone's row: P_n or f
        fc, dfc = v[j], M[j]
        if fc <= 0.0:
            return np.array([True])
        g0, g1 = v[gi], v[gi + 1]
        y0, y1 = F0 + rho0 * g0, F1 + rho1 * g1
        ny = (y0 * y0 + y1 * y1) ** 0.5
        if ny <= 0.0:
            return None
        h0, h1 = y0 / ny, y1 / ny
        R = mu * fc
        p0, p1 = F0 - R * h0, F1 - R * h1
        res = max(abs(p0), abs(p1))
        if res <= tol:
            # on the cone exactly: with the direction found, |F| = mu fc is linear in fc
            fc = b[j] / (1.0 - mu * (dfc[0] * h0 + dfc[1] * h1))
            F0, F1 = mu * fc * h0, mu * fc * h1
            g0 = b[gi] + M[gi][0] * F0 + M[gi][1] * F1
            g1 = b[gi + 1] + M[gi + 1][0] * F0 + M[gi + 1][1] * F1
            return np.array([F0, F1]), np.array([[g0, g1]]), np.array([[h0, h1]]), steps
        if not res < last:
            # overshot (a slip direction turning fast): back along the step, or give up
            if prev is None or lam <= _DAMP_MIN or steps == _NEWTON:
                return None
            lam *= 0.5
            F0, F1 = prev[0] - lam * prev[2], prev[1] - lam * prev[3]
            steps += 1
            continue
        if steps == _NEWTON:
            return None
        last, lam = res, 1.0
        steps += 1
        # J = I - d(R yh)/dF, d(R yh)/dF = yh mu dfc + R/|y| (I - yh yh^T) dy/dF,
        # dy/dF = I + rho dg/dF
        Dy = sm.Dy_list
        k = R / ny
        q00, q01, q11 = 1.0 - h0 * h0, -h0 * h1, 1.0 - h1 * h1
        a = [[(1.0 if i == j else 0.0) - mu * (h0, h1)[i] * dfc[j]
              - k * ((q00, q01)[i] * Dy[0][j] + (q01, q11)[i] * Dy[1][j])
              for j in (0, 1)] for i in (0, 1)]
        det = a[0][0] * a[1][1] - a[0][1] * a[1][0]
        if det == 0.0:
            return None
        d0 = (a[1][1] * p0 - a[0][1] * p1) / det
        d1 = (a[0][0] * p1 - a[1][0] * p0) / det
        prev = (F0, F1, d0, d1)
        F0 -= d0
        F1 -= d1


def _solve(form, cache, code, z, r, F, tol):
    """The state ``code`` at wrench r with ties z: (u, P (n d,), (g, yh) of the open
    patches or None, Newton steps, the state's maps from :func:`_maps`); None where the state holds no cuff
    or its sliding patches find no Coulomb force (a slip that vanishes, no convergence: a
    different state); a boolean mask over the open patches where their cones close on
    the way."""
    n, d, mu = form.n, form.d, form.mu
    hit = _maps(form, cache, code)
    maps, sm = hit[0], hit[1]
    if not maps:
        return None
    D = maps.D
    P0 = maps.G @ (maps.delta_D - z.reshape(-1)[D])
    u = maps.Hinv @ (r - maps.TD.T @ P0)
    PD = maps.GT @ u
    PD += P0
    P = np.zeros(n * d)
    if sm is None:
        P[D] = PD
        return u, P, None, 0, hit
    K = sm.opn.size
    # [P_n; f; g] of the open patches at F = 0, then + M F
    base = sm.B_u @ u + sm.B_P @ PD + sm.B_c
    base[-2 * K:] -= z[sm.opn, 1:3].reshape(-1)
    out = _newton_one(sm, base, F, mu, tol) if K == 1 else _newton(sm, base, F, mu, tol)
    if out is None or not isinstance(out, tuple):
        return out
    F, g, yh, steps = out
    u += sm.Uf @ F
    P[D] = PD + sm.Pf @ F
    P[sm.Sd] = F
    return u, P, (g, yh), steps, hit


def _newton(sm, base, F, mu, tol):
    """Newton's method on F = mu R y/|y| for K sliding patches (docstring of
    :func:`_solve`): (F, g (K, 2), yh (K, 2), steps), a mask of closing cones, or None."""
    K = sm.opn.size
    steps, last, lam, prev = 0, np.inf, 1.0, None
    while True:
        v = sm.M @ F
        v += base
        Pn = v[:K]
        if sm.CN is None:
            fc, dfc = Pn, sm.Mn
        else:
            fr = v[K:2 * K]
            on = fr < Pn
            if on.all():        # the usual case: the reading is the smaller
                fc, dfc = fr, sm.Mf
            elif on.any():
                fc = np.where(on, fr, Pn)
                dfc = np.where(on[:, None], sm.Mf, sm.Mn)
            else:
                fc, dfc = Pn, sm.Mn
        if fc.min() <= 0.0:
            return fc <= 0.0            # these cones close: the patches slide freely
        g = v[-2 * K:]
        # Alart-Curnier's augmented force y = F + rho g (rho: each dof's stiffness): at
        # the answer F = R y/|y| with y along g; unlike g's own direction, y's stays well
        # defined as the slip of a sample goes to 0
        y = (sm.rho * g + F).reshape(K, 2)
        ny = np.hypot(y[:, 0], y[:, 1])
        if ny.min() <= 0.0:
            return None
        yh = y / ny[:, None]
        R = mu * fc
        phi = F - (R[:, None] * yh).reshape(-1)
        res = max(phi.max(), -phi.min())
        if res <= tol:
            # on the cones exactly: with the directions found, F = mu Y fc and fc is
            # affine in F, a K x K solve
            if sm.CN is None or not on.any():
                fb = base[:K]
            elif on.all():
                fb = base[K:2 * K]
            else:
                fb = np.where(on, base[K:2 * K], base[:K])
            A = np.eye(K) - mu * np.einsum("ekc,kc->ek", dfc.reshape(K, K, 2), yh)
            fc = lu_solve_or_none(A, fb)
            if fc is None:
                return None
            F = (mu * fc[:, None] * yh).reshape(-1)
            g = base[-2 * K:] + sm.Mg @ F
            return F, g.reshape(K, 2), yh, steps
        if not res < last:
            # overshot (a slip direction turning fast): back along the step, or give up
            if prev is None or lam <= _DAMP_MIN or steps == _NEWTON:
                return None
            lam *= 0.5
            F = prev[0] - lam * prev[1]
            steps += 1
            continue
        if steps == _NEWTON:
            return None
        last, lam = res, 1.0
        steps += 1
        # d(R yh)/dF = yh mu dfc + R/|y| (I - yh yh^T) (I + rho dg/dF)
        proj = sm.I2 - yh[:, :, None] * yh[:, None, :]
        dRy = mu * yh[:, :, None] * dfc[:, None, :]
        dRy += (R / ny)[:, None, None] * (proj @ sm.Dy3)
        dF = lu_solve_or_none(sm.I - dRy.reshape(2 * K, 2 * K), phi)
        if dF is None:
            return None
        prev = (F, dF)
        F = F - dF


def active_step(form, cache: dict, state: PathState, r, f_tol, x_tol, first=None):
    """One sample of the coupled model from ``state`` by active sets (module docstring):
    (u, P, new state, solves, True), or None where no consistent state is found (then the
    semismooth Newton takes the sample). ``f_tol``, ``x_tol``: the state checks'
    tolerances [N, m]. ``first``: (u, P) of the path's own state at r where it is known
    (a block of that state ended at this sample) and no patch slides: the predictor."""
    n, d, mu = form.n, form.d, form.mu
    cone = form.cone_normal
    z = state.z.copy()
    tol = 1e-12 * (max(r.max(), -r.min()) + form.pre_scale)
    # the elastic predictor: every touching patch tied where it is (a sliding patch's tie
    # is where its last slip ended, a free one's where its skin was), corrected from there
    code = (state.cls != RELEASED).astype(np.int8)
    F = np.zeros(0)
    solves = 0
    for _ in range(_HOPS):
        if first is not None:
            sol = first + (None, 0, _maps(form, cache, code))
            first = None
        else:
            sol = _solve(form, cache, code, z, r, F, tol)
        solves += 1
        if sol is None:
            return None
        if not isinstance(sol, tuple):
            # sliding patches whose cone closes on the way: they slide freely
            code[np.flatnonzero(code == _OPEN)[sol]] = _FREE
            F = F.reshape(-1, 2)[~sol].reshape(-1)
            continue
        u, P, slip, steps, (maps, sm, touch, stuck, fre) = sol
        solves += steps
        Pn = P[0::d]
        tn = np.hypot(P[1::d], P[2::d])
        fc = Pn if cone is None else np.minimum(Pn, cone @ P)
        # the usual outcome first, in few operations: every check passes
        ok = Pn[touch].min() >= -f_tol
        if ok and stuck.size:
            ok = (tn[stuck] - mu * np.maximum(fc[stuck], 0.0)).max() <= f_tol
        if ok and sm is not None:
            g, yh = slip
            ok = (fc[sm.opn].min() > 0.0
                  and (g[:, 0] * yh[:, 0] + g[:, 1] * yh[:, 1]).min() >= -x_tol)
        if ok and fre.size:
            ok = fc[fre].max() <= f_tol
        if ok and maps.rel.size:
            ok = (maps.T_rel @ u + maps.d_rel - maps.C_rel @ P).max() <= x_tol
        if ok:
            s = state.s
            if maps.free.size:
                rel = relative(form, u, P).reshape(n, d)
                s = s.copy()
                if sm is not None:
                    z[sm.opn, 1:3] = rel[sm.opn, 1:3]
                    s[sm.opn] = yh
                # a free patch's tie follows the skin: where it is now
                z[fre, 1:3] = rel[fre, 1:3]
                s[fre] = 0.0
            cls = np.minimum(code, SLIDING)
            return u, P, PathState(cls=cls, z=z, s=s, u=u, P=P), solves, True
        # the next state: each patch corrected on its own, as a return mapping does
        new = code.copy()
        lift = Pn < -f_tol
        lift &= code != RELEASED
        new[lift] = RELEASED
        over = tn > mu * np.maximum(fc, 0.0) + f_tol
        over &= code == STUCK
        over &= ~lift
        if over.any():
            # a stuck patch beyond its cone slides: on its cone, or freely if that closed
            new[over] = np.where(fc[over] > 0.0, _OPEN, _FREE)
        if sm is not None:
            o = sm.opn
            g, yh = slip
            # a sliding patch whose cone closed slides freely; one whose slip would run
            # against its force sticks
            new[o[(fc[o] <= 0.0) & ~lift[o]]] = _FREE
            new[o[(g[:, 0] * yh[:, 0] + g[:, 1] * yh[:, 1] < -x_tol) & ~lift[o]]] = STUCK
        reopened = fre[(fc[fre] > f_tol) & ~lift[fre]]
        if reopened.size:
            # it sticks where it is now
            new[reopened] = STUCK
            rel = relative(form, u, P).reshape(n, d)
            z[reopened, 1:3] = rel[reopened, 1:3]
        if maps.rel.size:
            # a released patch whose skin the others press into its cuff comes back,
            # landing where its skin was at the last sample (as in the semismooth Newton)
            pen = maps.T_rel @ u + maps.d_rel - maps.C_rel @ P
            back = maps.rel[pen > x_tol]
            if back.size:
                new[back] = STUCK
                land = relative(form, state.u, state.P).reshape(n, d)
                z[back, 1:] = land[back, 1:]
        if not new.any() or np.array_equal(new, code):
            return None
        # a newly sliding patch starts on its cone along the force it had stuck, or, if
        # it slid at the last sample, with the force it had then
        Pe = P.reshape(n, d)
        Fe = Pe[:, 1:3].copy()
        to_open = over & (new == _OPEN)
        if to_open.any():
            Fe[to_open] *= (mu * fc[to_open] / tn[to_open])[:, None]
            cont = to_open & (state.cls == SLIDING)
            cont &= np.any(state.s != 0.0, axis=1)
            Fe[cont] = state.P.reshape(n, d)[cont, 1:3]
        code = new
        F = Fe[code == _OPEN].reshape(-1)
    return None
