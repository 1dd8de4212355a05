"""The coupled model's events by active sets (docs/model.md section 12.3): a sample where
patches slip, stick again, lift off or come back, solved on the small system of the
sliding patches' forces instead of the full semismooth Newton system.

For a given state (which patches are stuck, sliding on an open cone, sliding on a closed
one, released) the coupled equilibrium is linear except for the slip directions: with F
(2K,) the tangential forces of the K patches sliding on an open cone, the cached maps of
the state with those patches tied only on their normal and rotations
(:class:`~phri_spring.physics.friction.maps.StuckMaps`) give u, the patch forces, each
sliding patch's cone force R and its slip increment g, and everything the state's checks
read, all affine in the wrench, the ties and F (:class:`StateMaps`, one product per
state tried). The Coulomb law of a sliding patch, ``F_e = mu R_e g_e / |g_e|``, is
then 2K equations in 2K unknowns, solved by Newton's method (K is a few patches, so a
step is a 2K x 2K solve rather than one of the full system's 132 unknowns).

Which state holds is found as a return mapping does: the elastic predictor (every
touching patch tied where it is) and its corrections, patch by patch: a stuck patch beyond its cone slides,
a sliding one whose cone closes slides freely, a patch pulled off is released, a
released one pressed comes back. Every state accepted passes the checks of any answer
(equilibrium by construction, compression, the cone, no penetration, slip along the
force); where none is found within a few corrections the caller's semismooth Newton
(:func:`~phri_spring.physics.friction.events.solve_event_coupled`) takes the sample.
"""

from __future__ import annotations

import numpy as np

from .form import RELEASED, SLIDING, STATE_RTOL, STUCK, PathState, lu_solve_or_none
from .maps import kept, stuck_maps

__all__ = ["StateMaps", "active_step"]

#: most states tried per sample
_HOPS = 6
#: most Newton steps on the sliding patches' forces
_NEWTON = 12
#: the shortest fraction of a Newton step tried where the full one overshoots
_DAMP_MIN = 1.0 / 16
#: a patch's code in a state tried: released, stuck, sliding on an open cone, sliding on a
#: closed one (free); the first two are the path's RELEASED and STUCK
_OPEN, _FREE = 2, 3


def _tangential_dofs(patches, d):
    """The two tangential dofs of each of ``patches``, in order."""
    return (patches[:, None] * d + np.arange(1, 3)[None, :]).reshape(-1)


