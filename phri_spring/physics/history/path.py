"""Muscle activation along a loading path: the coupled arm's continuum layer, and the spring
arms with friction, stiffened sample by sample.

docs/model.md section 15.2. A linear elastic layer whose moduli (Young's modulus, at a fixed
Poisson ratio) are scaled by s has every stiffness scaled by s: its condensed stiffness
K_t becomes s K_t, its compliance C_t / s, and the traction values a patch's reading sums
(docs/model.md section 10.6, linear in the moduli too) s times theirs. With the activation a
of a sample,
s = 1 + (c - 1) a (:func:`~phri_spring.physics.history.model.activation_scale`), so each
sample is the coupled model of section 10 with

    C(s) = C_t / s + C_c,     delta unchanged,

C_c the cuff's compliance (unchanged: activation stiffens the tissue, not the cuff) and
delta the strap's preload offset, a displacement: the strap was tightened on the resting
muscle, and contracting it under the strap presses the skin harder, as on the spring arms
(section 15.2; with the handles strap the preload is a wrench, delta = 0). What a patch
reads does not depend on s for given patch forces. The interface's
path state (which patches are released, stuck or sliding, and their slip) is carried from
sample to sample as it is without activation: a change of stiffness moves the skin under
a stuck patch, not the patch's tie. Consecutive samples with the same activation share
one compliance form and are solved together.

The spring arms with ``interface.friction_coefficient`` run along the same path solver
(section 12); their tissue springs stiffened by s are those of the spring model built with
the tissue stiffness s k_t: the tissue's compliance 1/(s k0) normal and 1/(eta s k0)
tangential in series with the unchanged cuff's, a nonlinear law rebuilt with s k0 and its
other parameters (the exponential law's rate) kept, so that every tissue force is s times
the unactivated one; their preload compressions are kept as the unactivated model's. The
rigid arm has no tissue: activation leaves it as it is.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...errors import ModelInputError
from ..contact.paths import friction_solution, path_wrenches
from ..contact.solution import Solution
from ..friction.form import InterfaceForm, initial_state, interface_form
from ..friction.normal import NormalResponse
from ..laws.series import SeriesElement
from ..friction.states import interface_mu
from ..friction.path import solve_path
from .model import activation_scale, check_activation_factor

__all__ = ["PathActivation", "stiffened_layer"]

#: compliance forms kept per activation scale (a log with a few activation levels reuses
#: them; a continuous channel makes one per sample and keeps the last few)
_FORMS = 32


def stiffened_layer(form: InterfaceForm, scale: float, offset=None) -> InterfaceForm:
    """The coupled model's compliance form (:func:`interface_form`) with its tissue layer
    stiffened by ``scale`` (C_t / scale; the cuff's compliance C - C_t unchanged) and, with
    ``offset`` (n d,) [N, N*m], tissue forces P = scale K_t q + offset: the tied dofs'
    offset becomes delta + C_t offset / scale."""
    C_skin = form.C_skin / scale
    C = C_skin + (form.C - form.C_skin)
    delta = form.delta if offset is None else form.delta + C_skin @ offset
    return InterfaceForm(n=form.n, d=form.d, C=C, C_skin=C_skin, T=form.T, delta=delta,
                         W_pre=form.W_pre, mu=form.mu, diagonal=False,
                         # the reading maps forces to tractions: a uniformly stiffened layer
                         # moves less under the same forces with the same tractions
                         cone_normal=form.cone_normal)


def _spring_split(model):
    """(tissue, cuff) (3n,): the diagonal compliance of a spring model's form split into
    its tissue springs' part at small compression (1/k0 normal, 1/(eta k0) tangential) and
    its cuff springs' (1/k_c, 1/(eta k_c); 0 for a rigid cuff); None for the rigid arm (no
    tissue)."""
    law = model.element.law
    if law is None or model.arm != "compliant":
        return None
    eta = model.k_shear / model.k
    with np.errstate(divide="ignore"):
        c = 1.0 / model.element.k_cuff
    t = 1.0 / law.k0
    return (np.stack([t, t / eta, t / eta], axis=1).ravel(),
            np.stack([c, c / eta, c / eta], axis=1).ravel())


class PathActivation:
    """A model solved along its interface's loading path, its tissue stiffened by a
    per-sample activation.

    Parameters
    ----------
    base : CoupledModel or SpringModel
        The linear coupled arm (docs/model.md section 10), hoop or handles strap, with or
        without ``friction_coefficient``; or a spring arm with ``friction_coefficient``.
    activation_factor : float
        c of s = 1 + (c - 1) a [-], > 0.

    Raises
    ------
    ModelInputError
        A model that is not the linear coupled arm, or a factor that is not a finite
        number > 0.
    """

    has_history = True

    def __init__(self, base, activation_factor: float = 1.0):
        spring = hasattr(base, "element")
        if not spring and (not hasattr(base, "C_t") or hasattr(base, "solve_wrenches")):
            raise ModelInputError("activation on the coupled arm needs its linear continuum "
                                  "layer (the hyperelastic layers' reduced models are built "
                                  "for one modulus)", "activation_factor")
        activation_factor = check_activation_factor(activation_factor)
        if interface_mu(base) is None:
            raise ModelInputError("activation along a loading path: expected the coupled "
                                  "arm's lift-off interface or a friction coefficient (bonded "
                                  "ties everywhere is a legacy mode)", "activation_factor")
        self.base = base
        self.activation_factor = activation_factor
        self._spring = spring
        self._form = interface_form(base)
        self._split = _spring_split(base) if spring else None
        self._forms: dict[float, tuple[InterfaceForm, dict]] = {}
        self.state = None

    def __getattr__(self, name):
        if name == "base":
            raise AttributeError(name)
        return getattr(self.base, name)

    def reset(self) -> None:
        """Back to the strap's state at zero wrench."""
        self.state = None

    def form(self, s: float) -> tuple[InterfaceForm, dict]:
        """The compliance form of the layer stiffened by ``s`` and its factor cache."""
        hit = self._forms.get(s)
        if hit is None:
            f = self._form
            if s == 1.0 or (self._spring and self._split is None):
                form = f
            elif self._spring:
                # the tissue springs' compliance over s, the cuff's as it is, a nonlinear
                # law with s k0, on the unactivated preload compressions (the form of the
                # model built with s k_t, without building it per sample)
                tissue, cuff = self._split
                normal = None
                if f.normal_response is not None:
                    element = self.base.element
                    law = element.law
                    normal = NormalResponse(SeriesElement(type(law)(law.k0 * s, **law.params),
                                                          element.k_cuff))
                form = replace(f, C=np.diag(tissue / s + cuff), normal_response=normal)
            else:
                form = stiffened_layer(f, s)
            if len(self._forms) >= _FORMS:
                self._forms.pop(next(iter(self._forms)))
            hit = self._forms[s] = (form, {})
        return hit

    def solve_log(self, wrench, times=None, activation=None, *, max_iterations: int = 100,
                  state=None, keep: bool = True) -> Solution:
        """Solve the samples of a log in order with their activations (None: 0).

        ``times`` is accepted for the interface of
        :class:`~phri_spring.physics.history.model.HistoryModel` and not used: the
        elastic layer has no memory of time, only the interface's path.
        """
        W = np.atleast_2d(np.asarray(wrench, dtype=float))
        m = len(W)
        if W.shape != (m, 6) or not np.isfinite(W).all():
            raise ValueError(f"wrench: expected finite numbers of shape (m, 6), got {W.shape}")
        s = (np.ones(m) if activation is None
             else activation_scale(np.asarray(activation, dtype=float), self.activation_factor))
        if s.shape != (m,) or not (np.isfinite(s).all() and (s > 0).all()):
            raise ValueError(f"activation: expected {m} values giving a scale > 0")
        st = self.state if state is None else state
        st = initial_state(self._form) if st is None else st
        r, finite = path_wrenches(W, self.base.W_pre)
        n, d = self._form.n, self._form.d
        u = np.empty((m, 6))
        P = np.empty((m, n * d))
        cls = np.empty((m, n), dtype=np.int8)
        solves = np.empty(m, dtype=np.int64)
        conv = np.empty(m, dtype=bool)
        # runs of equal activation: one form, one call along the path
        edges = np.flatnonzero(np.diff(s)) + 1
        for i, e in zip(np.r_[0, edges], np.r_[edges, m]):
            form, cache = self.form(float(s[i]))
            u[i:e], P[i:e], cls[i:e], solves[i:e], conv[i:e], st = solve_path(
                form, r[i:e], st, cache)
        if keep:
            self.state = st
        return friction_solution(self.base, u, P, cls, solves, conv & finite, single=False)

    def solve_rested(self, wrench, activation=None, *, max_iterations: int = 100) -> Solution:
        """The rows as a loading path from the strap's state at zero wrench (what the coupled
        arm answers for a static question), without touching the model's path state."""
        return self.solve_log(wrench, None, activation, max_iterations=max_iterations,
                              state=initial_state(self._form), keep=False)

    def rested_forces(self, wrench, activation: float = 0.0, *, max_iterations: int = 100):
        """Reported normal forces (n,) [N] under ``wrench`` (6,) from the strap's state."""
        return self.solve_rested(np.atleast_2d(wrench), [activation],
                                 max_iterations=max_iterations).forces[0]
