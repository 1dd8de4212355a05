"""Free element layouts: sensor patches anywhere on the limb (docs/model.md section 14).

A patch is an element placed by its own centre and size instead of a rows x angles grid:
axial position x [m], angle theta [rad], angular size ``width`` [rad] and axial size
``length`` [m]. It is placed on the limb's section exactly as a grid element is
(docs/model.md section 13): the point on the outline at theta, the outline's normal there
(tilted by the taper), the arc s between the rays at theta -/+ width / 2, area
s * length / cos(taper), and the tangent's turning psi across it.

Hoop preload of a free layout (Laplace's law p = T / (w rho)): the strap presses the
axial band the patches cover, of width w_strap = the length of the union of the patches'
axial intervals; a patch gets f0 = T psi (its axial length inside that band) / w_strap.
On a grid (rows that do not overlap) this is T psi w_r / sum_r w_r, the grid's preload.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import ModelInputError

__all__ = ["PatchLayout", "mat_layout", "check_layout", "hoop_shares", "patch_geometry"]


@dataclass(frozen=True, eq=False)
class PatchLayout:
    """Sensor patches: labels and (n,) arrays x [m], theta [rad], width [rad], length [m]."""

    labels: tuple
    x: np.ndarray
    theta: np.ndarray
    width: np.ndarray
    length: np.ndarray
    #: (rows, columns) of a mat (labels row-major), None for a free list
    mat_shape: tuple | None = None

    @property
    def n(self) -> int:
        return len(self.labels)


def mat_layout(rows: int, columns: int, pitch_axial: float, pitch_deg: float, x0: float,
               theta0_deg: float, cell_length: float | None = None,
               cell_width_deg: float | None = None) -> PatchLayout:
    """A pressure mat: rows (axial, toward +x) x columns (toward increasing theta) of cells.

    Cell (i, j) sits at x0 + i * pitch_axial, theta0 + j * pitch_deg, labelled
    ``R{i+1:02d}C{j+1:02d}`` (row-major); the cells' sizes default to the pitches.
    """
    rows, columns = int(rows), int(columns)
    i, j = np.divmod(np.arange(rows * columns), columns)
    digits = max(2, len(str(max(rows, columns))))
    labels = tuple(f"R{a + 1:0{digits}d}C{b + 1:0{digits}d}" for a, b in zip(i, j))
    length = pitch_axial if cell_length is None else cell_length
    width = pitch_deg if cell_width_deg is None else cell_width_deg
    n = rows * columns
    return PatchLayout(labels, x0 + pitch_axial * i.astype(float),
                       np.radians(theta0_deg + pitch_deg * j.astype(float)),
                       np.full(n, math.radians(width)), np.full(n, float(length)),
                       mat_shape=(rows, columns))


def check_layout(layout: PatchLayout) -> None:
    """Refuse duplicate labels, non-positive sizes and overlapping patches.

    Two patches overlap when both their axial intervals and their angular intervals
    (modulo 360 deg) share an interior; touching edges are allowed. Raises
    :class:`ModelInputError` (quantity ``patches``) naming the first offending patch(es).
    """
    labels = list(layout.labels)
    seen = set()
    for lab in labels:
        if lab in seen:
            raise ModelInputError(f"label {lab!r} appears twice; expected unique labels",
                                  "patches")
        seen.add(lab)
    x, th, w, ln = layout.x, layout.theta, layout.width, layout.length
    bad = ~(np.isfinite(x) & np.isfinite(th) & (w > 0) & (w <= 2 * math.pi + 1e-12)
            & (ln > 0) & np.isfinite(ln))
    if bad.any():
        lab = labels[int(np.argmax(bad))]
        raise ModelInputError(f"patch {lab}: expected finite x and theta, 0 < width <= 360 deg "
                              "and a positive finite length", "patches")
    tol = 1e-9
    n = len(labels)
    for i0 in range(0, n, 256):     # blocks of rows: memory of 256 x n, not n x n
        i = slice(i0, min(n, i0 + 256))
        ax = np.abs(x[i, None] - x[None, :]) < 0.5 * (ln[i, None] + ln[None, :]) * (1 - tol)
        d = np.abs((th[i, None] - th[None, :] + math.pi) % (2 * math.pi) - math.pi)
        ang = d < 0.5 * (w[i, None] + w[None, :]) * (1 - tol) - 1e-12
        both = np.triu(ax & ang, k=i0 + 1)
        if both.any():
            a, b = np.argwhere(both)[0]
            raise ModelInputError(f"patches {labels[i0 + a]} and {labels[b]} overlap (their "
                                  "axial and angular extents both intersect); expected "
                                  "patches that at most touch", "patches")


def hoop_shares(x, length) -> np.ndarray:
    """Each patch's axial length over the strap band's width w_strap (the length of the
    union of the patches' axial intervals), shape (n,)."""
    x, length = np.asarray(x, float), np.asarray(length, float)
    lo, hi = x - length / 2, x + length / 2
    order = np.argsort(lo, kind="stable")
    total, cur_lo, cur_hi = 0.0, None, None
    for a, b in zip(lo[order], hi[order]):
        if cur_hi is None or a > cur_hi:
            if cur_hi is not None:
                total += cur_hi - cur_lo
            cur_lo, cur_hi = a, b
        else:
            cur_hi = max(cur_hi, b)
    total += cur_hi - cur_lo
    return length / total


def _interp(row_x, x):
    """(i0, i1, lam) per x: the two nearest rows and the weight of the second one
    (the nearest row's values beyond the ends)."""
    row_x = np.asarray(row_x, float)
    order = np.argsort(row_x, kind="stable")
    xs = row_x[order]
    if len(xs) == 1:
        z = np.zeros(len(x), int)
        return order[z], order[z], np.zeros(len(x))
    i = np.clip(np.searchsorted(xs, x, side="right") - 1, 0, len(xs) - 2)
    lam = np.clip((x - xs[i]) / (xs[i + 1] - xs[i]), 0.0, 1.0)
    return order[i], order[i + 1], lam


def patch_geometry(layout: PatchLayout, row_x, sections, taper_deg: float = 0.0,
                   circular_radius=None):
    """The :class:`~phri_spring.physics.cuff.geometry.CuffGeometry` of a free layout.

    Parameters
    ----------
    layout : PatchLayout
    row_x : array_like, shape (R,)
        Axial positions [m] the sections are given at (one value: the same section everywhere).
    sections : sequence of Section, length R
        The outlines at ``row_x``; between two of them, the outline's radius, slope, arc and
        turning are interpolated linearly in x (the nearest one's beyond the ends), as the
        strap's handles are placed.
    taper_deg : float
        Taper half-angle alpha [deg].
    circular_radius : array_like, shape (R,), optional
        With circular sections: their radii, so that the points are those of
        :func:`~phri_spring.physics.cuff.geometry.cuff_geometry` to round-off.
    """
    from .geometry import CuffGeometry
    from ..limb.sections import StrapSection

    check_layout(layout)
    n = layout.n
    x, th, w, ln = (np.asarray(a, float) for a in (layout.x, layout.theta, layout.width,
                                                    layout.length))
    i0, i1, lam = _interp(row_x, x)
    c, s = np.cos(th), np.sin(th)
    if circular_radius is not None:
        R = np.asarray(circular_radius, float)
        rho = (1 - lam) * R[i0] + lam * R[i1]
        slope, arc, turn = np.zeros(n), rho * w, w.copy()
    else:
        secs = list(sections)
        rho, slope, arc, turn = (np.empty(n) for _ in range(4))
        for e in range(n):
            a = np.array([th[e]])
            lo, hi = a - w[e] / 2, a + w[e] / 2
            vals = [(float(q.rho(a)[0]), float(q.rho_slope(a)[0]), float(q.arc(lo, hi)[0]),
                     float(q.turning(lo, hi)[0])) for q in (secs[i0[e]], secs[i1[e]])]
            rho[e], slope[e], arc[e], turn[e] = ((1 - lam[e]) * p + lam[e] * q
                                                 for p, q in zip(*vals))
    points = np.column_stack([x, rho * c, rho * s])
    # outward normal: the tangent d/dtheta (rho e_r) = slope e_r + rho e_theta turned by -90 deg
    ty, tz = slope * c - rho * s, slope * s + rho * c
    norm = np.hypot(ty, tz)
    m = np.column_stack([tz / norm, -ty / norm])
    ca, sa = math.cos(math.radians(taper_deg)), math.sin(math.radians(taper_deg))
    normals = -np.column_stack([np.full(n, sa), ca * m])
    strap = None if circular_radius is not None else StrapSection(row_x, secs)
    geom = CuffGeometry.from_elements(
        layout.labels, ("",), 1, n, x=x, row_width=ln, theta=th, span=w, points=points,
        normals=normals, areas=ln * arc / ca, turning=turn, strap_section=strap)
    from dataclasses import replace

    return replace(geom, hoop_share=hoop_shares(x, ln), free_layout=True,
                   handles_radius=None if circular_radius is None
                   else float(np.mean(circular_radius)))
