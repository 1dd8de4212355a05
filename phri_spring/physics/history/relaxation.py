"""Reduced relaxation functions of quasi-linear viscoelastic (QLV) tissue: Prony series.

In Fung's quasi-linear viscoelasticity the force of a tissue whose elastic (instantaneous)
response to a compression history d(s) is F^e(d(s)) [N] is the hereditary integral

    F(t) = int_{-inf}^{t} G(t - s) dF^e(d(s))/ds ds,

with the reduced relaxation function, a Prony series,

    G(t) = 1 - sum_i g_i (1 - exp(-t / tau_i)),     g_i >= 0, sum_i g_i < 1, tau_i > 0 [s].

A step compression held long relaxes from F^e to G(inf) F^e = (1 - sum g_i) F^e; a constant
force creeps. Written as G(t) = G_inf + sum_i g_i exp(-t / tau_i), the integral splits into
G_inf F^e(t) + sum_i g_i h_i(t) with memory terms h_i(t) = int exp(-(t - s)/tau_i) dF^e(s).
With F^e taken linear between samples t_{n-1} and t_n (step dt), each term updates exactly by

    h_i(t_n) = a_i h_i(t_{n-1}) + b_i (F^e_n - F^e_{n-1}),
    a_i = exp(-dt / tau_i),   b_i = (tau_i / dt) (1 - a_i)   (b_i -> 1 as dt -> 0),

constant work per sample and term (:func:`step_coefficients`). A tissue that has rested long
before the first sample has h_i = 0 there, which is also what a first step dt = inf gives
(a_i = b_i = 0): the force is then G_inf F^e, the relaxed response.

References
----------
Fung, Y.C. (1993). Biomechanics: Mechanical Properties of Living Tissues, 2nd ed., ch. 7.
Zheng, Y.P., Mak, A.F.T. (1999). Extraction of quasi-linear viscoelastic parameters for lower
limb soft tissues from manual indentation experiment. J. Biomech. Eng. 121(3):330-339.

>>> import numpy as np
>>> p = Prony([0.3, 0.2], [0.5, 6.0])
>>> round(float(p.G(0.0)), 12), round(float(p.G(1e9)), 12)      # instant 1, relaxed 0.5
(1.0, 0.5)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ModelInputError

__all__ = ["Prony", "step_coefficients"]


@dataclass(frozen=True)
class Prony:
    """A Prony series G(t) = 1 - sum g_i (1 - exp(-t / tau_i)).

    Parameters
    ----------
    fractions : sequence of float
        g_i >= 0, with sum g_i < 1 (the relaxed fraction G(inf) = 1 - sum g_i stays > 0).
    times_s : sequence of float
        tau_i > 0 [s], one per fraction.
    """

    fractions: tuple
    times_s: tuple

    def __post_init__(self):
        g = np.atleast_1d(np.asarray(self.fractions, dtype=float))
        tau = np.atleast_1d(np.asarray(self.times_s, dtype=float))
        if g.ndim != 1 or tau.ndim != 1 or len(g) != len(tau):
            raise ModelInputError(f"relaxation: expected as many fractions as times_s, got "
                                  f"{g.size} and {tau.size}", "relaxation")
        if not (np.isfinite(g).all() and (g >= 0).all()):
            raise ModelInputError("relaxation.fractions: expected finite numbers >= 0",
                                  "relaxation")
        if not float(g.sum()) < 1.0:
            raise ModelInputError(f"relaxation.fractions: expected a sum < 1 (the relaxed "
                                  f"tissue keeps a stiffness), got {float(g.sum()):g}",
                                  "relaxation")
        if not (np.isfinite(tau).all() and (tau > 0).all()):
            raise ModelInputError("relaxation.times_s: expected finite times > 0 [s]",
                                  "relaxation")
        object.__setattr__(self, "fractions", tuple(float(x) for x in g))
        object.__setattr__(self, "times_s", tuple(float(x) for x in tau))

    @property
    def g(self) -> np.ndarray:
        return np.asarray(self.fractions, dtype=float)

    @property
    def tau(self) -> np.ndarray:
        return np.asarray(self.times_s, dtype=float)

    @property
    def relaxed(self) -> float:
        """G(inf) = 1 - sum g_i."""
        return 1.0 - float(self.g.sum())

    @property
    def is_elastic(self) -> bool:
        """True without relaxation (no term, or every g_i = 0): the elastic law, exactly."""
        return not bool((self.g > 0).any())

    def G(self, t) -> np.ndarray:
        """G(t) for t >= 0 [s] (array_like)."""
        t = np.asarray(t, dtype=float)
        return 1.0 - np.sum(self.g * -np.expm1(-t[..., None] / self.tau), axis=-1)


def step_coefficients(prony: Prony, dt) -> tuple[np.ndarray, np.ndarray]:
    """(a, b), each shape (m, terms), of the recursive update over sample steps dt (m,) [s].

    dt = inf (or any dt > 700 tau) gives a = b = 0 (a long rest); dt <= 0 (a repeated time
    stamp) the limit a = b = 1 (no time passes).
    """
    dt = np.asarray(dt, dtype=float)[..., None]
    tau = prony.tau
    x = np.where(dt > 0, dt / tau, 0.0)
    a = np.exp(-x)
    with np.errstate(invalid="ignore", divide="ignore"):
        b = np.where(x > 1e-8, -np.expm1(-x) / np.where(x > 1e-8, x, 1.0), 1.0 - 0.5 * x)
    b = np.where(np.isinf(x), 0.0, b)
    return a, b
