"""The strap's handles on a scanned limb (docs/scans.md, "Strap handles").

With ``strap.model: handles`` the handles sit at the strap's axial position on the limb's
section there. On a scan that section is the scan's own cross-section by the plane at the
strap's x (a scan is a surface: cutting it where the strap lies is what the strap sees),
not an interpolation between the rows' outlines.
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import ModelInputError
from .scan_sections import DEFAULT_SMOOTHING, ScanMesh, axis_loop, ray_hits, tangent_angle

__all__ = ["ScanStrapSection", "scan_strap_section"]


class ScanStrapSection:
    """The scan's outline at one axial position ``x`` [m]: ``yz`` (k, 2) by increasing theta,
    with the tangent smoothed over +-``h`` [m] as the elements' turnings are."""

    def __init__(self, x: float, yz, h: float):
        self.x = float(x)
        self.yz = np.asarray(yz, dtype=float)
        self.h = float(h)
        seg = np.linalg.norm(np.roll(self.yz, -1, axis=0) - self.yz, axis=1)
        self._seg = seg
        self._cum = np.concatenate([[0.0], np.cumsum(seg)])

    def point_and_tangent(self, theta: float, x: float):
        """Point p (3,) [m] where the ray at ``theta`` leaves the outline and the outline's
        unit tangent t (3,) there, toward increasing theta. ``x`` must be the section's own
        (the strap's axial position it was cut at)."""
        if not math.isclose(float(x), self.x, rel_tol=0.0, abs_tol=1e-9):
            raise ModelInputError(f"the scan's strap section was cut at x = {self.x:.6g} m, "
                                  f"not at {float(x):.6g} m", "strap_axial_position")
        k, s = ray_hits(self.yz, np.array([float(theta)]))
        if k[0] < 0:
            raise ModelInputError(f"the ray at {math.degrees(theta):.4g} deg misses the scan's "
                                  f"section at x = {self.x:.4g} m", "scan")
        i = int(k[0])
        nxt = self.yz[(i + 1) % len(self.yz)]
        yz = self.yz[i] + s[0] * (nxt - self.yz[i])
        phi = float(tangent_angle(self.yz, np.array([self._cum[i] + s[0] * self._seg[i]]),
                                  self.h)[0])
        return (np.array([self.x, yz[0], yz[1]]),
                np.array([0.0, math.cos(phi), math.sin(phi)]))


def scan_strap_section(mesh: ScanMesh, x: float, smoothing: float | None = None,
                       name: str = "the strap") -> ScanStrapSection:
    """The scan's section at the strap's axial position ``x`` [m] (ModelInputError quantity
    ``scan`` if the plane misses the scan or its section does not go around the axis). The
    smoothing length is ``smoothing`` or, as for a row, the largest of
    :data:`DEFAULT_SMOOTHING`, two median mesh edges and three median outline segments."""
    loop = axis_loop(mesh, float(x), name)
    if smoothing is None:
        seg = np.linalg.norm(np.roll(loop.yz, -1, axis=0) - loop.yz, axis=1)
        smoothing = max(DEFAULT_SMOOTHING, 2 * mesh.edge_length, 3 * float(np.median(seg)))
    return ScanStrapSection(x, loop.yz, smoothing)