class StateMaps:
    """One state's affine maps, stacked: Y = A0 [r; z_D] + AF F + c, with r the wrench,
    z_D the ties of the tied dofs D and F (2K,) the tangential forces of the K patches
    sliding on an open cone, and Y (in this order) u (6), P (n d), the reading's integral
    f = cone_normal P (n, with a reading's cone), the released patches' gap (their
    normal rel), and the sliding patches' (open, then free) tangential rel.

    From the state's :class:`~phri_spring.physics.friction.maps.StuckMaps` (G = C_DD^-1,
    H = T_D^T G T_D): u = H^-1 (r - T_D^T G (delta_D - z_D)) + Uf F and P_D = G T_D u +
    G (delta_D - z_D) - G C_DS F, with Uf = H^-1 (T_D^T G C_DS - T_S^T); P on the sliding
    dofs S is F, elsewhere 0. ``ok`` is False where the state holds no cuff."""

    def __init__(self, form, cache, code):
        n, d = form.n, form.d
        N = n * d
        maps = stuck_maps(form, cache, np.minimum(code, SLIDING), code >= _OPEN)
        self.ok = bool(maps)
        if not self.ok:
            return
        D = maps.D
        nD = D.size
        opn = np.flatnonzero(code == _OPEN)
        K = opn.size
        self.opn, self.K, self.D = opn, K, D
        Sd = _tangential_dofs(opn, d)
        self.Sd = Sd
        G, GT, Hinv = maps.G, maps.GT, maps.Hinv
        W = GT.T                                                  # T_D^T G (6, |D|)
        dD = form.delta[D]
        cols = 6 + nD + 2 * K
        U = np.zeros((6, cols))
        U[:, :6] = Hinv
        U[:, 6:6 + nD] = Hinv @ W
        cu = -(Hinv @ (W @ dD))
        PD = np.zeros((nD, cols))
        if K:
            C_DS = form.C[np.ix_(D, Sd)]
            U[:, 6 + nD:] = Hinv @ (W @ C_DS - form.T[Sd].T)
            PD[:, 6 + nD:] = -(G @ C_DS)
        PD += GT @ U
        PD[:, 6:6 + nD] -= G
        Pm = np.zeros((N, cols))
        Pm[D] = PD
        cP = np.zeros(N)
        cP[D] = GT @ cu + G @ dD
        if K:
            Pm[Sd, 6 + nD:] = np.eye(2 * K)
        blocks, consts = [U, Pm], [cu, cP]
        self.on_reading = form.cone_normal is not None
        if self.on_reading:
            blocks.append(form.cone_normal @ Pm)
            consts.append(form.cone_normal @ cP)
        self.rel = maps.rel
        slid = np.flatnonzero(code >= _OPEN)
        slid = np.concatenate([opn, slid[code[slid] == _FREE]])   # open first, then free
        self.free = slid[K:]
        for rows in (form.normal[maps.rel],
                     _tangential_dofs(slid, d)):
            # rel = T u + delta - C P on these rows
            blocks.append(form.T[rows] @ U - form.C[rows] @ Pm)
            consts.append(form.T[rows] @ cu + form.delta[rows] - form.C[rows] @ cP)
        A = np.vstack(blocks)
        self.A0 = np.ascontiguousarray(A[:, :6 + nD])
        self.AF = np.ascontiguousarray(A[:, 6 + nD:])
        self.c = np.concatenate(consts)
        # where each quantity sits in Y
        at = 6 + N
        self.f_at = at
        at += n if self.on_reading else 0
        self.pen = slice(at, at + maps.rel.size)
        at += maps.rel.size
        self.slid_rel = slice(at, at + 2 * slid.size)
        self.slid = slid
        self.touch = np.flatnonzero(code != RELEASED)
        stuck = np.flatnonzero(code == STUCK)
        self.stuck = stuck
        self.stuck_t = (6 + stuck * d + 1, 6 + stuck * d + 2)
        # the Newton iteration's rows [P_n; f; g] of the open patches and their
        # response to F
        if K:
            rows = [6 + opn * d]
            if self.on_reading:
                rows.append(self.f_at + opn)
            rows.append(np.arange(self.slid_rel.start, self.slid_rel.start + 2 * K))
            self.newton_rows = np.concatenate(rows)
            M = self.AF[self.newton_rows]
            self.M, self.Mn, self.Mg = M, M[:K], M[-2 * K:]
            self.Mf = M[K:2 * K] if self.on_reading else None
            self.I = np.eye(2 * K)
            self.IK = np.eye(K)
            self.I2 = np.eye(2)[None]
            # the event solver's augmentation: with friction set, one value per patch for
            # both tangential dofs, so that y = F + rho g lies along F only where the slip
            # g does (isotropic friction, :class:`~.form.EventArrays`)
            self.rho = form.event_arrays.rho[Sd]
            Dy = self.I + self.rho[:, None] * self.Mg
            self.Dy3 = Dy.reshape(K, 2, 2 * K)
            # the same as Python lists, for the scalar iteration of one sliding patch
            self.M_list = M.tolist()
            self.rho_list = self.rho.tolist()
            self.Dy_list = Dy.tolist()


def _state(form, cache, code):
    """The :class:`StateMaps` of state ``code`` (n,) int8, from ``cache`` or made there."""
    # the key apart from stuck_maps' keys
    return kept(cache, b"active" + code.tobytes(), lambda: StateMaps(form, cache, code))


def _solve(form, sm, z, r, F, tol):
    """The state ``sm`` at wrench r with ties z: (Y, (g, yh) of the open patches or None,
    Newton steps); a boolean mask over the open patches whose cones close on the way, or
    None (see :func:`_newton`)."""
    Y = sm.A0 @ np.concatenate((r, z.reshape(-1)[sm.D]))
    Y += sm.c
    if not sm.K:
        return Y, None, 0
    base = Y[sm.newton_rows]
    base[-2 * sm.K:] -= z[sm.opn, 1:3].reshape(-1)
    newton = _newton_one if sm.K == 1 else _newton_few if sm.K <= 3 else _newton
    out = newton(sm, base, F, form.mu, tol)
    if out is None or not isinstance(out, tuple):
        return out
    F, g, yh, steps = out
    Y += sm.AF @ F
    return Y, (g, yh), steps


