"""The interface in compliance form and the state of a loading path (docs/model.md
section 12): what the friction solvers of :mod:`phri_spring.physics.friction.path` and
:mod:`phri_spring.physics.friction.events` share. The law itself is described in
:mod:`phri_spring.physics.friction.path`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.linalg import get_lapack_funcs

from .states import RELEASED, SLIDING, STUCK, interface_mu
from ..cuff.geometry import element_jacobians

__all__ = ["InterfaceForm", "PathState", "interface_form", "initial_state", "interface_mu",
           "RELEASED", "STUCK", "SLIDING", "STATE_RTOL"]

#: relative tolerance of the state checks (forces against the sample's force scale)
STATE_RTOL = 1e-9

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
    normal_response : NormalResponse or None
        The spring model's normal law where it is not the linear spring 1/C (a nonlinear
        tissue law, :mod:`phri_spring.physics.friction.normal`); None: linear.
    cone_normal : ndarray, shape (n, n d), or None
        With it, the friction cone's normal force is the smaller of P_n and f =
        cone_normal P [N], the coupled model's traction integral with the skin's local
        normal (N_out C_t), which never exceeds what its patches report (docs/model.md
        10.6): a patch's shear then stays within mu times the force along its normal and
        within mu times the force its sensor reads. None: P_n alone.
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
    normal_response: object = None
    cone_normal: np.ndarray | None = None

    @property
    def normal(self) -> np.ndarray:
        return np.arange(self.n) * self.d

    def cone_force(self, P) -> np.ndarray:
        """The normal force of each patch's friction cone, (..., n) from P (..., n d):
        P_n, or with ``cone_normal`` the smaller of P_n and f = cone_normal P."""
        P = np.asarray(P)
        if self.cone_normal is None:
            return P[..., ::self.d]
        return np.minimum(P[..., ::self.d], P @ self.cone_normal.T)

    @cached_property
    def elements(self) -> "ElementArrays":
        """The spring model's per-element arrays (diagonal C only), made once per form."""
        return ElementArrays(self)

    @cached_property
    def event_arrays(self) -> "EventArrays":
        """The coupled model's constant event arrays, made once per form."""
        return EventArrays(self)


class EventArrays:
    """The coupled model's constant arrays of an event's Newton system (see
    :func:`~phri_spring.physics.friction.events.solve_event_coupled`), made once per form:
    the dof indices, each dof's stiffness rho = 1/C_ii, d rel / d(P, u) and the rows of a
    touching, stuck patch, -rho_i d rel_i / d(P, u), with the cuff's rows T^T below (each
    Newton step copies them and changes only the rows of released and sliding patches)."""

    def __init__(self, form: "InterfaceForm"):
        n, d = form.n, form.d
        N = n * d
        self.dof = np.arange(N).reshape(n, d)
        self.nrm, self.tan, self.rot = self.dof[:, 0], self.dof[:, 1:3], self.dof[:, 3:]
        self.rho = 1.0 / np.diag(form.C)
        if form.cone_normal is not None:
            # friction set by the user: one value per patch for both tangential dofs, so
            # that the projection of y = P_t + rho rel_t puts the force along the slip
            # (isotropic Coulomb friction); a value per dof puts it along the slip scaled
            # by each dof's stiffness, which the default's lift-off cone (only a smooth
            # release) keeps, its outputs as they were
            self.rho[self.tan] = self.rho[self.tan].mean(axis=1, keepdims=True)
        self.rho_n, self.rho_t = self.rho[self.nrm], self.rho[self.tan]
        self.dRel = np.hstack([-form.C, form.T])
        self.TT = np.ascontiguousarray(form.T.T)
        self.J0 = np.zeros((N + 6, N + 6))
        self.J0[:N] = -self.rho[:, None] * self.dRel
        self.J0[N:, :N] = self.TT


class ElementArrays:
    """The spring model's per-element arrays, ready for the return mapping."""

    def __init__(self, form: "InterfaceForm"):
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


