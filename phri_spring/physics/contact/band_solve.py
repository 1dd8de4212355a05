"""The equilibrium of a cuff held by an elastic band strap (docs/model.md section 3.1).

The band is one more one-sided spring on the cuff: its tension T(u) = k_b (s - h . u)_+
with k_b = k / L0 [N/m], h the band's wrench on the cuff per newton (physics/cuff/band.py)
and s [m] its stretch at u = 0. For a fixed tension the cuff is the ``handles`` model with
that tension, solved by the spring solver; the tension is then the root of the scalar
g(T) = T - k_b (s - h . u(T))_+, which increases with T (a larger tension pulls the shell's
edges together and shortens the band), so it has one root and every evaluation brackets
it: T and k_b (s - h . u(T))_+ lie on either side. A safeguarded Newton step (slope
1 + k_b h^T K^-1 h, K the tangent stiffness) finds it; bisection of the bracket takes
over where Newton leaves it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from ...errors import ModelInputError
from ..cuff.band import band_path
from ..springs.model import SpringModel, field_unit
from .solution import Solution
from .solver import solve

__all__ = ["BandModel", "BandSolution", "band_model", "solve_band"]

#: most evaluations of the tension's equation per sample (each a solve of the springs)
BAND_MAX_ITERATIONS = 60


@dataclass(frozen=True, eq=False)
class BandModel(SpringModel):
    """A spring model whose strap is an elastic band (``strap.model: band``).

    Its ``W_pre`` is the band's wrench at its preload tension (the ``handles`` model's);
    :func:`solve` solves it by :func:`solve_band`.
    """

    band_h: np.ndarray = field(default=None, metadata=field_unit("[-, m]", "docs/model.md section 3.1"))
    band_k: float = field(default=0.0, metadata=field_unit("N/m", "docs/model.md section 3.1"))
    band_stretch: float = field(default=0.0, metadata=field_unit("m", "docs/model.md section 3.1"))
    band_tension: float = field(default=0.0, metadata=field_unit("N", "docs/model.md section 3.1"))
    band_width: float = field(default=0.0, metadata=field_unit("m", "docs/model.md section 3.1"))
    band_length: float = field(default=0.0, metadata=field_unit("m", "docs/model.md section 3.1"))
    band_min_radius: float = field(default=0.0, metadata=field_unit("m", "docs/model.md section 3.1"))

    def plain(self) -> SpringModel:
        """The same springs with a constant-tension strap (the band's preload tension)."""
        cached = self.__dict__.get("_plain")
        if cached is None:
            cached = SpringModel(**{f.name: getattr(self, f.name) for f in fields(SpringModel)
                                    if f.init})
            object.__setattr__(self, "_plain", cached)
        return cached

    def solve_band(self, W, max_iterations: int = 100, cache=None) -> "BandSolution":
        return solve_band(self, W, max_iterations=max_iterations, cache=cache)

    def solve_wrenches(self, W, max_iterations: int = 100):
        """``(u, forces, iterations, converged, contact)`` of :func:`solve_band` for wrenches
        (m, 6): the form of a model that solves its own samples, which the single-sample
        :class:`~phri_spring.physics.contact.solver.Solver` (``phri live``) calls."""
        sol = solve_band(self, W, max_iterations=max_iterations)
        return sol.u, sol.forces, sol.iterations, sol.converged, sol.contact

    def tangent_stiffness(self, u, contact=None) -> np.ndarray:
        """dW/du (6, 6) at displacement u (6,): the springs' tangent plus the taut band's
        k_b h h^T (its tension falls as h . u grows)."""
        K = SpringModel.tangent_stiffness(self, u, contact)
        if self.band_k > 0 and self.band_stretch - float(np.asarray(u, float) @ self.band_h) > 0:
            K = K + self.band_k * np.outer(self.band_h, self.band_h)
        return K

    def band_pressure_kpa(self, tension) -> np.ndarray:
        """The band's largest pressure on the skin it covers [kPa], T / (w rho_min)."""
        return np.asarray(tension, dtype=float) / (self.band_width * self.band_min_radius) / 1000.0


class BandSolution(Solution):
    """A :class:`Solution` with the band's tension per sample, ``strap_tension`` (m,) [N]."""

    __slots__ = ("strap_tension",)

    def __init__(self, *args, strap_tension=None, **kwargs):
        super().__init__(*args, **kwargs)
        self.strap_tension = strap_tension


def band_model(spring: SpringModel, stiffness: float, width: float, tension: float,
               handle_angles_deg=None, handle_axial_position=None) -> BandModel:
    """The band strap on a spring model built with ``strap_model='band'``.

    Parameters
    ----------
    spring : SpringModel
        Built by ``build_model(..., strap_tension=tension, strap_model='band')``.
    stiffness : float
        The band's tension per unit strain k [N] (>= 0; 0: a constant tension, the
        ``handles`` model).
    width : float
        Axial width of the band w [m] (> 0).
    tension : float
        The band's tension at zero wrench [N]; its rest length follows.
    """
    if not (np.isfinite(stiffness) and stiffness >= 0):
        raise ModelInputError(f"expected a finite tension per unit strain "
                              f">= 0 [N], got {stiffness!r}", "strap_stiffness")
    if not (np.isfinite(width) and width > 0):
        raise ModelInputError(f"expected a finite axial width > 0 [m], got "
                              f"{width!r}", "strap_width")
    if spring.friction_coefficient is not None:
        raise ModelInputError("the band strap is not available with "
                              "interface.friction_coefficient: the friction path holds a "
                              "constant strap wrench, not one that follows the cuff",
                              "friction_coefficient")
    path = band_path(spring.geometry, handle_angles_deg, handle_axial_position)
    k_b = float(stiffness) / path.length
    base = {f.name: getattr(spring, f.name) for f in fields(SpringModel) if f.init}
    base["strap_model"] = "band"
    u0 = np.zeros(6)
    if k_b > 0:   # the band's rest length: tension T at the zero-wrench equilibrium
        sol0 = solve(SpringModel(**base), np.zeros(6))
        u0 = np.asarray(sol0.u, dtype=float)
    stretch = (float(tension) / k_b if k_b > 0 else 0.0) + float(path.h @ u0)
    return BandModel(**base, band_h=path.h, band_k=k_b, band_stretch=stretch,
                     band_tension=float(tension), band_width=float(width),
                     band_length=path.length, band_min_radius=path.min_radius)


def _tangent_stiffness(model: SpringModel, u, contact) -> np.ndarray:
    """K_s + sum_{e in contact} k_e b_e b_e^T for every sample (m, 6, 6)."""
    if model.is_linear:
        k = np.broadcast_to(model.k, contact.shape)
    else:
        k = model.element.tangent(np.maximum(model.delta0 + u @ model.bT, 0.0))
    kS = np.where(contact, k, 0.0)
    return model.K_s + (kS @ model.bb).reshape(-1, 6, 6)


def solve_band(model: BandModel, wrench, *, max_iterations: int = 100,
               cache=None) -> BandSolution:
    """Solve the cuff with its band strap for every sample (m, 6) or (6,) [N, N*m]."""
    W = np.asarray(wrench, dtype=float)
    single = W.ndim == 1
    W = np.atleast_2d(W)
    plain = model.plain()
    k_b, T0 = model.band_k, model.band_tension
    m = len(W)
    if k_b == 0.0:   # a constant tension: the handles model
        sol = solve(plain, W, max_iterations=max_iterations, cache=cache)
        out = BandSolution(np.atleast_2d(sol.u), np.atleast_2d(sol.forces),
                           np.atleast_1d(sol.iterations), np.atleast_1d(sol.converged),
                           np.atleast_2d(sol.contact), strap_tension=np.full(m, T0))
    else:
        out = _solve_tension(model, plain, W, max_iterations, cache)
    if single:
        return BandSolution(out.u[0], out.forces[0], out.iterations[0], out.converged[0],
                            out.contact[0], strap_tension=out.strap_tension[0])
    return out


def _solve_tension(model, plain, W, max_iterations, cache) -> BandSolution:
    h, k_b, s, T0 = model.band_h, model.band_k, model.band_stretch, model.band_tension
    m, n = len(W), model.n
    u, forces = np.zeros((m, 6)), np.full((m, n), np.nan)
    contact, converged = np.zeros((m, n), dtype=bool), np.zeros(m, dtype=bool)
    iterations, tension = np.zeros(m, dtype=np.int64), np.full(m, np.nan)
    T = np.full(m, T0)
    lo, hi = np.zeros(m), np.full(m, np.inf)
    todo = np.arange(m)
    for _ in range(BAND_MAX_ITERATIONS):
        Tt = T[todo]
        sol = solve(plain, W[todo] + (Tt - T0)[:, None] * h, max_iterations=max_iterations,
                    cache=cache)
        iterations[todo] += sol.iterations
        ut = sol.u
        stretch = s - ut @ h
        Tb = k_b * np.maximum(stretch, 0.0)
        g = Tt - Tb
        # the springs are solved to round-off of their own (a nonlinear law's Newton
        # finish): the tension is asked for to a relative 1e-8, or until its bracket does
        # not hold two distinct answers
        tol = 1e-8 * np.maximum(np.maximum(Tt, Tb), 1.0)
        done = (np.abs(g) <= tol) | (hi[todo] - lo[todo] <= tol) | ~sol.converged
        idx = todo[done]
        u[idx], forces[idx], contact[idx] = ut[done], sol.forces[done], sol.contact[done]
        converged[idx] = sol.converged[done]
        tension[idx] = np.where(sol.converged[done], Tt[done], np.nan)
        keep = ~done
        todo, Tt, Tb, g, ut = todo[keep], Tt[keep], Tb[keep], g[keep], ut[keep]
        if not len(todo):
            break
        # T and the band's tension at u(T) bracket the root (g increases with T)
        lo[todo] = np.maximum(lo[todo], np.minimum(Tt, Tb))
        hi[todo] = np.minimum(hi[todo], np.maximum(Tt, Tb))
        K = _tangent_stiffness(plain, ut, sol.contact[keep])
        x = np.linalg.solve(K, np.broadcast_to(h, (len(todo), 6))[..., None])[..., 0]
        slope = 1.0 + k_b * (x @ h) * (stretch[keep] > 0)
        Tn = Tt - g / slope
        outside = ~((Tn >= lo[todo]) & (Tn <= hi[todo]))
        T[todo] = np.where(outside, 0.5 * (lo[todo] + hi[todo]), Tn)
    return BandSolution(u, forces, iterations, converged, contact, strap_tension=tension)
