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

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.linalg import LinAlgWarning, cho_factor, cho_solve, lu_factor, lu_solve

from .geometry import element_jacobians

__all__ = ["InterfaceForm", "PathState", "interface_form", "initial_state", "solve_path",
           "RELEASED", "STUCK", "SLIDING"]

RELEASED, STUCK, SLIDING = 0, 1, 2
#: relative tolerance of the state checks (forces against the sample's force scale)
STATE_RTOL = 1e-9
#: samples solved together while the state holds
_BLOCK = 4096
_FIRST_BLOCK = 8


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
        with warnings.catch_warnings():
            warnings.simplefilter("error", LinAlgWarning)
            x = lu_solve(lu_factor(A, check_finite=False), b, check_finite=False)
    except (np.linalg.LinAlgError, ValueError, LinAlgWarning):
        return None
    if not np.all(np.isfinite(x)):
        return None
    x[free] = 0.0   # exactly: pivoting can leave round-off on the rows that say P_e = 0
    return x[N:], x[:N]


def _relative(form: InterfaceForm, u, P):
    """Cuff-side minus skin-side motion of every dof not carried by the cuff spring,
    (T u + delta - C P) (n d,): the tie's offset a patch would need to carry P."""
    return form.T @ u + form.delta - form.C @ P


def _scales(form: InterfaceForm, r):
    force = np.abs(r).max() + np.abs(form.W_pre).max() + 1e-300
    return force, force * np.abs(np.diag(form.C)).max()


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
    from .friction_events import solve_event_coupled, solve_event_elements

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
        event = solve_event_elements if form.diagonal else solve_event_coupled
        ui, Pi, new, its, ok = event(form, r[i], state, guess)
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
