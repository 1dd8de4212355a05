"""Tissue laws: the normal force of an element's tissue for a compression, as plug-ins.

A tissue law gives, for every element e and tissue compression d >= 0 [m], the
normal force F_e(d) [N], its tangent dF_e/dd [N/m] and the stored energy
psi_e(d) = int_0^d F_e [J]; all three are 0 for d <= 0 (the skin has left the
cuff). ``k0`` (n,) [N/m] is each element's stiffness at small compression,
F_e'(0), the ``tissue.stiffness`` of the config converted to elements. A law
must be monotone (F_e' >= 0) with a convex energy, so that the equilibrium of
the spring model stays the minimum of a convex energy (docs/model.md section 11).

In the spring model (``--arm compliant``) the law is in series with the
element's linear cuff spring k_c,e (:class:`SeriesElement`): the element is a
chain bone - tissue - skin - cuff - robot whose total compression d splits into
the tissue's d_t and the cuff's f / k_c,e.

Adding a law (docs/model.md, "Adding a tissue law"): subclass
:class:`TissueLaw`, give it a ``name``, its ``parameters`` (config keys under
``tissue.``, each with its unit and default), implement ``force``, ``tangent``
and ``energy``, and decorate it with :func:`register_law`. The config then
accepts ``tissue.law: NAME`` and the parameters' keys, and every command runs it.
A law whose force depends on the loading history (viscoelastic, plastic) sets
``has_state`` and implements :meth:`TissueLaw.initial_state` and
:meth:`TissueLaw.advance`; the solver then solves the samples in order and
carries the state from sample to sample and from chunk to chunk.

>>> import numpy as np
>>> law = make_law("linear", k0=[1000.0, 2000.0])
>>> law.force(np.array([0.002, -0.001]))             # N: 1000 N/m x 2 mm; lifted: 0
array([2., 0.])
>>> {"linear", "exponential"} <= set(TISSUE_LAWS)
True
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar

import numpy as np

from ..errors import ModelInputError

__all__ = ["LawParameter", "TissueLaw", "LinearLaw", "SeriesElement", "TISSUE_LAWS",
           "register_law", "make_law"]


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


def make_law(name, k0, **params) -> "TissueLaw":
    """The law ``name`` (a registered name, or a :class:`TissueLaw` subclass) with initial
    stiffness ``k0`` (n,) [N/m] and its parameters."""
    if isinstance(name, type) and issubclass(name, TissueLaw):
        cls = name
    else:
        try:
            cls = TISSUE_LAWS[name]
        except KeyError:
            raise ValueError(f"tissue law: expected one of {', '.join(sorted(TISSUE_LAWS))}, "
                             f"got {name!r}") from None
    law = cls(k0, **params)
    # a law that is linear at these parameters is solved as the linear law, exactly
    return LinearLaw(law.k0) if law.linear_here() else law


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
    #: the force depends on the loading history (samples are solved in order)
    has_state: ClassVar[bool] = False
    #: for a law with history: the state the force is evaluated in, set by the solver to
    #: the state the previous sample left (:meth:`initial_state` before the first)
    state = None

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

    # ---- history (laws with has_state only)
    def initial_state(self):
        """The state before the first sample (None for a law without history)."""
        return None

    def advance(self, state, d: np.ndarray):
        """The state after a sample settled at compression d (n,); stateless laws keep it."""
        return state

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


@register_law
class LinearLaw(TissueLaw):
    """F(d) = k0 d for d > 0: the paper's linear tissue spring (docs/model.md section 2)."""

    name = "linear"
    is_linear = True

    def force(self, d):
        return self.k0 * np.maximum(d, 0.0)

    def tangent(self, d):
        return np.where(np.asarray(d) >= 0.0, self.k0, 0.0)

    def energy(self, d):
        dp = np.maximum(d, 0.0)
        return 0.5 * self.k0 * dp * dp

    def series_share(self, d, c_cuff):
        return d / (1.0 + self.k0 * c_cuff)

    def compression_at(self, f):
        return np.asarray(f, dtype=float) / self.k0