def _newton_one(sm, base, F, mu, tol):
    """The Newton iteration of :func:`_newton` for one sliding patch (K = 1), in scalars:
    (F, g, yh, steps), a boolean mask where its cone closes, or None."""
    F0, F1 = float(F[0]), float(F[1])
    b = base.tolist()
    M = sm.M_list
    rho0, rho1 = sm.rho_list
    on_reading = sm.on_reading
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
        a = [[(1.0 if i == c else 0.0) - mu * (h0, h1)[i] * dfc[c]
              - k * ((q00, q01)[i] * Dy[0][c] + (q01, q11)[i] * Dy[1][c])
              for c in (0, 1)] for i in (0, 1)]
        det = a[0][0] * a[1][1] - a[0][1] * a[1][0]
        if det == 0.0:
            return None
        d0 = (a[1][1] * p0 - a[0][1] * p1) / det
        d1 = (a[0][0] * p1 - a[1][0] * p0) / det
        prev = (F0, F1, d0, d1)
        F0 -= d0
        F1 -= d1


def _gauss(a, b):
    """x with a x = b for a small dense system (lists, modified in place), by Gaussian
    elimination with partial pivoting; None if singular."""
    k = len(b)
    for c in range(k):
        p = max(range(c, k), key=lambda i: abs(a[i][c]))
        if a[p][c] == 0.0:
            return None
        if p != c:
            a[c], a[p] = a[p], a[c]
            b[c], b[p] = b[p], b[c]
        piv = a[c][c]
        for i in range(c + 1, k):
            f = a[i][c] / piv
            if f != 0.0:
                ai, ac = a[i], a[c]
                for j in range(c + 1, k):
                    ai[j] -= f * ac[j]
                b[i] -= f * b[c]
    x = [0.0] * k
    for c in range(k - 1, -1, -1):
        t = b[c]
        ac = a[c]
        for j in range(c + 1, k):
            t -= ac[j] * x[j]
        x[c] = t / ac[c]
    return x