def interface_form(model, like: InterfaceForm | None = None) -> InterfaceForm:
    """The compliance form of a spring model with ``friction_coefficient`` set, or of a
    linear coupled model (:func:`interface_mu`); ``like``: the form of a spring model on the
    same geometry, whose map T is taken instead of made again."""
    mu = float(interface_mu(model))
    if hasattr(model, "K_t"):        # the coupled model: already in this form
        N_out = getattr(model, "N_out", None)
        # a friction coefficient is a law a user checks against the forces written; the
        # default's lift-off cone (mu_bond) only lets a patch go smoothly, on P_n
        cone = (None if N_out is None or model.friction_coefficient is None
                else np.ascontiguousarray(N_out @ model.C_t))
        return InterfaceForm(n=model.n, d=model.dofs, C=model.C, C_skin=model.C_t, T=model.T,
                             delta=model.delta, W_pre=model.W_pre, mu=mu, diagonal=False,
                             cone_normal=cone)
    g = model.geometry
    n = g.n
    if like is not None and like.diagonal and like.n == n:
        T = like.T
    else:
        B = element_jacobians(g.points)                               # (n, 3, 6)
        T = np.stack([g.b, np.einsum("ei,eij->ej", g.meridian, B),
                      np.einsum("ei,eij->ej", g.circumferential, B)], axis=1).reshape(3 * n, 6)
    comp = np.stack([1.0 / model.k, 1.0 / model.k_shear, 1.0 / model.k_shear], axis=1).ravel()
    delta = np.zeros((n, 3))
    delta[:, 0] = model.delta0
    normal = None
    if not model.element.is_linear:
        from .normal import NormalResponse   # it builds on this module

        normal = NormalResponse(model.element)
    return InterfaceForm(n=n, d=3, C=np.diag(comp), C_skin=None, T=T, delta=delta.ravel(),
                         W_pre=model.W_pre, mu=mu, diagonal=True, normal_response=normal)


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
    memo : tuple or None
        With a nonlinear tissue law (spring model): the series elements' split at that
        solution, where the next sample's evaluations start (see
        :meth:`~phri_spring.physics.friction.normal.NormalResponse.evaluate`); None: made
        from the forces when needed.
    """

    cls: np.ndarray
    z: np.ndarray
    s: np.ndarray
    u: np.ndarray
    P: np.ndarray
    memo: tuple | None = None

    def copy(self) -> "PathState":
        # the memo's arrays are never written in place: shared
        return PathState(self.cls.copy(), self.z.copy(), self.s.copy(), self.u.copy(),
                         self.P.copy(), self.memo)


def initial_state(form: InterfaceForm) -> PathState:
    """The strap's state at zero wrench: every patch stuck where the strap put it, no slip."""
    n, d = form.n, form.d
    return PathState(cls=np.full(n, STUCK), z=np.zeros((n, d)), s=np.zeros((n, 2)),
                     u=np.zeros(6), P=np.zeros(n * d))


# --------------------------------------------------------------------------- one state
def solve_state(form: InterfaceForm, r, cls, z, s, reduce: bool = False, on_reading=None):
    """(u, P) of one wrench r (6,) in a fixed state; None if the state holds no cuff.
    ``reduce``: solve without the released patches' rows and columns (their rows say
    P_e = 0, so their columns multiply zeros): a smaller LU, the same answer.
    ``on_reading`` (n,) bool: the sliding patches whose cone is on f = cone_normal P
    rather than on P_n (see :attr:`InterfaceForm.cone_normal`)."""
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
    on = np.zeros(sl.size, dtype=bool) if on_reading is None else on_reading[sl]
    for j in (1, 2):
        rows = dof[sl, j]
        A[rows, rows] = 1.0
        # P_t = mu s P_n, or mu s f where the patch's cone is on the reading
        A[rows[~on], dof[sl[~on], 0]] = -mu * s[sl[~on], j - 1]
        if on.any():
            A[rows[on], :N] -= (mu * s[sl[on], j - 1])[:, None] * form.cone_normal[sl[on]]
    A[N:, :N] = form.T.T
    b[N:] = r
    if reduce and free.size:
        keep = np.ones(N + 6, dtype=bool)
        keep[free] = False
        x = np.zeros(N + 6)
        sub = lu_solve_or_none(A[np.ix_(keep, keep)], b[keep])
        if sub is None:
            return None
        x[keep] = sub
        return x[N:], x[:N]
    x = lu_solve_or_none(A, b)
    if x is None:
        return None
    x[free] = 0.0   # exactly: pivoting can leave round-off on the rows that say P_e = 0
    return x[N:], x[:N]


_getrf, _getrs = get_lapack_funcs(("getrf", "getrs"), dtype=np.float64)


def lu_solve_or_none(A, b):
    """A x = b by LAPACK's LU (numpy's threaded solve can stall on a busy machine at the
    coupled model's size); None for a singular A or a non-finite x. LAPACK is called
    directly: an event makes several of these small solves, and the checking wrappers of
    ``scipy.linalg.lu_factor`` cost a fair share of each (benchmarks/FRICTION.md)."""
    lu, piv, info = _getrf(A, overwrite_a=False)
    if info != 0:     # > 0: an exactly zero pivot (singular), < 0: a bad argument
        return None
    x, info = _getrs(lu, piv, b, overwrite_b=False)
    return x if info == 0 and np.all(np.isfinite(x)) else None


def relative(form: InterfaceForm, u, P):
    """Cuff-side minus skin-side motion of every dof not carried by the cuff spring,
    (T u + delta - C P) (n d,): the tie's offset a patch would need to carry P."""
    return form.T @ u + form.delta - form.C @ P


def scales(form: InterfaceForm, r):
    force = np.abs(r).max() + np.abs(form.W_pre).max() + 1e-300
    return force, force * np.abs(np.diag(form.C)).max()
