"""The exponential tissue law F = (k0 / beta)(exp(beta d) - 1): tissue that stiffens."""

from __future__ import annotations

from functools import cached_property

import numpy as np

from .base import LawParameter, TissueLaw, register_law

__all__ = ["ExponentialLaw"]


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
