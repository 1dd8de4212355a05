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
        self.I2 = np.eye(2)[None]


def _maps(form, cache, cls, opn, free):
    """The maps of the state (cls with ``opn`` and ``free`` patches sliding): (StuckMaps,
    SlidingMaps or None), or (False, None) where the state holds no cuff."""
    maps = stuck_maps(form, cache, cls, opn | free)
    if not maps or not opn.any():
        return maps, None
    key = ("open", (cls == STUCK).tobytes(), opn.tobytes(), free.tobytes())
    sm = cache.get(key)
    if sm is None:
        sm = SlidingMaps(form, maps, np.flatnonzero(opn))
        if len(cache) >= MAPS_KEPT:
            del cache[next(iter(cache))]
        cache[key] = sm
    return maps, sm


def _solve(form, cache, cls, opn, free, z, r, F, tol):
    """u, P (n d,), the open patches' slip increments g (K, 2) and the Newton steps taken,
    of the state; None where the state holds no cuff or its sliding patches find no
    Coulomb force (a cone closing, a slip that vanishes, no convergence: a different
    state)."""
    n, d, mu = form.n, form.d, form.mu
    maps, sm = _maps(form, cache, cls, opn, free)
    if not maps:
        return None
    D = maps.D
    P0 = maps.G @ (form.delta[D] - z.ravel()[D])
    u = maps.Hinv @ (r - maps.TD.T @ P0)
    PD = maps.GT @ u + P0
    P = np.zeros(n * d)
    if sm is None:
        P[D] = PD
        return u, P, None, 0
    K = sm.opn.size
    # [P_n; f; g] of the open patches at F = 0, then + M F
    base = sm.B_u @ u + sm.B_P @ PD + sm.B_c
    base[sm.g_rows] -= z[sm.opn, 1:3].ravel()
    steps, last = 0, np.inf
    while True:
        v = base + sm.M @ F
        Pn = v[:K]
        if sm.CN is None:
            fc, dfc = Pn, sm.Mn
        else:
            fr = v[K:2 * K]
            on = fr < Pn
            if on.any():
                fc = np.where(on, fr, Pn)
                dfc = np.where(on[:, None], sm.Mf, sm.Mn)
            else:
                fc, dfc = Pn, sm.Mn
        if fc.min() <= 0.0:
            return fc <= 0.0            # these cones close: the patches slide freely
        g = v[sm.g_rows]
        # Alart-Curnier's augmented force y = F + rho g (rho: each dof's stiffness): at
        # the answer F = R y/|y| with y along g; unlike g's own direction, y's stays well
        # defined as the slip of a sample goes to 0
        y = (F + sm.rho * g).reshape(K, 2)
        ny = np.sqrt(y[:, 0] ** 2 + y[:, 1] ** 2)
        if ny.min() <= 0.0:
            return None
        yh = y / ny[:, None]
        R = mu * fc
        phi = F - (R[:, None] * yh).ravel()
        res = np.abs(phi).max()
        if res <= tol:
            break
        # Newton converges quadratically where the state holds: a residual that does not
        # fall is a state without a Coulomb solution
        if steps == _NEWTON or res > last:
            return None
        last = res
        steps += 1
        # d(R yh)/dF = yh mu dfc + R/|y| (I - yh yh^T) (I + rho dg/dF)
        proj = sm.I2 - yh[:, :, None] * yh[:, None, :]
        dRy = mu * yh[:, :, None] * dfc[:, None, :]
        dRy += (R / ny)[:, None, None] * (proj @ sm.Dy3)
        dF = lu_solve_or_none(sm.I - dRy.reshape(2 * K, 2 * K), phi)
        if dF is None:
            return None
        F = F - dF
    u = u + sm.Uf @ F
    P[D] = PD + sm.Pf @ F
    P[sm.Sd] = F
    return u, P, (g.reshape(K, 2), yh), steps


