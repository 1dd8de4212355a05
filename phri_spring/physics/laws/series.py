"""A tissue law in series with each element's linear cuff spring (the spring arm's element)."""

from __future__ import annotations

import numpy as np

from .base import TissueLaw

__all__ = ["SeriesElement"]


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