@register_law
class ExponentialLaw(TissueLaw):
    """F(d) = (k0 / beta) (exp(beta d) - 1) for d > 0: tissue that stiffens with compression.

    k0 [N/m] is the slope at d = 0 and beta [1/m] the stiffening rate: the tangent
    k0 exp(beta d) grows by e every 1/beta of compression. beta = 0 is the linear law
    (exactly: :func:`make_law` then returns it). Exponential (Fung-type) laws describe
    the force-indentation curves of soft tissue and whole interfaces (docs/model.md
    section 11.3).
    """

    name = "exponential"
    parameters = (LawParameter("stiffening", "1/m", "stiffening rate beta of "
                               "F = (k0/beta)(exp(beta d) - 1)", default=0.0, minimum=0.0,
                               csv_column="stiffening_per_m",
                               # 1/beta >= 0.1 mm: soft tissue's fits are about 50-200 1/m
                               # (docs/model.md 11.3); far past them exp(beta d) overflows
                               # at displacements of centimetres
                               maximum=1.0e4),)

    def linear_here(self) -> bool:
        return bool(np.all(self.params["stiffening"] == 0.0))

    def _x(self, d):
        return self.params["stiffening"] * np.maximum(d, 0.0)

    def force(self, d):
        beta = self.params["stiffening"]
        dp = np.maximum(d, 0.0)
        x = beta * dp
        # expm1(x) / beta without dividing by a zero beta: dp * expm1(x) / x, -> dp as x -> 0
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            ratio = np.where(x > 0, np.expm1(x) / np.where(x > 0, x, 1.0), 1.0)
        return self.k0 * dp * ratio

    def tangent(self, d):
        d = np.asarray(d, dtype=float)
        with np.errstate(over="ignore"):
            return np.where(d >= 0.0, self.k0 * np.exp(self._x(d)), 0.0)

    #: stiffening rate [1/m] from which :meth:`force_tangent` takes exp(x) - 1 for expm1(x)
    _EXP_BETA = 1.0

    @cached_property
    def _k0_over_beta(self):
        """k0 / beta where every element stiffens at >= _EXP_BETA, else None."""
        beta = self.params["stiffening"]
        return self.k0 / beta if bool(np.all(beta >= self._EXP_BETA)) else None

    def force_tangent(self, d):
        # one exponential for both: F = (k0/beta) expm1(x), F' = k0 (1 + expm1(x)); d >= 0
        beta = self.params["stiffening"]
        if self._k0_over_beta is not None:
            # exp is cheaper than expm1; exp(x) - 1 loses up to one rounding of exp(x),
            # F' eps / beta <= F' * 2.2e-16 m for beta >= 1 1/m: a force of a compression
            # far below anything the solver resolves (its tolerance is 1e-10 of the forces)
            E = np.exp(beta * d)
            Ft = self.k0 * E
            E -= 1.0
            E *= self._k0_over_beta
            return E, Ft
        em = np.expm1(beta * d)
        stiffens = beta > 0
        if stiffens.all():
            F = self.k0 / beta * em
        else:   # elements with beta = 0 are linear: k0 d
            F = np.where(stiffens, self.k0 / np.where(stiffens, beta, 1.0) * em, self.k0 * d)
        return F, self.k0 * (1.0 + em)

    def energy(self, d):
        # psi = k0 (expm1(x) - x) / beta^2 = k0 dp^2 (expm1(x) - x) / x^2; a series where x is
        # small, as the difference cancels there
        beta = self.params["stiffening"]
        dp = np.maximum(d, 0.0)
        x = beta * dp
        small = x < 1e-3
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            xs = np.where(small, 1.0, x)
            g = np.where(small, 0.5 + x / 6.0 + x * x / 24.0 + x ** 3 / 120.0,
                         (np.expm1(xs) - xs) / (xs * xs))
        return self.k0 * dp * dp * g

    def series_share(self, d, c_cuff):
        # d + a = d_t + a exp(beta d_t) with a = k0 c / beta has the closed form
        # d_t = d + a - omega(ln(a beta) + beta (d + a)) / beta (omega: Wright's omega,
        # W(exp(z)) without overflow). Where beta d is tiny that difference cancels, and the
        # second-order expansion in beta d is exact to round-off instead. Two Newton steps on
        # d_t + F(d_t) c = d then remove what round-off is left.
        from scipy.special import wrightomega

        beta = self.params["stiffening"]
        d = np.maximum(np.asarray(d, dtype=float), 0.0)
        c = np.broadcast_to(np.asarray(c_cuff, dtype=float), (self.n,))
        k0c = self.k0 * c
        lin = d / (1.0 + k0c)
        dt = lin - 0.5 * k0c * beta * lin * lin / (1.0 + k0c)
        big = (beta * d >= 1e-6) & (c > 0)
        if big.any():
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                bs = np.where(beta > 0, beta, 1.0)
                a = k0c / bs
                z = np.log(np.where(a > 0, a * bs, 1.0)) + bs * (d + a)
                closed = d + a - wrightomega(z) / bs
            dt = np.where(big & np.isfinite(closed), closed, dt)
        with np.errstate(over="ignore", invalid="ignore"):
            for _ in range(2):
                dt = np.clip(dt, 0.0, d)
                g = dt + self.force(dt) * c - d
                dt = dt - g / (1.0 + self.tangent(dt) * c)
            dt = np.clip(dt, 0.0, d)
        if not np.isfinite(dt).all():      # overflow of exp(beta d): the general inversion
            return super().series_share(d, c_cuff)
        return dt

    def compression_at(self, f):
        beta = self.params["stiffening"]
        f = np.asarray(f, dtype=float)
        y = beta * f / self.k0
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.where(y > 0, np.log1p(y) / np.where(y > 0, y, 1.0), 1.0)
        return f / self.k0 * ratio


