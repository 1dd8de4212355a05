"""Spring models whose tissue has a history: QLV relaxation and muscle activation.

:class:`HistoryModel` wraps a spring model (the compliant arm: tissue in series with the
cuff) and solves a log's samples in order, carrying the tissue's memory from sample to
sample and from call to call (the chunks of one stream):

* ``relaxation`` (:class:`~phri_spring.physics.history.relaxation.Prony`): the tissue's normal and
  shear springs are quasi-linear viscoelastic with the reduced relaxation function G(t) on
  top of the elastic law (linear or exponential); before the first sample the tissue has
  rested long at that sample's state (docs/model.md section 15);
* ``activation`` (a per-sample input a in 0..1): the tissue's stiffness (normal and shear)
  is scaled by s = 1 + (c - 1) a, c the activation factor (section 15.4).

Without relaxation and with a = 0 the answer is the elastic spring model's (the same
equilibrium, solved to the same residual test). Every other attribute is the wrapped
model's, so reports and extras read it as they read a spring model.

>>> import numpy as np
>>> from phri_spring.physics.cuff.geometry import cuff_geometry
>>> from phri_spring.physics.springs.model import build_model
>>> from phri_spring.physics.history.relaxation import Prony
>>> geom = cuff_geometry([0.0], 0.045, 0.025, 75.0, 35.0, 7)
>>> model = HistoryModel(build_model(geom, 50e3, 1e6, strap_tension=15.0),
...                      Prony([0.5], [2.0]))
>>> W = np.zeros((3, 6)); W[:, 1] = -40.0                 # a 40 N step held 0, 2, 20 s
>>> sol = model.solve_log(W, [0.0, 2.0, 20.0])
>>> bool(sol.converged.all())
True
"""

from __future__ import annotations

import numpy as np

from ...errors import ModelInputError
from ..cuff.geometry import element_jacobians
from .relaxation import Prony, step_coefficients
from ..contact.solution import Solution

__all__ = ["HistoryModel", "HistorySolver", "HistoryState", "activation_scale", "kernel",
           "log_steps", "check_activation_factor", "warm_up"]

_KERNEL = None
_WARMING = None


def _load():
    global _KERNEL
    from .kernel import solve_history

    # one tiny call loads (or compiles) the machine code for the argument types of a run
    n, T = 1, 1
    z = np.zeros
    solve_history(z((1, 6)), z((1, T)), z((1, T)), np.ones(1), z((n, 6)), z((n, 6, 6)),
                  z((n, 3, 6)), z((n, 2, 3)), z(n), np.ones(n), np.ones(n), z(n), z(n), False,
                  1.0, z(T), z((T, n)), z((T, n, 3)), z(n), z((n, 3)), z(6), z((1, 6)),
                  z((1, n)), z((1, n, 2)), z(1, dtype=np.int64), z(1, dtype=bool), 0, 1e-10)
    _KERNEL = solve_history


def warm_up() -> None:
    """Start loading the sample loop on a thread (numba's import and its machine code take
    a moment); the first solve waits for it. Called when a history model is made, so that
    the loading overlaps the reading of the log."""
    global _WARMING
    if _KERNEL is None and _WARMING is None:
        import threading

        _WARMING = threading.Thread(target=_load, name="phri-history-kernel", daemon=True)
        _WARMING.start()


def kernel():
    """The compiled sample loop (numba, the ``fast`` extra), else the same loop in Python."""
    if _WARMING is not None:
        _WARMING.join()
    if _KERNEL is None:
        _load()
    return _KERNEL


def activation_scale(activation, factor: float) -> np.ndarray:
    """s = 1 + (c - 1) a: the tissue stiffness's scale at activation a (0..1) [-]."""
    return 1.0 + (float(factor) - 1.0) * np.asarray(activation, dtype=float)


