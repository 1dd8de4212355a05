"""The elastic band strap (``strap.model: band``, docs/model.md section 3.1).

The shell (the cuff's elements) covers part of the limb's circumference; an elastic band
of axial width w and stiffness k (tension per unit strain) [N] runs over the skin between
the shell's edges. Its ends are fixed to the shell, so a cuff displacement u changes the
band's length: to first order dL = -h . u, with h = (t_b - t_a, p_b x t_b - p_a x t_a) the
unit-tension wrench of the band on the cuff (the ``handles`` wrench divided by T). The
band's tension is T = max(0, T_pre + k (L - L_pre) / L0): a slack band carries nothing.
It presses the skin it covers by Laplace's law, p = T / (w rho), rho the outline's radius
of curvature.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import ModelInputError
from .preload import handle_edges, strap_preload

__all__ = ["BandPath", "band_path", "laplace_pressure"]

#: points along the band's path where a section's outline is sampled
_PATH_SAMPLES = 2048


@dataclass(frozen=True)
class BandPath:
    """The band's path over the skin between the shell's edges.

    Attributes
    ----------
    h : ndarray, shape (6,)
        Wrench of the band on the cuff per newton of tension [-, m] (the band's length
        changes by -h . u under a small cuff displacement u).
    length : float
        Length L0 of the path [m].
    min_radius : float
        Smallest radius of curvature of the outline along the path [m] (where Laplace's
        law gives the band's largest pressure).
    """

    h: np.ndarray
    length: float
    min_radius: float


def laplace_pressure(tension, width: float, radius) -> np.ndarray:
    """Pressure of a band of tension T [N] and width w [m] on skin of radius of
    curvature rho [m]: p = T / (w rho) [Pa] (Laplace's law)."""
    return np.asarray(tension, dtype=float) / (float(width) * np.asarray(radius, dtype=float))


def band_path(geometry, handle_angles_deg=None, handle_axial_position=None) -> BandPath:
    """The band's path from the shell's edge theta_b around the uncovered side to its edge
    theta_a + 2 pi (the edges as the ``handles`` model places its handles: default the
    cuff's edges and the mean row position).

    Raises
    ------
    ModelInputError
        If the shell's edges leave no uncovered skin, or the geometry has no outline.
    """
    ta, tb, ax = handle_edges(geometry, handle_angles_deg, handle_axial_position)
    # the band's pull per newton is the handles' wrench at unit tension
    _, h = strap_preload(geometry, 1.0, "handles", handle_angles_deg, handle_axial_position)
    covered = (tb - ta) % (2 * math.pi)
    gap = 2 * math.pi - covered
    if not gap > 1e-6 or not covered > 1e-6:
        raise ModelInputError("the band needs uncovered skin between the "
                              "shell's edges (the shell covers the whole circumference)",
                              "strap_handle_angles")
    if geometry.strap_section is None:
        r = float(geometry.handles_radius)
        return BandPath(h=np.asarray(h, dtype=float), length=r * gap, min_radius=r)
    theta = tb + gap * np.linspace(0.0, 1.0, _PATH_SAMPLES + 1)
    pts, tans = zip(*(geometry.strap_section.point_and_tangent(t, ax) for t in theta))
    pts, tans = np.array(pts), np.array(tans)
    ds = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    psi = np.unwrap(np.arctan2(tans[:, 2], tans[:, 1]))
    dpsi = np.diff(psi)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.where(dpsi > 0, ds / dpsi, np.inf)   # a flat or concave stretch presses nothing
    return BandPath(h=np.asarray(h, dtype=float), length=float(ds.sum()),
                    min_radius=float(np.min(rho)))