def _newton_few(sm, base, F, mu, tol):
    """:func:`_newton` for a few sliding patches (K = 2 or 3) in Python scalars: at this
    size a step's dozens of array operations cost more than its arithmetic."""
    K = sm.K
    K2 = 2 * K
    F = F.tolist()
    b = base.tolist()
    M = sm.M_list
    rho = sm.rho_list
    Dy = sm.Dy_list
    gi = len(b) - K2
    steps, last, lam, prev = 0, np.inf, 1.0, None
    while True:
        v = [bi + sum(m_ * f_ for m_, f_ in zip(Mi, F)) for bi, Mi in zip(b, M)]
        rows = [K + e if sm.on_reading and v[K + e] < v[e] else e for e in range(K)]
        fc = [v[j] for j in rows]
        if min(fc) <= 0.0:
            return np.array([x <= 0.0 for x in fc])
        y = [F[i] + rho[i] * v[gi + i] for i in range(K2)]
        ny = [(y[2 * e] ** 2 + y[2 * e + 1] ** 2) ** 0.5 for e in range(K)]
        if min(ny) <= 0.0:
            return None
        h = [y[i] / ny[i // 2] for i in range(K2)]
        R = [mu * x for x in fc]
        phi = [F[i] - R[i // 2] * h[i] for i in range(K2)]
        res = max(abs(x) for x in phi)
        if res <= tol:
            # on the cones exactly (as in _newton): fc = fb + dfc mu Y fc
            A = [[(1.0 if e == c else 0.0)
                  - mu * (M[rows[e]][2 * c] * h[2 * c] + M[rows[e]][2 * c + 1] * h[2 * c + 1])
                  for c in range(K)] for e in range(K)]
            fc = _gauss(A, [b[j] for j in rows])
            if fc is None:
                return None
            F = np.array([mu * fc[i // 2] * h[i] for i in range(K2)])
            g = np.asarray(b[gi:]) + sm.Mg @ F
            return F, g.reshape(K, 2), np.asarray(h).reshape(K, 2), steps
        if not res < last:
            # overshot (a slip direction turning fast): back along the step, or give up
            if prev is None or lam <= _DAMP_MIN or steps == _NEWTON:
                return None
            lam *= 0.5
            F = [f0 - lam * d0 for f0, d0 in zip(*prev)]
            steps += 1
            continue
        if steps == _NEWTON:
            return None
        last, lam = res, 1.0
        steps += 1
        # J = I - d(R yh)/dF with d(R yh_e)/dF = yh_e mu dfc_e + R_e/|y_e| (I - yh yh^T) Dy_e
        J = []
        for i in range(K2):
            e, a = i // 2, i % 2
            k = R[e] / ny[e]
            q0 = (1.0 if a == 0 else 0.0) - h[i] * h[2 * e]
            q1 = (1.0 if a == 1 else 0.0) - h[i] * h[2 * e + 1]
            Me, D0, D1 = M[rows[e]], Dy[2 * e], Dy[2 * e + 1]
            J.append([(1.0 if i == c else 0.0) - mu * h[i] * Me[c]
                      - k * (q0 * D0[c] + q1 * D1[c]) for c in range(K2)])
        dF = _gauss(J, phi)
        if dF is None:
            return None
        prev = (F, dF)
        F = [f0 - d0 for f0, d0 in zip(F, dF)]


def _newton(sm, base, F, mu, tol):
    """Newton's method on the K sliding patches' forces F (2K,): F_e = mu R_e y_e/|y_e|
    with R_e the cone's normal force and y_e = F_e + rho_e g_e, where [P_n; f; g] =
    ``base`` + M F (:class:`StateMaps`). Returns (F, g (K, 2), y/|y| (K, 2), steps), a
    boolean mask over the patches whose cones close on the way (they slide freely), or
    None (a slip that vanishes, no convergence: not this state)."""
    K = sm.K
    steps, last, lam, prev = 0, np.inf, 1.0, None
    while True:
        v = sm.M @ F
        v += base
        Pn = v[:K]
        if not sm.on_reading:
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
            if not sm.on_reading or not on.any():
                fb = base[:K]
            elif on.all():
                fb = base[K:2 * K]
            else:
                fb = np.where(on, base[K:2 * K], base[:K])
            A = sm.IK - mu * (dfc.reshape(K, K, 2) * yh[None]).sum(axis=2)
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


def _next_state(form, state, sm, code, z, Y, P, fc, slip, f_tol, x_tol):
    """The state to try after ``code`` failed a check, patch by patch (see
    :func:`active_step`), with the sliding forces to start from: (code, F), or (None,
    None) where nothing would change or nothing touches. ``P``, ``fc``: the patch forces
    (n d) and cone forces (n) of the state tried, as lists; ties z are updated in place
    for patches that stick where they are or come back."""
    n, d, mu = form.n, form.d, form.mu
    old = code.tolist()
    new = list(old)
    if slip is not None:
        g, yh = slip
        along = (g[:, 0] * yh[:, 0] + g[:, 1] * yh[:, 1]).tolist()
    start = {}                      # a newly sliding patch's force to start from
    slid_before = None              # the patches that slid on an open cone at the last sample
    k = 0                           # the open patches' order in slip
    for e in range(n):
        c = old[e]
        if c == RELEASED:
            continue
        i = e * d
        if P[i] < -f_tol:
            new[e] = RELEASED
        elif c == STUCK:
            t0, t1 = P[i + 1], P[i + 2]
            tn = (t0 * t0 + t1 * t1) ** 0.5
            f = fc[e]
            if tn > mu * max(f, 0.0) + f_tol:
                # beyond its cone it slides: on the cone along the force it had stuck (or,
                # if it slid at the last sample, with the force it had then), or freely
                # where the cone has closed
                if f > 0.0:
                    new[e] = _OPEN
                    if slid_before is None:
                        slid_before = set(np.flatnonzero(
                            (state.cls == SLIDING) & state.s.any(axis=1)).tolist())
                    if e in slid_before:
                        start[e] = (float(state.P[i + 1]), float(state.P[i + 2]))
                    else:
                        start[e] = (t0 * mu * f / tn, t1 * mu * f / tn)
                else:
                    new[e] = _FREE
        elif c == _OPEN:
            if fc[e] <= 0.0:
                new[e] = _FREE          # its cone closed: it slides freely
            elif along[k] < -x_tol:
                new[e] = STUCK          # its slip would run against its force
        elif fc[e] > f_tol:
            new[e] = STUCK              # a free patch's cone opens: it sticks where it is
            at = sm.slid_rel.start + 2 * int(np.flatnonzero(sm.slid == e)[0])
            z[e, 1:3] = Y[at:at + 2]
        if c == _OPEN:
            k += 1
    if sm.rel.size:
        # a released patch whose skin the others press into its cuff comes back, landing
        # where its skin was at the last sample (as in the semismooth Newton)
        back = sm.rel[Y[sm.pen] > x_tol]
        if back.size:
            for e in back.tolist():
                new[e] = STUCK
            land = (form.T @ state.u + form.delta - form.C @ state.P).reshape(n, d)
            z[back, 1:] = land[back, 1:]
    if new == old or not any(new):
        return None, None
    F = []
    for e in range(n):
        if new[e] == _OPEN:
            F.extend(start.get(e, (P[e * d + 1], P[e * d + 2])))
    return np.array(new, dtype=np.int8), np.array(F)


def active_step(form, cache: dict, state: PathState, r, f_tol, x_tol):
    """One sample of the coupled model from ``state`` by active sets (module docstring):
    (u, P, new state, solves, True), or None where no consistent state is found (then the
    semismooth Newton takes the sample). ``f_tol``, ``x_tol``: the state checks'
    tolerances [N, m]."""
    n, d, mu = form.n, form.d, form.mu
    N = n * d
    f_tol, x_tol = float(f_tol), float(x_tol)      # Python scalars for the per-patch loop
    z = state.z.copy()
    tol = f_tol * (1e-12 / STATE_RTOL)     # 1e-12 of the sample's force scale
    # the elastic predictor: every touching patch tied where it is (a sliding patch's tie
    # is where its last slip ended, a free one's where its skin was), corrected from there
    code = (state.cls != RELEASED).astype(np.int8)
    F = np.zeros(0)
    solves = 0
    tried = [code]
    for _ in range(_HOPS):
        sm = _state(form, cache, code)
        if not sm.ok:
            return None
        sol = _solve(form, sm, z, r, F, tol)
        solves += 1
        if sol is None:
            return None
        if not isinstance(sol, tuple):
            # sliding patches whose cone closes on the way: they slide freely
            code[sm.opn[sol]] = _FREE
            F = F.reshape(-1, 2)[~sol].reshape(-1)
            continue
        Y, slip, steps = sol
        solves += steps
        P = Y[6:6 + N]
        Pn = P[0::d]
        fc = np.minimum(Pn, Y[sm.f_at:sm.f_at + n]) if sm.on_reading else Pn
        # the usual outcome first, in few operations: every check passes
        ok = Pn[sm.touch].min() >= -f_tol
        if ok and sm.stuck.size:
            tn = np.hypot(Y[sm.stuck_t[0]], Y[sm.stuck_t[1]])
            ok = (tn - mu * np.maximum(fc[sm.stuck], 0.0)).max() <= f_tol
        if ok and sm.K:
            g, yh = slip
            ok = (fc[sm.opn].min() > 0.0
                  and (g[:, 0] * yh[:, 0] + g[:, 1] * yh[:, 1]).min() >= -x_tol)
        if ok and sm.free.size:
            ok = fc[sm.free].max() <= f_tol
        if ok and sm.rel.size:
            ok = Y[sm.pen].max() <= x_tol
        if ok:
            s = state.s
            if sm.slid.size:
                # a sliding patch's tie is where its slip ended; a free one's follows the
                # skin: both where the patch is now
                z[sm.slid, 1:3] = Y[sm.slid_rel].reshape(-1, 2)
                s = s.copy()
                s[sm.slid] = 0.0
                if sm.K:
                    s[sm.opn] = yh
            u, P = Y[:6].copy(), P.copy()
            return u, P, PathState(cls=np.minimum(code, SLIDING), z=z, s=s, u=u, P=P), \
                solves, True
        # the next state: each patch corrected on its own, as a return mapping does (a
        # loop over the patches: few of them change, and at this size Python's scalars
        # cost less than a few dozen array operations)
        last = code
        code, F = _next_state(form, state, sm, code, z, Y, P.tolist(), fc.tolist(), slip,
                              f_tol, x_tol)
        if code is None:
            return None
        if any(np.array_equal(code, t) for t in tried):
            # a patch at the edge of contact toggles: released, its skin presses it back;
            # tied where it lands, it pulls. It touches with its cone closed (the reading
            # under it not compressive): it slides freely (the semismooth Newton's answer)
            flip = (code == RELEASED) != (last == RELEASED)
            flip &= (code <= STUCK) & (last <= STUCK)
            if flip.any():
                free = code.copy()
                free[flip] = _FREE
                if not any(np.array_equal(free, t) for t in tried):
                    code = free
        tried.append(code)
    return None