class HistoryState:
    """The tissue's memory after a sample: everything the next sample needs."""

    def __init__(self, terms: int, n: int):
        self.h = np.zeros((terms, n))           # memory terms of the normal springs [N]
        self.hs = np.zeros((terms, n, 3))       # ... of the shear springs [N]
        self.Fe = np.zeros(n)                   # elastic response of the last sample [N]
        self.Se = np.zeros((n, 3))
        self.u = np.zeros(6)                    # its displacement [m, rad]
        self.time = None                        # its time [s]; None: rested

    def copy(self) -> "HistoryState":
        new = HistoryState(0, 0)
        for k, v in vars(self).items():
            setattr(new, k, v.copy() if isinstance(v, np.ndarray) else v)
        return new


class HistoryModel:
    """A spring model solved sample by sample with tissue relaxation and/or activation.

    Parameters
    ----------
    base : SpringModel
        The compliant arm (a tissue law, linear or exponential, in series with the cuff).
    relaxation : Prony, optional
        The tissue's reduced relaxation function; None: elastic.
    activation_factor : float
        c of s = 1 + (c - 1) a (>= 1 stiffens with activation).

    Raises
    ------
    ModelInputError
        The rigid arm (no tissue), friction, or a tissue law other than linear/exponential.
    """

    has_history = True

    def __init__(self, base, relaxation: Prony | None = None, activation_factor: float = 1.0):
        law = getattr(getattr(base, "element", None), "law", None)
        if law is None or not hasattr(base, "geometry"):
            raise ModelInputError("relaxation and activation act on the tissue: the rigid arm "
                                  "has none (use the compliant arm)", "relaxation")
        if getattr(base, "friction_coefficient", None) is not None:
            raise ModelInputError("relaxation and activation with friction: a sliding contact "
                                  "would have to move the shear springs' memory along the skin, "
                                  "which this model does not define", "relaxation")
        if law.name not in ("linear", "exponential"):
            raise ModelInputError(f"relaxation and activation: expected the linear or exponential "
                                  f"tissue law, got {law.name!r}", "relaxation")
        self.base = base
        self.relaxation = relaxation if relaxation is not None else Prony((), ())
        self.activation_factor = check_activation_factor(activation_factor)
        n = len(base.k)
        g = base.geometry
        B = element_jacobians(g.points)                              # (n, 3, 6)
        P = np.eye(3)[None] - g.normals[:, :, None] * g.normals[:, None, :]
        self._PB = np.ascontiguousarray(P @ B)
        self._Ms = np.ascontiguousarray(np.einsum("eqj,eqk->ejk", self._PB, self._PB))
        self._b = np.ascontiguousarray(g.b, dtype=float)
        self._axes = np.ascontiguousarray(np.stack([g.meridian, g.circumferential], axis=1),
                                          dtype=float)
        self._kt = np.ascontiguousarray(law.k0, dtype=float)
        self._kc = np.ascontiguousarray(np.broadcast_to(base.element.k_cuff, (n,)), dtype=float)
        self._eta = np.ascontiguousarray(base.k_shear / base.k)
        self._beta = np.ascontiguousarray(
            np.broadcast_to(law.params.get("stiffening", 0.0), (n,)), dtype=float)
        self._law_exp = law.name == "exponential"
        self.state = HistoryState(len(self.relaxation.g), n)
        warm_up()

    def __getattr__(self, name):
        if name == "base":
            raise AttributeError(name)
        return getattr(self.base, name)

    def reset(self) -> None:
        """Forget the history: the next sample finds the tissue rested."""
        self.state = HistoryState(len(self.relaxation.g), len(self._kt))

    def solve_rested(self, wrench, activation=None, *, max_iterations: int = 100) -> Solution:
        """Every sample as held long (the tissue rested under it, relaxed), independently of
        the others and of the model's history: what a static question (an interface
        stiffness, a design's load set, a comparison's held conditions) asks."""
        W = np.atleast_2d(np.asarray(wrench, dtype=float))
        W, _, _ = log_steps(W, np.zeros(len(W)))
        fresh = HistoryState(len(self.relaxation.g), len(self._kt))
        # an infinite step before every sample forgets all history (a = b = 0)
        return _solve_steps(self, W, np.full(len(W), np.inf), activation, fresh,
                            max_iterations)

    def solve_log(self, wrench, times, activation=None, *, max_iterations: int = 100,
                  state: HistoryState | None = None, keep: bool = True) -> Solution:
        """Solve the samples of a log in order, from the model's state (or ``state``).

        Parameters
        ----------
        wrench : array_like, shape (m, 6)
            Wrench on the cuff, cuff frame [N, N*m] (the strap's is added).
        times : array_like, shape (m,)
            Sample times [s]. A time that repeats or goes back (a glitch of the logger) is
            taken as no time passing (dt = 0), as the elastic model and the tolerance dose
            take it.
        activation : array_like, shape (m,), optional
            Muscle activation a in [0, 1]; None: 0.
        state : HistoryState, optional
            Start from this state instead of the model's.
        keep : bool
            Keep the state after the last sample as the model's (the next call continues).
        """
        st = (self.state if state is None else state).copy()
        W, t, dt = log_steps(wrench, times, st.time)
        sol = _solve_steps(self, W, dt, activation, st, max_iterations)
        st.time = float(t[-1]) if len(W) else st.time
        if keep:
            self.state = st
        return sol

    def rested_forces(self, wrench, activation: float = 0.0, *, max_iterations: int = 100):
        """Forces (n,) [N] of the tissue rested long under ``wrench`` (6,), without touching
        the model's history: the relaxed answer (a baseline of a log)."""
        return self.solve_rested(np.atleast_2d(wrench), [activation],
                                 max_iterations=max_iterations).forces[0]


