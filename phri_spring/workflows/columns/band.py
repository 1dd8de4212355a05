"""The ``strap.model: band`` columns of ``phri simulate`` (docs/model.md section 3.1).

Per sample: the band's tension [N] and the largest pressure it puts on the skin it covers,
by Laplace's law [kPa]; NaN where the sample did not converge.
"""

from __future__ import annotations

import numpy as np

__all__ = ["BAND_COLUMN_TYPES", "has_band", "band_extras", "largest_tension"]

#: the band's columns, after the others, with their types
BAND_COLUMN_TYPES = (("strap_tension_N", "float64"), ("strap_pressure_kPa", "float64"))


def has_band(model) -> bool:
    """Whether the model's strap is an elastic band (its tension is an output)."""
    return hasattr(model, "solve_band")


def band_extras(model, sol) -> dict:
    """``strap_tension_N`` (m,) [N] and ``strap_pressure_kPa`` (m,) of a band model's
    solution; an empty dict for any other model."""
    if not has_band(model):
        return {}
    tension = np.array(np.atleast_1d(sol.strap_tension), dtype=float)
    tension[~np.atleast_1d(np.asarray(sol.converged, dtype=bool))] = np.nan
    return {"strap_tension_N": tension,
            "strap_pressure_kPa": model.band_pressure_kpa(tension)}


def largest_tension(sol) -> float:
    """The largest converged band tension of a solution [N] (NaN without one)."""
    t = getattr(sol, "strap_tension", None)
    if t is None:
        return float("nan")
    t = np.where(np.atleast_1d(sol.converged), np.atleast_1d(t), np.nan)
    return float(np.nanmax(t)) if np.isfinite(t).any() else float("nan")
