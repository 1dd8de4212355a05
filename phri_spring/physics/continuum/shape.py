"""The tissue layer of the built-in FE on a limb of any section (docs/model.md section 13).

The mesh of :mod:`phri_spring.physics.continuum.mesh` is built in cylindrical
coordinates (x, theta, r), r from R - t (the bone) to R (the skin). On a circular
cylinder a node sits at (x, r cos theta, r sin theta). On any other limb the same
structured mesh is mapped: each radial line (x, theta) runs straight from the bone's
point B(theta, x) to the skin's point S(theta, x), at the same fraction
s = (r - (R - t)) / t of the way, so that the circle (S = R e_r, B = (R - t) e_r)
gives today's nodes to round-off.

- the skin: each row's outline (its section, or the circle of its radius) on the ray
  at theta; between rows the distance from the axis is interpolated linearly in x,
  and beyond the outer rows (or off the row of a one-row cuff) it follows the taper,
  d rho / dx = -tan(alpha), the cone of ``geometry.taper_deg``;
- the bone: a circle of centre (y, z) and radius r_b (``geometry.bone``), reached on
  the ray from its centre at theta; by default the rows' skin moved inward by t on every
  ray (beyond the outer rows, the outer row's: the bone does not follow the taper).

Pure numpy; errors are ``ValueError`` with a one-line message.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["LayerShape", "layer_shape", "check_layer", "reference_radius", "BONE_MARGIN_M"]

#: the least tissue left between the bone and the skin [m] (and between the default
#: bone and the axis): a bone that comes closer squashes the elements of that radial
#: line flat
BONE_MARGIN_M = 0.002


def reference_radius(geometry) -> float:
    """R of the parametric mesh [m]: the one radius of a circular cylinder's rows, else the
    mean distance of the patch points from the axis."""
    R = np.asarray(geometry.radius, float)
    if R.size and np.ptp(R) <= 1e-12 * np.max(np.abs(R)):
        return float(R[0])
    return float(np.mean(R))


def _taper_tan(geometry) -> float:
    """tan(alpha) of the taper the geometry's normals carry (n_x = -sin alpha)."""
    sa = -float(np.asarray(geometry.normals, float)[0, 0])
    sa = min(max(sa, -1.0), 1.0)
    return sa / math.sqrt(1.0 - sa * sa)