def log_steps(wrench, times, last_time: float | None = None):
    """``(W (m, 6), t (m,), dt (m,))`` of a log: wrenches and times as arrays of finite
    numbers (else a ValueError), and each sample's step from the one before [s], the first
    from ``last_time`` (None: rested, an infinite step); a time that repeats or goes back
    is no time passing (dt = 0)."""
    W = np.atleast_2d(np.asarray(wrench, dtype=float))
    t = np.atleast_1d(np.asarray(times, dtype=float))
    m = len(W)
    if W.shape != (m, 6) or t.shape != (m,):
        raise ValueError(f"wrench and times: expected shapes (m, 6) and (m,), got "
                         f"{W.shape} and {t.shape}")
    if not (np.isfinite(W).all() and np.isfinite(t).all()):
        raise ValueError("wrench and times: expected finite numbers")
    dt = np.empty(m)
    if m:
        dt[0] = np.inf if last_time is None else t[0] - last_time
        dt[1:] = np.diff(t)
    return W, t, np.maximum(dt, 0.0)


def check_activation_factor(factor) -> float:
    """c of s = 1 + (c - 1) a as a float, or a ModelInputError unless finite and > 0."""
    if not (np.isfinite(factor) and factor > 0):
        raise ModelInputError("activation_factor: expected a finite number > 0",
                              "activation_factor")
    return float(factor)


