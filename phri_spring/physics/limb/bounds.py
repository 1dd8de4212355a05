"""What a limb's shape may be: the bounds of its size and taper (docs/model.md section 13).

Kept apart from :mod:`~phri_spring.physics.limb.sections` (which re-exports them) so that a
config with the circular default checks its radius and taper without loading the outline
maths.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["SectionError", "RHO_RANGE_M", "MIN_OUTLINE_POINTS", "TAPER_LIMIT_DEG",
           "check_taper", "check_rho_range"]

#: distance of a limb's skin from its axis we accept [m]: a child's wrist is about
#: 0.02 m, a large thigh about 0.15 m (a 45 m "limb" is a unit mistake)
RHO_RANGE_M = (0.005, 0.3)
#: fewest points of an outline (a cubic spline through fewer hardly describes a limb)
MIN_OUTLINE_POINTS = 8
#: largest ``|taper half-angle|`` we accept [deg]: limb segments taper by 2-9 deg; beyond
#: 30 deg a cuff would slide off the cone, and the element areas grow as 1/cos(alpha)
TAPER_LIMIT_DEG = 30.0


class SectionError(ValueError):
    """A section's parameters do not describe a limb outline (one-line message)."""


def check_rho_range(rho_min: float, rho_max: float, what: str) -> None:
    """SectionError unless distances from the axis rho_min..rho_max [m] are a limb's."""
    lo, hi = RHO_RANGE_M
    if not (np.isfinite(rho_min) and np.isfinite(rho_max)):
        raise SectionError(f"{what}: expected finite numbers [m]")
    if rho_min < lo or rho_max > hi:
        got = rho_max if rho_max > hi else rho_min
        hint = " (metres expected: in mm?)" if rho_max > hi and rho_max > 1.0 else ""
        raise SectionError(f"{what}: expected distances from the arm axis between {lo:g} and "
                           f"{hi:g} m (a limb), got {got:g} m{hint}")


def check_taper(alpha_deg) -> float:
    """The taper half-angle [deg] as a float, or SectionError outside the accepted range."""
    try:
        a = float(alpha_deg)
    except (TypeError, ValueError):
        raise SectionError(f"expected a number [deg], got {alpha_deg!r}") from None
    if not math.isfinite(a) or abs(a) > TAPER_LIMIT_DEG:
        raise SectionError(f"expected a half-angle between -{TAPER_LIMIT_DEG:g} and "
                           f"{TAPER_LIMIT_DEG:g} deg (limb segments taper by 2-9 deg; at 90 deg "
                           f"the limb would be a flat disc), got {alpha_deg!r}")
    return a