def active_step(form, cache: dict, state: PathState, r, f_tol, x_tol):
    """One sample of the coupled model from ``state`` by active sets (module docstring):
    (u, P, new state, solves, True), or None where no consistent state is found (then the
    semismooth Newton takes the sample). ``f_tol``, ``x_tol``: the state checks'
    tolerances [N, m]."""
    n, d, mu = form.n, form.d, form.mu
    z = state.z.copy()
    back = state.cls == RELEASED
    if back.any():
        # a released patch comes back where its skin is (as in the semismooth Newton)
        land = relative(form, state.u, state.P).reshape(n, d)
        z[back, 1:] = land[back, 1:]
    sliding = state.cls == SLIDING
    was_open = sliding & np.any(state.s != 0.0, axis=1)
    tol = 1e-12 * (np.abs(r).max() + np.abs(form.W_pre).max() + 1e-300)
    # the elastic predictor: every touching patch tied where it is (a sliding patch's tie
    # is where its last slip ended, a free one's where its skin was)
    cls = state.cls.copy()
    cls[sliding] = STUCK
    opn = np.zeros(n, dtype=bool)
    free = np.zeros(n, dtype=bool)
    F = np.zeros(0)
    solves = 0
    for _ in range(_HOPS):
        sol = _solve(form, cache, cls, opn, free, z, r, F, tol)
        if sol is None:
            return None
        if not isinstance(sol, tuple):
            # sliding patches whose cone closes on the way: they slide freely
            solves += 1
            closing = np.flatnonzero(opn)[sol]
            opn[closing] = False
            free[closing] = True
            F = F.reshape(-1, 2)[~sol].ravel()
            continue
        solves += 1 + sol[3]
        u, P, slip, _ = sol
        Pe = P.reshape(n, d)
        Pn = Pe[:, 0]
        tn = np.sqrt(Pe[:, 1] ** 2 + Pe[:, 2] ** 2)
        fc = form.cone_force(P)
        touch = cls != RELEASED
        lift = touch & (Pn < -f_tol)
        over = (cls == STUCK) & ~lift & (tn > mu * np.maximum(fc, 0.0) + f_tol)
        to_open = over & (fc > 0.0)
        to_free = over & ~to_open
        closed = opn & ~lift & (fc <= 0.0)
        reopened = free & ~lift & (fc > f_tol)
        rel = relative(form, u, P).reshape(n, d)
        pressed = ~touch & (rel[:, 0] > x_tol)
        # a sliding patch whose slip would run against its force sticks
        sticks = np.zeros(n, dtype=bool)
        if slip is not None:
            g, yh = slip
            sticks[opn] = np.einsum("ek,ek->e", g, yh) < -x_tol
            sticks &= ~lift
        if not (lift.any() or over.any() or closed.any() or reopened.any()
                or pressed.any() or sticks.any()):
            s = state.s.copy()
            if opn.any():
                z[opn, 1:3] = rel[opn, 1:3]
                s[opn] = yh
            if free.any():
                # a free patch's tie follows the skin: where it is now
                z[free, 1:3] = rel[free, 1:3]
                s[free] = 0.0
            new = PathState(cls=cls, z=z, s=s, u=u, P=P)
            return u, P, new, max(solves, 1), True
        # the next state: each patch corrected on its own, as a return mapping does
        cls[lift] = RELEASED
        opn &= ~lift
        free &= ~lift
        cls[over] = SLIDING
        opn |= to_open
        free |= to_free
        opn &= ~closed
        free |= closed
        free &= ~reopened
        cls[reopened] = STUCK
        z[reopened, 1:3] = rel[reopened, 1:3]     # it sticks where it is
        cls[pressed] = STUCK
        opn &= ~sticks
        cls[sticks] = STUCK
        if not (cls != RELEASED).any():
            return None
        # a newly sliding patch starts on its cone along the force it had stuck, or, if
        # it slid at the last sample, with the force it had then
        Fe = Pe[:, 1:3].copy()
        if to_open.any():
            Fe[to_open] *= (mu * fc[to_open] / tn[to_open])[:, None]
            cont = to_open & was_open
            Fe[cont] = state.P.reshape(n, d)[cont, 1:3]
        F = Fe[opn].ravel()
    return None
