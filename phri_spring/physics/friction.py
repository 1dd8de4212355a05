"""Coulomb friction at the cuff-skin interface: contact that lets go and slides.

docs/model.md section 12. With ``interface.friction_coefficient`` (mu) set, each
element (spring model) or patch (coupled model) is in one of three states:

* **released** -- it has lifted off and carries nothing: no normal force, no
  tangential force, no moment;
* **stuck** -- it presses (normal force >= 0) and its tangential force stays within
  the friction cone |P_t| <= mu P_n; its tangential (and, for a patch, rotational)
  motion is tied to the cuff, offset by the slip z it has accumulated;
* **sliding** -- it presses and its tangential force is on the cone,
  P_t = mu P_n s with s the unit direction of its slip increment.

Both arm models are written in one compliance form (the coupled model's, docs/model.md
section 10.3): patch forces P (n d, local axes: normal, axial, circumferential[, three
rotations]), total compliance C, the rigid map T (n d, 6) and the preload offset delta.
For the spring model C is diagonal (1/k_e normal, 1/k_s,e tangential, d = 3) and T's rows
are b_e and the tangential rows of B_e. For a given state the equilibrium is linear:

    stuck or sliding, normal and rotational dofs:  (C P)_i = (T u + delta - z)_i
    stuck, tangential dofs:                        (C P)_i = (T u + delta - z)_i
    sliding, tangential dofs:                      P_i = mu P_n,e s_e,i
    released:                                      P_e = 0
    the cuff:                                      T^T P = W + W_pre

Friction makes the answer depend on the loading path, so a log is solved in order,
each sample from the state the previous one left (backward-Euler return mapping):
the state is updated until it is consistent -- stuck patches inside the cone and
pressing, sliding ones pressing with their slip increment along s, released ones not
penetrating. Samples that leave the state unchanged (every pressing patch stuck, the
set of released ones the same) are affine in the wrench and solved together, so a
log costs a few vectorised products between the samples where something slips,
lifts off or comes back. The problem is not convex (Coulomb friction is not the
minimum of an energy); what the solver guarantees is that every sample it reports as
converged satisfies equilibrium to round-off, the cone, compressive normal forces and
no penetration, checked; otherwise the sample is flagged and its forces are NaN, and
the next sample starts from the last consistent state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve, lu_factor, lu_solve

from .geometry import element_jacobians

__all__ = ["InterfaceForm", "PathState", "interface_form", "initial_state", "solve_path",
           "RELEASED", "STUCK", "SLIDING"]

RELEASED, STUCK, SLIDING = 0, 1, 2
#: relative tolerance of the state checks (forces against the sample's force scale)
STATE_RTOL = 1e-9
#: most state updates per sample
_MAX_UPDATES = 60
#: a sliding patch's direction has settled when it moves less than this [-]
_DIR_TOL = 1e-10
#: samples solved together while the state holds
_BLOCK = 4096
_FIRST_BLOCK = 8
#: Newton steps without halving the residual before a sample is given up
_STALL = 6


@dataclass(frozen=True, eq=False)
class InterfaceForm:
    """An arm model in compliance form (see the module docstring), local axes, SI units.

    Attributes
    ----------
    n, d : int
        Patches (elements) and dofs per patch (3 or 6).
    C : ndarray, shape (n d, n d)
        Total compliance [m/N, rad/(N*m)].
    C_skin : ndarray, shape (n d, n d), or None
        Compliance of the skin alone (the coupled model's C_t): how pressing patches move
        the skin under a released one. None: a released element's skin does not move.
    T : ndarray, shape (n d, 6)
    delta : ndarray, shape (n d,)
    W_pre : ndarray, shape (6,)
    mu : float
        Coulomb coefficient [-].
    diagonal : bool
        C is diagonal (the spring model).
    """

    n: int
    d: int
    C: np.ndarray
    C_skin: np.ndarray | None
    T: np.ndarray
    delta: np.ndarray
    W_pre: np.ndarray
    mu: float
    diagonal: bool

    @property
    def normal(self) -> np.ndarray:
        return np.arange(self.n) * self.d


def interface_form(model) -> InterfaceForm:
    """The compliance form of a spring or coupled model with ``friction_coefficient`` set."""
    mu = float(model.friction_coefficient)
    if hasattr(model, "K_t"):        # the coupled model: already in this form
        return InterfaceForm(n=model.n, d=model.dofs, C=model.C, C_skin=model.C_t, T=model.T,
                             delta=model.delta, W_pre=model.W_pre, mu=mu, diagonal=False)
    g = model.geometry
    n = g.n
    B = element_jacobians(g.points)                                   # (n, 3, 6)
    a = np.array([1.0, 0.0, 0.0])
    circ = np.cross(g.normals, a)
    T = np.stack([g.b, B[:, 0, :], np.einsum("ei,eij->ej", circ, B)], axis=1).reshape(3 * n, 6)
    comp = np.stack([1.0 / model.k, 1.0 / model.k_shear, 1.0 / model.k_shear], axis=1).ravel()
    delta = np.zeros((n, 3))
    delta[:, 0] = model.delta0
    return InterfaceForm(n=n, d=3, C=np.diag(comp), C_skin=None, T=T, delta=delta.ravel(),
                         W_pre=model.W_pre, mu=mu, diagonal=True)


@dataclass
class PathState:
    """Where the loading path has left the interface (carried from sample to sample).

    Attributes
    ----------
    cls : ndarray of int, shape (n,)
        RELEASED, STUCK or SLIDING.
    z : ndarray, shape (n, d)
        Offset of each patch's tie [m, rad]: the slip accumulated on its tangential dofs
        and, for a patch that came back, where it landed (0 on the normal dof).
    s : ndarray, shape (n, 2)
        Slip direction of the sliding patches (unit).
    u, P : ndarray, shape (6,), (n d,)
        The last sample's solution (a patch that comes back lands where it was then).
    """

    cls: np.ndarray
    z: np.ndarray
    s: np.ndarray
    u: np.ndarray
    P: np.ndarray

    def copy(self) -> "PathState":
        return PathState(self.cls.copy(), self.z.copy(), self.s.copy(), self.u.copy(),
                         self.P.copy())


def initial_state(form: InterfaceForm) -> PathState:
    """The strap's state at zero wrench: every patch stuck where the strap put it, no slip."""
    n, d = form.n, form.d
    return PathState(cls=np.full(n, STUCK), z=np.zeros((n, d)), s=np.zeros((n, 2)),
                     u=np.zeros(6), P=np.zeros(n * d))


# --------------------------------------------------------------------------- one state
def _solve_state(form: InterfaceForm, r, cls, z, s):
    """(u, P) of one wrench r (6,) in a fixed state; None if the state holds no cuff."""
    n, d, mu = form.n, form.d, form.mu
    N = n * d
    A = np.zeros((N + 6, N + 6))
    b = np.zeros(N + 6)
    dof = np.arange(N).reshape(n, d)
    tied = np.zeros((n, d), dtype=bool)
    tied[cls == STUCK] = True
    tied[cls == SLIDING] = True
    tied[cls == SLIDING, 1:3] = False
    ti = dof[tied]
    A[ti, :N] = form.C[ti]
    A[ti, N:] = -form.T[ti]
    b[ti] = form.delta[ti] - z.ravel()[ti]
    free = dof[cls == RELEASED].ravel()
    A[free, free] = 1.0
    sl = np.flatnonzero(cls == SLIDING)
    for j in (1, 2):
        rows = dof[sl, j]
        A[rows, rows] = 1.0
        A[rows, dof[sl, 0]] = -mu * s[sl, j - 1]
    A[N:, :N] = form.T.T
    b[N:] = r
    try:
        x = lu_solve(lu_factor(A, check_finite=False), b, check_finite=False)
    except (np.linalg.LinAlgError, ValueError):
        return None
    if not np.all(np.isfinite(x)):
        return None
    return x[N:], x[:N]


def _relative(form: InterfaceForm, u, P):
    """Cuff-side minus skin-side motion of every dof not carried by the cuff spring,
    (T u + delta - C P) (n d,): the tie's offset a patch would need to carry P."""
    return form.T @ u + form.delta - form.C @ P


def _penetration(form: InterfaceForm, u, P, e):
    """How far released patches e would be pressed into the skin [m] (> 0: penetrating)."""
    i = form.normal[e]
    pen = form.T[i] @ u + form.delta[i]
    if form.C_skin is not None:
        pen = pen - form.C_skin[i] @ P
    return pen


def _scales(form: InterfaceForm, r):
    force = np.abs(r).max() + np.abs(form.W_pre).max() + 1e-300
    return force, force * np.abs(np.diag(form.C)).max()


def solve_event(form: InterfaceForm, r, state: PathState):
    """One sample from ``state`` by state updates; returns (u, P, new state, solves, ok)."""
    n, d, mu = form.n, form.d, form.mu
    cls, z, s = state.cls.copy(), state.z.copy(), state.s.copy()
    z_start = state.z
    rel_prev = None
    f_tol, x_tol = (STATE_RTOL * v for v in _scales(form, r))
    Ktt = _tangential_stiffness(form)
    for it in range(1, _MAX_UPDATES + 1):
        sol = _solve_state(form, r, cls, z, s)
        if sol is None:      # e.g. every patch released: come back where it was
            if (cls == RELEASED).any():
                back = np.flatnonzero(cls == RELEASED)
                rel_prev = _relative(form, state.u, state.P) if rel_prev is None else rel_prev
                _land(form, z, back, rel_prev)
                cls[back] = STUCK
                continue
            return state.u, state.P, state, it, False
        u, P = sol
        Pe = P.reshape(n, d)
        Pn = Pe[:, 0]
        Pt = Pe[:, 1:3]
        rel = _relative(form, u, P).reshape(n, d)
        new = cls.copy()
        pressing = cls != RELEASED
        # 1. a pressing patch that would pull lets go
        pull = pressing & (Pn < -f_tol)
        new[pull] = RELEASED
        # 2. a released patch the cuff presses into the skin comes back, stuck where it was
        rel_e = np.flatnonzero(cls == RELEASED)
        back = rel_e[_penetration(form, u, P, rel_e) > x_tol] if rel_e.size else rel_e
        # 3. a stuck patch outside the cone starts to slide along its trial force
        tn = np.linalg.norm(Pt, axis=1)
        out = (cls == STUCK) & ~pull & (tn > mu * np.maximum(Pn, 0.0) + f_tol)
        # 4. a sliding patch: its trial force (what it would carry stuck where the sample
        #    began, all else as now) sets the direction; inside the cone it sticks again
        slide = np.flatnonzero((cls == SLIDING) & ~pull)
        back_stick = turn = np.zeros(0, dtype=int)
        if slide.size:
            ds = rel[slide, 1:3] - z_start[slide, 1:3]
            trial = Pt[slide] + np.einsum("eij,ej->ei", Ktt[slide], ds)
            tr = np.linalg.norm(trial, axis=1)
            back_stick = slide[tr < mu * np.maximum(Pn[slide], 0.0) - f_tol]
            with np.errstate(invalid="ignore", divide="ignore"):
                s_new = trial / tr[:, None]
            dev = np.linalg.norm(s_new - s[slide], axis=1)
            turn = np.setdiff1d(slide[(tr > 0) & (dev > _DIR_TOL)], back_stick)
        if not (pull.any() or back.size or out.any() or back_stick.size or turn.size):
            new_state = PathState(cls=cls, z=z, s=s, u=u, P=P)
            sl = cls == SLIDING
            new_state.z[sl, 1:3] = rel[sl, 1:3]
            return u, P, new_state, it, True
        if back.size:
            if rel_prev is None:
                rel_prev = _relative(form, state.u, state.P)
            _land(form, z, back, rel_prev)
            new[back] = STUCK
        if out.any():
            o = np.flatnonzero(out)
            new[o] = SLIDING
            s[o] = Pt[o] / tn[o, None]
        if back_stick.size:
            new[back_stick] = STUCK
            z[back_stick, 1:3] = z_start[back_stick, 1:3]
        if turn.size:
            k = np.searchsorted(slide, turn)
            s[turn] = s_new[k]
        if pull.any():
            z[pull] = 0.0
        cls = new
    return state.u, state.P, state, _MAX_UPDATES, False


class _Elements:
    """The spring model's per-element arrays, ready for the return mapping."""

    def __init__(self, form: InterfaceForm):
        n = form.n
        T = form.T.reshape(n, 3, 6)
        self.Tn = np.ascontiguousarray(T[:, 0, :])
        self.Tt = np.ascontiguousarray(T[:, 1:3, :].reshape(2 * n, 6))   # rows e-axial, e-circ
        self.TtT = np.ascontiguousarray(self.Tt.T)
        self.TnT = np.ascontiguousarray(self.Tn.T)
        cdiag = np.diag(form.C).reshape(n, 3)
        self.kn, self.kt = 1.0 / cdiag[:, 0], 1.0 / cdiag[:, 1]
        self.dn = np.ascontiguousarray(form.delta.reshape(n, 3)[:, 0])
        self.NN = (self.Tn[:, :, None] * self.Tn[:, None, :]).reshape(n, 36)
        Tt3 = T[:, 1:3, :]
        self.TT = np.einsum("eki,ekj->eij", Tt3, Tt3).reshape(n, 36)
        self.Tt3 = Tt3


_ELEMENTS: dict = {}


def solve_event_elements(form: InterfaceForm, r, state: PathState, u0=None):
    """One sample of the spring model (independent elements) from ``state``.

    Given u every element's forces follow by its own return mapping (normal: compressive
    only; tangential: the trial force k_s (J_e u - z_e) from where it stuck, scaled back
    onto the cone when outside), so the equilibrium is six equations in u, solved by a
    semismooth Newton method with the consistent tangent and a backtracking line search
    on the residual, from ``u0`` (default: the last sample's u). Returns (u, P, new state,
    solves, ok) as :func:`solve_event`.
    """
    el = _ELEMENTS.get(id(form))
    if el is None or el[0] is not form:
        _ELEMENTS.clear()
        el = _ELEMENTS[id(form)] = (form, _Elements(form))
    el = el[1]
    n, mu = form.n, form.mu
    kn, kt, dn = el.kn, el.kt, el.dn
    # where each element's tie starts: stuck or sliding ones from their slip, released
    # ones land where they were at the last sample (their skin does not move)
    z0 = state.z[:, 1:3].copy()
    rel = state.cls == RELEASED
    if rel.any():
        z0[rel] = (el.Tt @ state.u).reshape(n, 2)[rel]
    force_scale = np.abs(r).max() + np.abs(form.W_pre).max() + 1e-300
    tol = 1e-13 * force_scale

    def forces(u):
        g = el.Tn @ u
        g += dn
        c = g > 0
        Pn = kn * g
        Pn[~c] = 0.0
        trial = (el.Tt @ u).reshape(n, 2)
        trial -= z0
        trial *= kt[:, None]
        tn = np.sqrt(trial[:, 0] ** 2 + trial[:, 1] ** 2)
        slide = tn > mu * Pn
        slide &= c
        Pt = trial
        dirn = None
        if slide.any():
            dirn = trial[slide] / tn[slide, None]
            Pt = trial.copy()
            Pt[slide] = (mu * Pn[slide])[:, None] * dirn
        Pt[~c] = 0.0
        R = el.TnT @ Pn + el.TtT @ Pt.ravel() - r
        return R, c, Pn, Pt, slide, dirn, tn

    u = (state.u if u0 is None else u0).copy()
    R, c, Pn, Pt, slide, dirn, tn = forces(u)
    res = np.abs(R).max()
    its = 0
    polished = False
    history = []
    while its < _MAX_UPDATES:
        if res <= tol:
            if polished:
                break
            polished = True   # one more step: the residual down to round-off
        elif len(history) >= _STALL and res > 0.5 * history[-_STALL]:
            # no progress: typically a load friction cannot hold (the cuff would slide
            # along or around the arm), which has no equilibrium
            break
        history.append(res)
        its += 1
        stick = c & ~slide
        K = ((kn * c) @ el.NN + (kt * stick) @ el.TT).reshape(6, 6)
        if dirn is not None:
            sl = np.flatnonzero(slide)
            Tts = el.Tt3[sl]
            # d(mu Pn d)/du = mu kn d Tn^T + mu Pn / |trial| kt (I - d d^T) Tt
            proj = np.eye(2)[None] - dirn[:, :, None] * dirn[:, None, :]
            dPt = (mu * kn[sl])[:, None, None] * dirn[:, :, None] * el.Tn[sl, None, :]
            dPt += ((mu * Pn[sl] / tn[sl]) * kt[sl])[:, None, None] * (proj @ Tts)
            K += np.einsum("eki,ekj->ij", Tts, dPt)
        try:
            du = np.linalg.solve(K, -R)
        except np.linalg.LinAlgError:
            du = np.linalg.lstsq(K, -R, rcond=None)[0]
        step = 1.0
        while True:
            cand = forces(u + step * du)
            new_res = np.abs(cand[0]).max()
            if new_res < res or step < 1e-4 or (polished and new_res <= tol):
                break
            step *= 0.5
        u = u + step * du
        R, c, Pn, Pt, slide, dirn, tn = cand
        if new_res >= res and res <= tol:
            break
        res = new_res
    ok = res <= tol * 10 and np.all(np.isfinite(u))
    if not ok:
        return state.u, state.P, state, max(its, 1), False
    cls = np.where(c, np.where(slide, SLIDING, STUCK), RELEASED).astype(state.cls.dtype)
    z = state.z.copy()
    z[:, 1:3] = z0
    s_dir = state.s.copy()
    if dirn is not None:
        z[slide, 1:3] = (el.Tt @ u).reshape(n, 2)[slide] - Pt[slide] / kt[slide, None]
        s_dir[slide] = dirn
    P = np.zeros((n, 3))
    P[:, 0], P[:, 1:3] = Pn, Pt
    P = P.ravel()
    return u, P, PathState(cls=cls, z=z, s=s_dir, u=u, P=P), max(its, 1), True


def _tangential_stiffness(form: InterfaceForm) -> np.ndarray:
    """Each patch's own tangential stiffness, the inverse of its 2x2 tangential block of C,
    (n, 2, 2) [N/m] (the spring model: k_s,e I)."""
    dof = np.arange(form.n * form.d).reshape(form.n, form.d)[:, 1:3]
    blocks = form.C[dof[:, :, None], dof[:, None, :]]
    return np.linalg.inv(blocks)


def _land(form: InterfaceForm, z, e, rel_prev):
    """Patches e come back: tied where they are relative to the cuff (no tangential force
    or moment at touch-down), the normal dof untouched."""
    d = form.d
    r = rel_prev.reshape(form.n, d)
    z[e, 1:] = r[e, 1:]
    z[e, 0] = 0.0


# --------------------------------------------------------------------------- blocks
class _StuckMaps:
    """The affine maps of one state with no sliding patch: u and P from the wrench."""

    def __init__(self, form: InterfaceForm, cls):
        n, d = form.n, form.d
        dof = np.arange(n * d).reshape(n, d)
        self.D = dof[cls == STUCK].ravel()
        self.rel = np.flatnonzero(cls == RELEASED)
        D = self.D
        if form.diagonal:
            g = 1.0 / np.diag(form.C)[D]
            self._G = lambda x: g[:, None] * x if x.ndim == 2 else g * x
        else:
            cf = cho_factor(form.C[np.ix_(D, D)])
            self._G = lambda x: cho_solve(cf, x)
        TD = form.T[D]
        self.GT = self._G(TD)
        H = TD.T @ self.GT
        self.Hinv = np.linalg.inv(0.5 * (H + H.T))
        self.TD = TD
        # penetration of the released patches: affine in u and in P_D
        ni = form.normal[self.rel]
        if form.C_skin is not None and self.rel.size:
            self.Q = form.T[ni] - form.C_skin[np.ix_(ni, D)] @ self.GT
            self.Cs = form.C_skin[np.ix_(ni, D)]
        else:
            self.Q = form.T[ni]
            self.Cs = None
        self.d_rel = form.delta[ni]

    def offsets(self, form, z):
        """For tie offsets z: (c, P0) with u = (r - c) @ Hinv.T, P_D = u @ GT.T + P0."""
        D = self.D
        P0 = self._G(form.delta[D] - z.ravel()[D])
        return self.TD.T @ P0, P0


def _block(form, maps, state, r, f_tol, x_tol):
    """Solve rows r (m, 6) in the state ``state`` (no sliding patch); returns
    (u, P, k, u_next): the first k rows keep the state (k = m if all do); u_next is the
    state's displacement at row k (a start for the event there), None if k = m."""
    n, d, mu = form.n, form.d, form.mu
    c, P0 = maps.offsets(form, state.z)
    u = (r - c) @ maps.Hinv.T
    PD = u @ maps.GT.T + P0
    m = len(r)
    ok = np.ones(m, dtype=bool)
    nd = PD.reshape(m, -1, d)
    Pn = nd[:, :, 0]
    ok &= np.all(Pn >= -f_tol[:, None], axis=1)
    if mu < np.inf:
        tn = np.sqrt(nd[:, :, 1] ** 2 + nd[:, :, 2] ** 2)
        ok &= np.all(tn <= mu * np.maximum(Pn, 0.0) + f_tol[:, None], axis=1)
    if maps.rel.size:
        pen = u @ maps.Q.T + maps.d_rel
        if maps.Cs is not None:
            pen -= P0 @ maps.Cs.T
        ok &= np.all(pen <= x_tol[:, None], axis=1)
    bad = np.flatnonzero(~ok)
    k = int(bad[0]) if bad.size else m
    P = np.zeros((k, n * d))
    P[:, maps.D] = PD[:k]
    return u[:k], P, k, (u[k] if k < m else None)


def _stuck_maps(form, cache, cls):
    key = (cls == STUCK).tobytes()
    maps = cache.get(key)
    if maps is None:
        try:
            maps = _StuckMaps(form, cls)
        except np.linalg.LinAlgError:
            maps = False
        cache[key] = maps
    return maps


def _contact_hop(form, cache, state, r, f_tol, x_tol, u_pred, hops: int = 3):
    """An event where only contacts change (a stuck patch lets go, a released one comes
    back) and nothing leaves the cone: the next state is read off the prediction u_pred
    and checked with its own affine maps. Returns (u, P, state), or None (Newton's job)."""
    n, d, mu = form.n, form.d, form.mu
    cur = state
    u = u_pred
    for _ in range(hops):
        maps = _stuck_maps(form, cache, cur.cls)
        if not maps:
            return None
        c, P0 = maps.offsets(form, cur.z)
        PD = (u @ maps.GT.T + P0).reshape(-1, d)
        Pn = PD[:, 0]
        tn = np.sqrt(PD[:, 1] ** 2 + PD[:, 2] ** 2)
        stuck = np.flatnonzero(cur.cls == STUCK)
        if np.any(tn > mu * np.maximum(Pn, 0.0) + f_tol):
            return None
        cls = cur.cls.copy()
        cls[stuck[Pn < -f_tol]] = RELEASED
        back = np.zeros(0, dtype=int)
        if maps.rel.size:
            pen = u @ maps.Q.T + maps.d_rel
            if maps.Cs is not None:
                pen -= P0 @ maps.Cs.T
            back = maps.rel[pen > x_tol]
            cls[back] = STUCK
        if not (cls == STUCK).any():
            return None
        z = cur.z.copy()
        if back.size:
            _land(form, z, back, _relative(form, state.u, state.P))
        nxt = PathState(cls=cls, z=z, s=cur.s, u=state.u, P=state.P)
        maps = _stuck_maps(form, cache, cls)
        if not maps:
            return None
        ub, Pb, k, u = _block(form, maps, nxt, r[None], np.atleast_1d(f_tol),
                              np.atleast_1d(x_tol))
        if k == 1:
            nxt.u, nxt.P = ub[0].copy(), Pb[0].copy()
            return ub[0], Pb[0], nxt
        cur = nxt
    return None


def solve_path(form: InterfaceForm, r, state: PathState | None = None, cache: dict | None = None,
               max_updates: int | None = None):
    """Solve wrenches r = W + W_pre (m, 6) in order along the loading path.

    Returns
    -------
    u : ndarray, shape (m, 6)
    P : ndarray, shape (m, n d)
        Patch forces on the skin, local axes (0 for released patches) [N, N*m].
    cls : ndarray of int, shape (m, n)
        Each patch's state at each sample.
    solves : ndarray of int, shape (m,)
        Linear solves the sample took (0 for a sample solved in a block).
    converged : ndarray of bool, shape (m,)
    state : PathState
        Where the path ends (pass it to the next chunk of the same log).
    """
    r = np.atleast_2d(np.asarray(r, dtype=float))
    m = len(r)
    n, d = form.n, form.d
    state = initial_state(form) if state is None else state.copy()
    cache = {} if cache is None else cache
    u = np.zeros((m, 6))
    P = np.zeros((m, n * d))
    cls = np.zeros((m, n), dtype=np.int8)
    solves = np.zeros(m, dtype=np.int64)
    conv = np.ones(m, dtype=bool)
    fs, xs = _scales(form, np.zeros(6))
    scale = np.abs(r).max(axis=1) + np.abs(form.W_pre).max() + 1e-300
    f_tol = STATE_RTOL * scale
    x_tol = f_tol * (xs / fs)
    i = 0
    width = _FIRST_BLOCK
    while i < m:
        guess = None
        if not (state.cls == SLIDING).any() and (state.cls == STUCK).any():
            maps = _stuck_maps(form, cache, state.cls)
            if maps:
                # the state usually holds for long stretches between events: grow the
                # block while it does, start small again after an event
                e = min(m, i + width)
                ub, Pb, k, guess = _block(form, maps, state, r[i:e], f_tol[i:e], x_tol[i:e])
                width = min(_BLOCK, 2 * width) if k == e - i else _FIRST_BLOCK
                if k:
                    u[i:i + k], P[i:i + k] = ub, Pb
                    cls[i:i + k] = state.cls
                    state.u, state.P = ub[-1].copy(), Pb[-1].copy()
                    i += k
                    if i >= m:
                        break
        if guess is not None:
            hop = _contact_hop(form, cache, state, r[i], f_tol[i], x_tol[i], guess)
            if hop is not None:
                u[i], P[i], state = hop
                cls[i] = state.cls
                i += 1
                continue
        if form.diagonal:
            ui, Pi, new, its, ok = solve_event_elements(form, r[i], state, guess)
        else:
            ui, Pi, new, its, ok = solve_event(form, r[i], state)
        solves[i] = its
        if ok:
            u[i], P[i], cls[i] = ui, Pi, new.cls
            state = new
        else:
            conv[i] = False
            u[i], P[i] = np.nan, np.nan
            cls[i] = RELEASED
        i += 1
    return u, P, cls, solves, conv, state
