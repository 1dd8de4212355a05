"""The single-sample solver for control loops (:class:`Solver`): one wrench per call,
warm-started from the call before, through the same kernel as
:func:`~phri_spring.physics.contact.solver.solve`.
"""

from __future__ import annotations

import numpy as np

from ..friction.states import interface_mu
from .active_set import FactorCache, iterate, set_keys
from .paths import HUGE, make_system, nonlinear_finish, solve_friction

__all__ = ["Solver"]


class Solver:
    """Single-sample solver for control loops, warm-started from the previous call.

    Keeps the contact set of the last call and a cache of the factorisation of
    every contact set met, so a call usually costs one 6x6 product and one
    consistency check. It runs the same kernel as :func:`solve`, on one row.

    Parameters
    ----------
    model : SpringModel or CoupledModel
    max_iterations : int
        Most linear solves per call.

    Examples
    --------
    >>> import numpy as np
    >>> from phri_spring.physics.cuff.geometry import cuff_geometry
    >>> from phri_spring.physics.springs.model import build_model
    >>> from phri_spring.physics.contact.solver import solve
    >>> model = build_model(cuff_geometry([0.0], 0.045, 0.025, 75.0, 35.0, 7), 50e3, 1e6)
    >>> solver = Solver(model)
    >>> f = solver.forces([0.0, 0.0, 20.0, 0.0, 0.0, 0.0])    # 20 N along z, cuff frame
    >>> f.shape, solver.last_converged
    ((7,), True)
    >>> bool(np.allclose(f, solve(model, [0.0, 0.0, 20.0, 0, 0, 0]).forces))
    True
    """

    def __init__(self, model, max_iterations: int = 100):
        self.model = model
        self.max_iterations = int(max_iterations)
        self.cache = FactorCache()
        self._direct = hasattr(model, "solve_wrenches")
        self._system = None if self._direct else make_system(model, self.cache)
        self._linear = model.is_linear
        self._wpre = model.W_pre
        self._S = np.ones((1, model.n), dtype=bool)
        self._keys = set_keys(self._S)
        self._q = None
        self._f_nl = None      # a nonlinear law's forces of the last call, from its iteration
        self.last_iterations = 0
        self.last_converged = True

    def displacement(self, wrench) -> np.ndarray:
        """Cuff displacement u (6,) [m, rad] for one wrench W (6,) [N, N*m] in the cuff frame."""
        if interface_mu(self.model) is not None:
            return self._friction_step(wrench)
        if self._direct:
            return self._direct_step(wrench)
        r = np.asarray(wrench, dtype=float) + self._wpre
        size = np.abs(r).max() if r.shape == (6,) else np.nan
        if not size <= HUGE and not np.isfinite(size):
            raise ValueError(f"wrench: expected 6 finite numbers, got {wrench!r}")
        if size <= HUGE:
            u, q, _, its, conv = iterate(self._system, r[None], self._S, self.max_iterations,
                                            keys=self._keys)
            ok = bool(conv[0])
        else:  # absurd but finite input: the result may overflow, which is not an answer
            with np.errstate(over="ignore", invalid="ignore"):
                u, q, _, its, conv = iterate(self._system, r[None], self._S,
                                                self.max_iterations, keys=self._keys)
                ok = bool(conv[0]) and bool(np.abs(u).max() <= HUGE)
        self._f_nl = None
        if not self._linear:
            q, self._f_nl = nonlinear_finish(self.model, r[None], u, its, conv,
                                              self.max_iterations)
            ok = ok and bool(conv[0])
        self.last_iterations, self.last_converged = int(its[0]), ok
        # the next call starts from the set read off this indicator; its key must be that
        # set's own (the kernel's keys name the set it last solved with, which can differ
        # from q > 0 at a contact on the boundary, and a key names a cached factorisation)
        S = q > 0
        if (S != self._S).any():   # the usual call keeps its set, and its key
            self._keys = set_keys(S)
        self._S, self._q = S, q
        return u[0]

    def _direct_step(self, wrench) -> np.ndarray:
        """One sample of a model that solves its samples itself (``solve_wrenches``)."""
        W = np.asarray(wrench, dtype=float)
        if W.shape != (6,) or not np.all(np.isfinite(W)):
            raise ValueError(f"wrench: expected 6 finite numbers, got {wrench!r}")
        u, f, its, conv, contact = self.model.solve_wrenches(W[None], self.max_iterations)
        self.last_iterations, self.last_converged = int(its[0]), bool(conv[0])
        self._f_nl, self._q, self._S = f, f[0], contact
        return u[0]

    def _friction_step(self, wrench) -> np.ndarray:
        """One sample of the loading path with friction, from where the last call left it."""
        W = np.asarray(wrench, dtype=float)
        if W.shape != (6,) or not np.all(np.isfinite(W)):
            raise ValueError(f"wrench: expected 6 finite numbers, got {wrench!r}")
        sol = solve_friction(self.model, W[None], False, self.cache)
        self.last_iterations = int(sol.iterations[0])
        self.last_converged = bool(sol.converged[0])
        self._q = sol.forces[0]
        self._S = sol.contact[:1]
        self.last_tangential = sol.tangential[0]
        return sol.u[0]

    @property
    def last_contact(self) -> np.ndarray:
        """The contact set (n,) bool the last call settled on (all False if it did not converge)."""
        if self._q is None:
            return np.zeros(self.model.n, dtype=bool)
        return self._S[0] & self.last_converged

    def forces(self, wrench) -> np.ndarray:
        """Normal force of every element f_e (n,) [N] for one wrench W (6,) [N, N*m].

        NaN everywhere if the solver did not converge (see ``last_converged``).
        """
        u = self.displacement(wrench)
        if interface_mu(self.model) is not None:
            return self._q.copy()
        if self._f_nl is not None:
            f = self._f_nl[0].copy()
        else:
            f = self._system.forces(self._q, u=u[None])[0]
        if not self.last_converged:
            f[:] = np.nan
        return f
