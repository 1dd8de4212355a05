"""Relaxing tissue on the coupled arm: the linear continuum layer as a QLV solid.

docs/model.md section 15.1. A linear elastic layer of one material (every modulus of every
region relaxing with the same reduced function G(t), at a fixed Poisson ratio) has its
condensed stiffness relax as its modulus does: K_t(t) = G(t) K_t. Its generalized forces on
the patches are then the hereditary integral of the elastic ones, F^e = s K_t q (q the
skin's patch motions, s the activation scale of section 15.2), exactly as a spring arm's
tissue springs (one spring per dof, all coupled through K_t). With the recursion of
:mod:`~phri_spring.physics.history.relaxation` (F^e linear between samples), a sample's
patch forces are

    P = c1 F^e + H,    c1 = G_inf + sum_i g_i b_i,    H = sum_i g_i (a_i h_i - b_i F^e_prev),

so the sample is the coupled model of section 10 with the layer stiffened by c1 s and a
memory offset: C(c1 s) = C_t / (c1 s) + C_c and the tied dofs' offset delta + C_t H / (c1 s)
(delta the strap's, kept as the resting tissue's). The interface's path (released, stuck,
sliding, and the slip) runs on as without relaxation, from sample to sample; a sample with
no answer leaves the tissue's memory to decay as if the skin had not moved. Before the
first sample the tissue has rested long at that sample's state (a = b = 0: the relaxed
layer, c1 = G_inf, H = 0).
"""

from __future__ import annotations

import numpy as np

from ...errors import ModelInputError
from ..contact.paths import friction_solution, path_wrenches
from ..contact.solution import Solution
from ..friction.form import InterfaceForm, initial_state, interface_form
from ..friction.path import solve_path
from ..friction.states import interface_mu
from .model import activation_scale, check_activation_factor, log_steps
from .path import stiffened_layer
from .relaxation import Prony, step_coefficients

__all__ = ["CoupledRelaxation", "CoupledHistoryState"]


class CoupledHistoryState:
    """What the next sample needs: the interface's path state, the memory terms h (T, N),
    the last elastic response F^e (N,) and the last sample's time (None: rested)."""

    def __init__(self, form: InterfaceForm, terms: int):
        N = form.n * form.d
        self.path = initial_state(form)
        self.h = np.zeros((terms, N))
        self.Fe = np.zeros(N)
        self.time = None

    def copy(self) -> "CoupledHistoryState":
        new = CoupledHistoryState.__new__(CoupledHistoryState)
        new.path, new.h, new.Fe, new.time = self.path.copy(), self.h.copy(), self.Fe.copy(), \
            self.time
        return new


class CoupledRelaxation:
    """The linear coupled arm with a relaxing (QLV) layer and, optionally, muscle activation.

    Parameters
    ----------
    base : CoupledModel
        The linear coupled arm (its lift-off interface or a friction coefficient).
    relaxation : Prony
        The layer's reduced relaxation function.
    activation_factor : float
        c of s = 1 + (c - 1) a [-], > 0.
    """

    has_history = True

    def __init__(self, base, relaxation: Prony, activation_factor: float = 1.0):
        if not hasattr(base, "C_t") or hasattr(base, "solve_wrenches"):
            raise ModelInputError("relaxation on the coupled arm needs its linear continuum "
                                  "layer (the hyperelastic layers' reduced models are "
                                  "elastic)", "relaxation")
        if interface_mu(base) is None:
            raise ModelInputError("relaxation on the coupled arm: expected its lift-off "
                                  "interface or a friction coefficient", "relaxation")
        self.base = base
        self.relaxation = relaxation
        self.activation_factor = check_activation_factor(activation_factor)
        self._form = interface_form(base)
        self.state = CoupledHistoryState(self._form, len(relaxation.g))

    def __getattr__(self, name):
        if name == "base":
            raise AttributeError(name)
        return getattr(self.base, name)

    def reset(self) -> None:
        """Forget the history: the next sample finds the tissue rested."""
        self.state = CoupledHistoryState(self._form, len(self.relaxation.g))

    def solve_log(self, wrench, times, activation=None, *, max_iterations: int = 100,
                  state: CoupledHistoryState | None = None, keep: bool = True) -> Solution:
        """Solve the samples of a log in order at their times [s] (a time that repeats or
        goes back: no time passing) and activations (None: 0), from the model's state."""
        st = (self.state if state is None else state).copy()
        W, t, dt = log_steps(wrench, times, st.time)
        return self._steps(W, dt, activation, st, keep, t)

    def _steps(self, W, dt, activation, st, keep, t=None) -> Solution:
        m = len(W)
        prony, f, base = self.relaxation, self._form, self.base
        g = np.asarray(prony.g, dtype=float)
        A, B = step_coefficients(prony, dt)
        s = (np.ones(m) if activation is None
             else activation_scale(np.asarray(activation, dtype=float), self.activation_factor))
        r, finite = path_wrenches(W, base.W_pre)
        N = f.n * f.d
        u = np.empty((m, 6))
        P = np.empty((m, N))
        cls = np.empty((m, f.n), dtype=np.int8)
        solves = np.empty(m, dtype=np.int64)
        conv = np.empty(m, dtype=bool)
        for k in range(m):
            c1 = float(prony.relaxed + g @ B[k])
            c = c1 * float(s[k])
            H = (g * A[k]) @ st.h - (g @ B[k]) * st.Fe
            # every sample has its own offset (the memory): its own form and factor cache
            uk, Pk, ck, sk, ok, path = solve_path(stiffened_layer(f, c, H), r[k:k + 1],
                                                  st.path, {})
            u[k], P[k], cls[k], solves[k], conv[k] = uk[0], Pk[0], ck[0], sk[0], ok[0]
            ok = bool(ok[0]) and bool(finite[k])
            Fe = (Pk[0] - H) / c1 if ok else st.Fe
            st.h = A[k][:, None] * st.h + B[k][:, None] * (Fe - st.Fe)[None, :]
            st.Fe = Fe.copy()
            st.path = path
        if t is not None and m:
            st.time = float(t[-1])
        if keep:
            self.state = st
        return friction_solution(base, u, P, cls, solves, conv & finite, single=False)

    def solve_rested(self, wrench, activation=None, *, max_iterations: int = 100) -> Solution:
        """The rows as a loading path of the relaxed layer, each after a long rest (what a
        static question asks), without touching the model's history."""
        W = np.atleast_2d(np.asarray(wrench, dtype=float))
        st = CoupledHistoryState(self._form, len(self.relaxation.g))
        return self._steps(W, np.full(len(W), np.inf), activation, st, keep=False)

    def rested_forces(self, wrench, activation: float = 0.0, *, max_iterations: int = 100):
        """Reported normal forces (n,) [N] of the layer rested long under ``wrench`` (6,)."""
        return self.solve_rested(np.atleast_2d(wrench), [activation],
                                 max_iterations=max_iterations).forces[0]