def _solve_steps(model: HistoryModel, wrench, dt, activation, state: HistoryState,
                max_iterations: int = 100) -> Solution:
    """Solve wrenches (m, 6) in order, each after a step dt (m,) [s] from the one before
    (the first from ``state``'s last sample): the sample loop of
    :meth:`HistoryModel.solve_log` (dt from the sample times) and
    :meth:`HistoryModel.solve_rested` (dt infinite: every sample after a long rest).

    A step <= 0 is no time passing; ``state`` (its memory terms and displacements) is
    advanced in place, its ``time`` left to the caller.
    """
    W = np.asarray(wrench, dtype=float)
    m, n = len(W), len(model._kt)
    dt = np.maximum(np.asarray(dt, dtype=float), 0.0)
    A, Bc = step_coefficients(model.relaxation, dt)
    s = (np.ones(m) if activation is None
         else activation_scale(np.asarray(activation, dtype=float), model.activation_factor))
    if not np.any(model.relaxation.g) and np.all(s == 1.0):
        return _elastic_steps(model, W, st_=state, max_iterations=max_iterations)
    with np.errstate(over="ignore", invalid="ignore"):
        r = W + model.base.W_pre
    u = np.empty((m, 6))
    f = np.empty((m, n))
    tangential = np.empty((m, n, 2))
    its = np.zeros(m, dtype=np.int64)
    conv = np.zeros(m, dtype=bool)
    st = state
    kernel()(np.ascontiguousarray(r), np.ascontiguousarray(A), np.ascontiguousarray(Bc),
             np.ascontiguousarray(s), model._b, model._Ms, model._PB, model._axes,
             np.ascontiguousarray(model.base.delta0, dtype=float), model._kt, model._kc,
             model._eta, model._beta, model._law_exp, float(model.relaxation.relaxed),
             np.ascontiguousarray(model.relaxation.g), st.h, st.hs, st.Fe, st.Se, st.u,
             u, f, tangential, its, conv, int(max_iterations), 1e-10)
    contact = f > 0
    if not conv.all():
        f[~conv] = np.nan
        contact[~conv] = False
    return Solution(u=u, forces=f, iterations=its, converged=conv, contact=contact,
                    tangential=tangential)


def _elastic_steps(model: HistoryModel, W, st_: HistoryState, max_iterations: int) -> Solution:
    """Samples without relaxation and without activation: the elastic spring model's own
    solve (the tissue has no memory to carry), its answer exactly; ``st_`` is left where a
    sample solved by the loop would leave it (the last converged displacement and elastic
    response) so that a later sample with relaxation or activation continues from it."""
    from ..contact.solver import solve

    base = model.base
    sol = solve(base, W, max_iterations=max_iterations)
    tangential = np.asarray(base.shear_components(sol.u, sol.contact), dtype=float)
    ok = np.flatnonzero(sol.converged)
    if ok.size:
        last = ok[-1]
        st_.u[:] = sol.u[last]
        st_.Fe[:] = sol.forces[last]
        st_.Se[:] = 0.0
    if not sol.converged.all():
        tangential[~sol.converged] = np.nan
    return Solution(u=sol.u, forces=sol.forces, iterations=sol.iterations,
                    converged=sol.converged, contact=sol.contact, tangential=tangential)


class HistorySolver:
    """One sample at a time, in order (``phri live``): the interface of
    :class:`~phri_spring.physics.contact.solver.Solver` for a :class:`HistoryModel`, whose
    ``forces`` also takes the sample's time [s] and activation."""

    def __init__(self, model: HistoryModel, max_iterations: int = 100):
        self.model = model
        self.max_iterations = int(max_iterations)
        self.last_iterations = 0
        self.last_converged = True
        self.last_contact = np.zeros(model.n, dtype=bool)
        self.last_tangential = None

    def forces(self, wrench, time: float = 0.0, activation: float | None = None) -> np.ndarray:
        """Normal force f_e (n,) [N] of the next sample (NaN if not converged)."""
        W = np.asarray(wrench, dtype=float)
        if W.shape != (6,) or not np.all(np.isfinite(W)):
            raise ValueError(f"wrench: expected 6 finite numbers, got {wrench!r}")
        sol = self.model.solve_log(W[None], [float(time)],
                                   None if activation is None else [activation],
                                   max_iterations=self.max_iterations)
        self.last_iterations = int(sol.iterations[0])
        self.last_converged = bool(sol.converged[0])
        self.last_contact = sol.contact[0]
        self.last_tangential = sol.tangential[0]
        return sol.forces[0]
