"""The linear tissue law F = k0 d: the paper's tissue spring."""

from __future__ import annotations

import numpy as np

from .base import TissueLaw, register_law

__all__ = ["LinearLaw"]


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
