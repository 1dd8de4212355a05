"""Tissue laws: the normal force of an element's tissue for a compression, as plug-ins.

A tissue law gives, for every element e and tissue compression d >= 0 [m], the
normal force F_e(d) [N], its tangent dF_e/dd [N/m] and the stored energy
psi_e(d) = int_0^d F_e [J]; all three are 0 for d <= 0 (the skin has left the
cuff). ``k0`` (n,) [N/m] is each element's stiffness at small compression,
F_e'(0), the ``tissue.stiffness`` of the config converted to elements. A law
must be monotone (F_e' >= 0) with a convex energy, so that the equilibrium of
the spring model stays the minimum of a convex energy (docs/model.md section 11).

In the spring model (``--arm compliant``) the law is in series with the
element's linear cuff spring k_c,e (:class:`~phri_spring.physics.laws.series.SeriesElement`): the element is a
chain bone - tissue - skin - cuff - robot whose total compression d splits into
the tissue's d_t and the cuff's f / k_c,e.

Adding a law (docs/extending.md, "Adding a tissue law"): subclass
:class:`TissueLaw`, give it a ``name``, its ``parameters`` (config keys under
``tissue.``, each with its unit and default), implement ``force``, ``tangent``
and ``energy``, and decorate it with :func:`register_law`. The config then
accepts ``tissue.law: NAME`` and the parameters' keys, and every command runs it.
A law is elastic: its force depends on the compression only. A tissue whose force
depends on its loading history (QLV relaxation, muscle activation) is any of these laws
solved in time by :class:`~phri_spring.physics.history.model.HistoryModel`.

"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...errors import ModelInputError

__all__ = ["LawParameter", "TissueLaw", "TISSUE_LAWS", "register_law"]


@dataclass(frozen=True)
class LawParameter:
    """One parameter of a tissue law, read from ``tissue.<key>`` of a config.

    Attributes
    ----------
    key : str
        Config key under ``tissue.`` (and keyword of the law's constructor).
    unit : str
        SI unit of the value.
    description : str
    default : float
        Value when the config does not give the key.
    minimum : float
        Smallest accepted value (inclusive); values must be finite.
    maximum : float
        Largest accepted value (inclusive): past it the law overflows or describes no
        tissue (a config's value above it is refused naming the key).
    csv_column : str, optional
        Column of a ``phri fit-stiffness`` CSV holding the parameter per location, so
        that the config's value may be that CSV's path.
    """

    key: str
    unit: str
    description: str
    default: float = 0.0
    minimum: float = 0.0
    csv_column: str | None = None
    maximum: float = float("inf")


#: name -> law class, every law a config can name (``tissue.law``)
TISSUE_LAWS: dict = {}


def register_law(cls):
    """Class decorator: make a :class:`TissueLaw` subclass available as ``tissue.law: name``."""
    if not (isinstance(cls, type) and issubclass(cls, TissueLaw)) or not cls.name:
        raise TypeError("register_law: expected a TissueLaw subclass with a name")
    for p in cls.parameters:
        if not isinstance(p, LawParameter) or not p.unit or not p.description:
            raise TypeError(f"tissue law {cls.name!r}: every parameter needs a LawParameter with "
                            "a unit and a description")
    TISSUE_LAWS[cls.name] = cls
    return cls


class TissueLaw:
    """Base class of the tissue laws (see the module docstring).

    Parameters
    ----------
    k0 : array_like, shape (n,)
        Stiffness of each element at small compression [N/m], > 0 and finite.
    **params
        The law's :attr:`parameters`, each a number or an (n,) array in its unit.
    """

    #: the name a config gives in ``tissue.law``
    name: ClassVar[str] = ""
    #: the law's parameters beyond ``k0`` (config keys under ``tissue.``)
    parameters: ClassVar[tuple] = ()
    #: force = k0 d: the solver then uses its exact linear path
    is_linear: ClassVar[bool] = False

    def __init__(self, k0, **params):
        k0 = np.atleast_1d(np.asarray(k0, dtype=float))
        if k0.ndim != 1 or not (np.isfinite(k0).all() and (k0 > 0).all()):
            raise ModelInputError("k0: expected finite tissue stiffnesses > 0 [N/m]", "stiffness")
        self.k0 = k0
        self.n = len(k0)
        self.params = {}
        for p in self.parameters:
            v = params.pop(p.key, p.default)
            arr = np.broadcast_to(np.asarray(v, dtype=float), (self.n,)).copy()
            if not (np.isfinite(arr).all() and (arr >= p.minimum).all()
                    and (arr <= p.maximum).all()):
                raise ModelInputError(f"{p.key}: expected finite values from {p.minimum:g} to "
                                      f"{p.maximum:g} {p.unit}", "tissue_law")
            self.params[p.key] = arr
        if params:
            raise ModelInputError(f"tissue law {self.name!r}: unknown parameter(s) "
                                  f"{', '.join(sorted(params))}", "tissue_law")

    def __repr__(self) -> str:
        return f"{type(self).__name__}(n={self.n})"

    def linear_here(self) -> bool:
        """True when the law is F = k0 d at its parameters (e.g. a zero stiffening rate)."""
        return False

    # ---- what every law implements (arrays of shape (..., n), compression d [m])
    def force(self, d: np.ndarray) -> np.ndarray:
        """Normal force F_e(d) [N], 0 where d <= 0."""
        raise NotImplementedError

    def tangent(self, d: np.ndarray) -> np.ndarray:
        """dF_e/dd [N/m] (the right derivative at d = 0, k0; 0 for d < 0)."""
        raise NotImplementedError

    def energy(self, d: np.ndarray) -> np.ndarray:
        """Stored energy psi_e(d) = int_0^d F_e [J], 0 where d <= 0."""
        raise NotImplementedError

    def force_tangent(self, d: np.ndarray):
        """(force, tangent) at compressions d >= 0 [N, N/m]; a law may override it to share
        the work of the two (the spring solver's inner loop asks for both)."""
        return self.force(d), self.tangent(d)

    # ---- derived
    def series_share(self, d, c_cuff) -> np.ndarray:
        """The tissue's compression d_t >= 0 [m] when the tissue is in series with a spring of
        compliance ``c_cuff`` (n,) [m/N] and the pair is compressed by d >= 0 (..., n):
        d = d_t + F(d_t) c_cuff. By safeguarded Newton; a law may override it in closed form.
        """
        guess = d / (1.0 + self.k0 * c_cuff)
        return _invert(lambda x: x + self.force(x) * c_cuff,
                       lambda x: 1.0 + self.tangent(x) * c_cuff, d, guess)

    def compression_at(self, f) -> np.ndarray:
        """Compression d_e >= 0 [m] at which F_e(d) = f_e [N] (f >= 0), by safeguarded Newton.

        Exact for monotone laws; a law with a closed-form inverse may override it.
        """
        f = np.asarray(f, dtype=float)
        f = np.broadcast_to(f, np.broadcast_shapes(f.shape, (self.n,)))   # (n,) or (m, n)
        return _invert(self.force, self.tangent, f, f / self.k0)


def _invert(fun, slope, target, guess, iterations: int = 100):
    """x >= 0 with fun(x) = target for increasing fun (elementwise, arrays of equal shape):
    Newton steps kept inside a bracket that bisection shrinks when a step leaves it."""
    target = np.asarray(target, dtype=float)
    x = np.maximum(np.asarray(guess, dtype=float), 0.0)
    lo = np.zeros_like(x)
    hi = np.maximum(x, 1e-12)
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(200):                       # grow the bracket until fun(hi) >= target
            short = fun(hi) < target
            if not short.any():
                break
            hi = np.where(short, 2.0 * hi, hi)
        for _ in range(iterations):
            r = fun(x) - target
            done = np.abs(r) <= 1e-13 * np.maximum(np.abs(target), 1e-300)
            if done.all():
                break
            lo = np.where(r < 0, x, lo)
            hi = np.where(r > 0, x, hi)
            s = slope(x)
            step = np.where(s > 0, x - r / np.where(s > 0, s, 1.0), 0.5 * (lo + hi))
            bad = ~np.isfinite(step) | (step <= lo) | (step >= hi)
            x = np.where(done, x, np.where(bad, 0.5 * (lo + hi), step))
    return x