@dataclass(frozen=True)
class LayerShape:
    """The skin and bone of a layer that is not a circular cylinder.

    Attributes
    ----------
    row_x : ndarray, shape (R,)
        Axial positions of the rows [m], increasing.
    sections : tuple
        Per row: a section (``rho(theta)``), or a float (a circle's radius) [m].
    taper_tan : float
        tan(alpha) of the taper [-].
    thickness : float
        t [m]: the default bone is the skin moved inward by t on every ray.
    bone : tuple or None
        (y_c, z_c, r_b) [m] of a circular bone, or None.
    """

    row_x: np.ndarray
    sections: tuple
    taper_tan: float
    thickness: float
    bone: tuple | None = None

    def _rows(self, theta, slope=False):
        """Each row's rho (or d rho / d theta) on the rays theta: (R, *theta.shape)."""
        ut, inv = np.unique(theta, return_inverse=True)
        rows = np.array([np.full(ut.shape, 0.0 if slope else s) if isinstance(s, float)
                         else (s.rho_slope(ut) if slope else s.rho(ut))
                         for s in self.sections])
        return rows[:, inv.reshape(theta.shape)]

    def skin_rho(self, theta, x, slopes: bool = False):
        """Distance of the skin from the axis on the ray at theta, at axial position x [m]
        (theta and x broadcast); ``slopes``: also d rho / d theta [m/rad] and d rho / dx."""
        theta, x = np.broadcast_arrays(np.asarray(theta, float), np.asarray(x, float))
        rows = self._rows(theta)
        xs = self.row_x
        if len(xs) == 1:
            rho = rows[0] - self.taper_tan * (x - xs[0])
            if not slopes:
                return rho
            return rho, self._rows(theta, True)[0], np.full(x.shape, -self.taper_tan)
        i = np.clip(np.searchsorted(xs, x, side="right") - 1, 0, len(xs) - 2)
        lam = np.clip((x - xs[i]) / (xs[i + 1] - xs[i]), 0.0, 1.0)
        take = lambda a, k: np.take_along_axis(a, k[None], 0)[0]        # noqa: E731
        beyond = x - np.clip(x, xs[0], xs[-1])                          # 0 within the rows
        rho = (1.0 - lam) * take(rows, i) + lam * take(rows, i + 1) - self.taper_tan * beyond
        if not slopes:
            return rho
        d_rows = self._rows(theta, True)
        d_t = (1.0 - lam) * take(d_rows, i) + lam * take(d_rows, i + 1)
        d_x = np.where(beyond == 0.0, (take(rows, i + 1) - take(rows, i)) / (xs[i + 1] - xs[i]),
                       -self.taper_tan)
        return rho, d_t, d_x

    def default_bone_rho(self, theta, x) -> np.ndarray:
        """Distance of the default bone from the axis [m]: the skin moved inward by t on
        every ray, the rows' outlines interpolated between them and, beyond the outer rows,
        the outer row's (a bone does not taper with the skin's fat and muscle)."""
        x = np.asarray(x, float)
        return self.skin_rho(theta, np.clip(x, self.row_x[0], self.row_x[-1])) - self.thickness

    def map_nodes(self, x, theta, r, R, t) -> np.ndarray:
        """Cartesian nodes (3, N) of the parametric nodes (x, theta, r), r in [R - t, R]."""
        s = (r - (R - t)) / t
        c, sn = np.cos(theta), np.sin(theta)
        rho = self.skin_rho(theta, x)
        if self.bone is None:
            rb = self.default_bone_rho(theta, x)
            return np.vstack([x, (rb + s * (rho - rb)) * c, (rb + s * (rho - rb)) * sn])
        yc, zc, rr = self.bone
        by, bz = yc + rr * c, zc + rr * sn
        return np.vstack([x, by + s * (rho * c - by), bz + s * (rho * sn - bz)])

    def inward_normal(self, X) -> np.ndarray:
        """Inward unit normal (3, ...) of the skin at the points X (3, ...) [m], on the ray
        through each point: -grad(r - rho(theta, x)) normalised,
        rho's slopes from the sections' own (0 on a circle of the axis, so that the normal
        is -e_r there, as on the circular cylinder)."""
        x, y, z = X
        r = np.hypot(y, z)
        th = np.arctan2(z, y)
        _, d_t, d_x = self.skin_rho(th, x, slopes=True)
        c, s = y / r, z / r
        g = np.stack([-d_x, c + d_t / r * s, s - d_t / r * c])     # e_r - rho_t / r e_theta
        return -g / np.linalg.norm(g, axis=0)

    def check(self, theta, x) -> None:
        """ValueError unless the bone lies inside the skin with :data:`BONE_MARGIN_M` of
        tissue on every ray of ``theta`` at every ``x`` (the mesh's lines; the taper
        narrows the skin beyond the rows)."""
        T, X = np.meshgrid(np.asarray(theta, float), np.asarray(x, float))
        rho = self.skin_rho(T, X)
        t, m = self.thickness, BONE_MARGIN_M
        if self.bone is None:
            rb = self.default_bone_rho(T, X)
            if np.min(rb) < m or np.min(rho - rb) < m:
                raise ValueError(f"a layer {t * 1e3:g} mm thick leaves "
                                 f"{min(np.min(rb), np.min(rho - rb)) * 1e3:.3g} mm of bone or "
                                 f"of tissue over the modelled tissue (the taper narrows the "
                                 f"skin beyond the rows); expected at least {m * 1e3:g} mm: a "
                                 "thinner layer (or a geometry.bone)")
            return
        yc, zc, rr = self.bone
        d = np.hypot(rho * np.cos(T) - yc, rho * np.sin(T) - zc)
        if np.min(d) - rr < m:
            raise ValueError(f"expected the bone inside the skin with at least {m * 1e3:g} mm "
                             f"of tissue over the modelled tissue (the taper narrows the skin "
                             f"beyond the rows), got {(np.min(d) - rr) * 1e3:.3g} mm")

    def fingerprint(self) -> bytes:
        """Bytes that change with the shape (the skin on 64 rays at every row, the taper,
        the bone): part of the FE cache key."""
        th = 2.0 * math.pi * np.arange(64) / 64
        rho = self.skin_rho(th[None, :], self.row_x[:, None])
        bone = np.asarray(self.bone if self.bone is not None else (np.nan,) * 3, "<f8")
        return b"shape" + np.ascontiguousarray(rho, "<f8").tobytes() + np.float64(
            self.taper_tan).tobytes() + bone.tobytes() + np.float64(self.thickness).tobytes()


def layer_shape(geometry, thickness, bone=None) -> LayerShape | None:
    """The shape of the layer under a cuff geometry, or None for a circular cylinder
    without a ``bone`` (today's mesh, node for node).

    Parameters
    ----------
    geometry : CuffGeometry
        From ``cuff_geometry`` or ``section_geometry`` (its ``strap_section`` holds the
        rows' sections).
    thickness : float
        t [m].
    bone : sequence (y_c, z_c, r_b) [m], optional
        A circular bone; None: the skin moved inward by t.
    """
    R = np.asarray(geometry.radius, float)
    tan_a = _taper_tan(geometry)
    strap = getattr(geometry, "strap_section", None)
    circular = strap is None and np.ptp(R) <= 1e-12 * np.max(np.abs(R)) and tan_a == 0.0
    if circular and bone is None:
        return None
    xs, first = np.unique(np.asarray(geometry.x, float), return_index=True)
    if strap is None:
        secs = tuple(float(R[k]) for k in first)
    else:
        secs = []
        for xv in xs:
            hit = np.nonzero(np.abs(strap.row_x - xv) <= 1e-12)[0]
            secs.append(strap.sections[int(hit[0]) if len(hit) else 0])
        secs = tuple(secs)
    b = None if bone is None else tuple(float(v) for v in bone)
    return LayerShape(row_x=xs, sections=secs, taper_tan=tan_a, thickness=float(thickness),
                      bone=b)


def check_layer(geometry, thickness, bone=None, length_factor=6.0) -> None:
    """ValueError (one line) unless the layer under ``geometry`` can be meshed: the bone
    inside the skin with :data:`BONE_MARGIN_M` of tissue over the modelled length (the
    rows' extent and ``length_factor`` thicknesses beyond each edge), on 720 rays."""
    shape = layer_shape(geometry, thickness, bone)
    if shape is None:
        return
    x = np.asarray(geometry.x, float)
    w = np.asarray(geometry.row_width, float)
    ext = float(length_factor) * float(thickness)
    lo, hi = float(np.min(x - w / 2)) - ext, float(np.max(x + w / 2)) + ext
    xs = np.unique(np.concatenate([[lo, hi], shape.row_x]))
    shape.check(2.0 * math.pi * np.arange(720) / 720, xs)