class SeriesElement:
    """A tissue law in series with a linear cuff spring k_c (n,) [N/m] (inf: a rigid cuff).

    For a total compression d of the element the tissue takes d_t with
    d = d_t + F(d_t) / k_c; the element's force is f = F(d_t), its tangent
    1 / (1/F'(d_t) + 1/k_c) and its energy psi_t(d_t) + f^2 / (2 k_c). With the
    linear law this is the spring k = 1 / (1/k0 + 1/k_c) of the paper.

    Parameters
    ----------
    law : TissueLaw, or None for the cuff spring alone (the rigid arm)
    k_cuff : array_like, shape (n,)
    """

    def __init__(self, law: TissueLaw | None, k_cuff):
        self.law = law
        self.k_cuff = np.asarray(k_cuff, dtype=float)
        with np.errstate(divide="ignore"):
            self._c_cuff = 1.0 / self.k_cuff                  # 0 for a rigid cuff

    @property
    def is_linear(self) -> bool:
        return self.law is None or self.law.is_linear

    def tissue_compression(self, d) -> np.ndarray:
        """The tissue's share d_t of total compressions d (..., n) [m] (0 where d <= 0)."""
        d = np.asarray(d, dtype=float)
        dp = np.maximum(d, 0.0)
        law = self.law
        if law is None:
            return np.zeros_like(dp)
        return law.series_share(dp, self._c_cuff)

    def from_share(self, dt):
        """(force [N], energy [J]) of the elements from the tissue's share d_t (a tissue law)."""
        f = self.law.force(dt)
        return f, self.law.energy(dt) + 0.5 * f * f * self._c_cuff

    def _with_cuff(self, kt):
        """The tissue's tangent kt [N/m] in series with the cuff spring (0 where kt is 0)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(kt > 0, 1.0 / (1.0 / np.where(kt > 0, kt, 1.0) + self._c_cuff), 0.0)

    def tangent_from_share(self, dt):
        """df/dd [N/m] from the tissue's share d_t (0 where the element is open)."""
        return np.where(dt > 0.0, self._with_cuff(self.law.tangent(dt)), 0.0)

    def force(self, d) -> np.ndarray:
        """Element force f [N] at total compressions d (..., n)."""
        if self.law is None:
            return self.k_cuff * np.maximum(d, 0.0)
        return self.law.force(self.tissue_compression(d))

    def tangent(self, d) -> np.ndarray:
        """df/dd [N/m] at total compressions d (0 where d < 0)."""
        d = np.asarray(d, dtype=float)
        if self.law is None:
            return np.where(d >= 0.0, self.k_cuff, 0.0)
        kt = self.law.tangent(self.tissue_compression(d))
        return np.where(d >= 0.0, self._with_cuff(kt), 0.0)

    def energy(self, d) -> np.ndarray:
        """Stored energy of the element [J] at total compressions d."""
        if self.law is None:
            dp = np.maximum(d, 0.0)
            return 0.5 * self.k_cuff * dp * dp
        return self.from_share(self.tissue_compression(d))[1]

    def compression_at(self, f) -> np.ndarray:
        """Total compression [m] at which the element carries f [N] (f >= 0)."""
        f = np.asarray(f, dtype=float)
        if self.law is None:
            return f / self.k_cuff
        return self.law.compression_at(f) + f * self._c_cuff
