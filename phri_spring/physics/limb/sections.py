"""Limb sections beyond the circle: the outline maths of docs/model.md section 13.

A section is a row's skin outline in the cuff's y-z plane: a closed curve around the
arm axis, star-shaped about it (the ray from the axis at angle theta leaves it once).
Every section is a periodic parametric curve c(t) = (y(t), z(t)) that runs toward
increasing angle theta as t grows; what the spring model needs follows from c and its
derivatives:

- the point on the ray at theta, rho(theta) its distance from the axis;
- the outward unit normal there;
- the arc length and the turning of the tangent between two rays.

Sections: :class:`CircleSection`, :class:`EllipseSection` (semi-axes a, b, turned by phi)
and :class:`OutlineSection` (a periodic cubic spline through points, parametrised by
chord length). :class:`StrapSection` gives the section at any axial position (the strap's
handles), interpolating rho linearly between rows.

Errors are :class:`SectionError` (a ``ValueError``) with a one-line message; the config
layer names the key.
"""

from __future__ import annotations

import math

import numpy as np

from .bounds import (MIN_OUTLINE_POINTS, RHO_RANGE_M, TAPER_LIMIT_DEG, SectionError,
                     check_rho_range, check_taper)

__all__ = ["SectionError", "Section", "CircleSection", "EllipseSection", "OutlineSection",
           "StrapSection", "RHO_RANGE_M", "MIN_OUTLINE_POINTS", "TAPER_LIMIT_DEG",
           "check_taper", "check_rho_range", "outlines_at"]

_QUAD = dict(epsabs=1e-15, epsrel=1e-13, limit=200)


def _wrap(a):
    """Angle(s) wrapped into (-pi, pi]."""
    return np.angle(np.exp(1j * np.asarray(a, dtype=float)))


class Section:
    """A closed outline around the axis, as a periodic curve c(t) of period ``period``.

    Subclasses give :meth:`curve` (derivative order 0, 1, 2) and :meth:`param_at`
    (the parameter t at which the curve crosses the ray at theta, continuous and
    increasing in theta, t(theta + 2 pi) = t(theta) + period).
    """

    period: float = 2.0 * math.pi

    def curve(self, t, order: int = 0) -> np.ndarray:     # pragma: no cover - abstract
        raise NotImplementedError

    def param_at(self, theta) -> np.ndarray:               # pragma: no cover - abstract
        raise NotImplementedError

    # ------------------------------------------------------------------ what the model reads
    def point(self, theta) -> np.ndarray:
        """(y, z) of the outline on the ray at theta [m], shape (..., 2)."""
        return self.curve(self.param_at(theta))

    def rho(self, theta) -> np.ndarray:
        """Distance from the axis of the outline on the ray at theta [m]."""
        return np.linalg.norm(self.point(theta), axis=-1)

    def unit_tangent(self, theta) -> np.ndarray:
        """Unit tangent (y, z) toward increasing theta, shape (..., 2)."""
        d = self.curve(self.param_at(theta), 1)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def outward_normal(self, theta) -> np.ndarray:
        """Outward unit normal (m_y, m_z): the unit tangent turned by -90 deg."""
        tg = self.unit_tangent(theta)
        return np.stack([tg[..., 1], -tg[..., 0]], axis=-1)

    def rho_slope(self, theta) -> np.ndarray:
        """d rho / d theta [m/rad]: rho (c . c') / (c x c')."""
        t = self.param_at(theta)
        c, d = self.curve(t), self.curve(t, 1)
        r = np.linalg.norm(c, axis=-1)
        return r * np.sum(c * d, axis=-1) / (c[..., 0] * d[..., 1] - c[..., 1] * d[..., 0])

    def _speed(self, t: float) -> float:
        d = self.curve(np.array([t]), 1)[0]
        return float(math.hypot(d[0], d[1]))

    def _curvature_speed(self, t: float) -> float:
        d1 = self.curve(np.array([t]), 1)[0]
        d2 = self.curve(np.array([t]), 2)[0]
        return float((d1[0] * d2[1] - d1[1] * d2[0]) / (d1[0] ** 2 + d1[1] ** 2))

    def _breaks(self, t0: float, t1: float) -> list:
        """Where the integrands are not smooth between t0 and t1 (spline knots)."""
        return []

    def _integrate(self, f, lo, hi) -> np.ndarray:
        from scipy.integrate import quad  # on demand: every config imports this module
        lo, hi = np.broadcast_arrays(np.asarray(lo, float), np.asarray(hi, float))
        tl, th = self.param_at(lo), self.param_at(hi)
        out = np.empty(tl.shape)
        for i, (a, b) in enumerate(zip(tl.ravel(), th.ravel())):
            pts = self._breaks(a, b)
            edges = [a, *pts, b]
            out.flat[i] = sum(quad(f, u, v, **_QUAD)[0] for u, v in zip(edges[:-1], edges[1:]))
        return out

    def arc(self, theta_lo, theta_hi) -> np.ndarray:
        """Arc length of the outline between the rays at theta_lo < theta_hi [m]."""
        return self._integrate(self._speed, theta_lo, theta_hi)

    def turning(self, theta_lo, theta_hi) -> np.ndarray:
        """Angle the tangent turns through between the rays at theta_lo < theta_hi [rad]
        (signed: negative where the outline is concave; 2 pi over a full turn)."""
        return self._integrate(self._curvature_speed, theta_lo, theta_hi)

    def rho_range(self) -> tuple:
        """(min, max) of rho over the outline [m] (sampled)."""
        r = self.rho(np.linspace(0.0, 2.0 * math.pi, 721))
        return float(r.min()), float(r.max())

    def perimeter(self) -> float:
        """Length of the whole outline [m]."""
        return float(self.arc(0.0, 2.0 * math.pi))


class CircleSection(Section):
    """The circle of radius R about the axis (section 1 of docs/model.md)."""

    def __init__(self, radius: float):
        self.radius = float(radius)

    def curve(self, t, order: int = 0):
        t = np.asarray(t, dtype=float)
        c, s = np.cos(t), np.sin(t)
        R = self.radius
        return R * {0: np.stack([c, s], -1), 1: np.stack([-s, c], -1),
                    2: np.stack([-c, -s], -1)}[order]

    def param_at(self, theta):
        return np.asarray(theta, dtype=float)

    def arc(self, theta_lo, theta_hi):
        return self.radius * (np.asarray(theta_hi, float) - np.asarray(theta_lo, float))

    def turning(self, theta_lo, theta_hi):
        return np.asarray(theta_hi, float) - np.asarray(theta_lo, float)


class EllipseSection(Section):
    """Semi-axes a along y' and b along z' [m], (y', z') turned by phi [rad] from +y to +z.

    c(t) = R(phi) (a cos t, b sin t).
    """

    def __init__(self, a: float, b: float, rotation: float = 0.0):
        a, b, rotation = float(a), float(b), float(rotation)
        if not (math.isfinite(a) and math.isfinite(b) and a > 0 and b > 0):
            raise SectionError(f"expected two positive semi-axes [m], got [{a:g}, {b:g}]")
        if not math.isfinite(rotation):
            raise SectionError(f"expected a finite rotation [deg], got {rotation!r}")
        check_rho_range(min(a, b), max(a, b), "semi-axes")
        self.a, self.b, self.phi = a, b, rotation

    def curve(self, t, order: int = 0):
        t = np.asarray(t, dtype=float)
        c, s = np.cos(t), np.sin(t)
        if order == 0:
            y, z = self.a * c, self.b * s
        elif order == 1:
            y, z = -self.a * s, self.b * c
        else:
            y, z = -self.a * c, -self.b * s
        cp, sp = math.cos(self.phi), math.sin(self.phi)
        return np.stack([cp * y - sp * z, sp * y + cp * z], axis=-1)

    def param_at(self, theta):
        q = np.asarray(theta, dtype=float) - self.phi
        c, s = np.cos(q), np.sin(q)
        # (cos t, sin t) is along (b cos q, a sin q); t - q stays in (-pi/2, pi/2)
        return q + np.arctan2((self.a - self.b) * s * c, self.b * c * c + self.a * s * s)

    def rho_range(self):
        return min(self.a, self.b), max(self.a, self.b)


class OutlineSection(Section):
    """The periodic cubic spline through points (y, z) [m] around the axis.

    Parametrised by chord length: t_0 = 0, ``t_i = t_{i-1} + |P_i - P_{i-1}|``, period the
    closed polygon's perimeter. Points in order of increasing angle; a last point equal
    to the first is dropped.
    """

    _SAMPLES = 48   # per spline piece, for the star-shape check and the inverse's start

    def __init__(self, points):
        from scipy.interpolate import CubicSpline  # on demand: every config imports this module
        try:
            P = np.asarray(points, dtype=float)
        except (TypeError, ValueError):
            raise SectionError("expected a list of [y, z] pairs [m]") from None
        if P.ndim != 2 or P.shape[1] != 2:
            raise SectionError(f"expected a list of [y, z] pairs [m], got shape {P.shape}")
        if not np.all(np.isfinite(P)):
            raise SectionError("expected finite coordinates [m]")
        if len(P) > 1 and np.allclose(P[-1], P[0], rtol=0, atol=1e-12):
            P = P[:-1]
        if len(P) < MIN_OUTLINE_POINTS:
            raise SectionError(f"expected at least {MIN_OUTLINE_POINTS} points around the limb, "
                               f"got {len(P)}")
        r = np.hypot(P[:, 0], P[:, 1])
        check_rho_range(float(r.min()), float(r.max()), "outline points")
        ang = np.arctan2(P[:, 1], P[:, 0])
        steps = _wrap(np.diff(np.append(ang, ang[0])))
        total = float(np.sum(steps))
        if abs(total) < math.pi:
            raise SectionError("the outline does not go around the arm axis (y = z = 0); "
                               "expected a closed outline enclosing it")
        if total < 0:
            raise SectionError("the points go clockwise; expected them in order of increasing "
                               "angle (from +y toward +z)")
        if abs(total - 2.0 * math.pi) > 1e-6 or np.any(steps <= 0):
            i = int(np.argmin(steps)) + 1
            raise SectionError(f"point {i % len(P)} is not at a larger angle than the point "
                               "before it: expected an outline star-shaped about the axis, "
                               "given in order of angle, not self-intersecting")
        chords = np.linalg.norm(np.diff(np.vstack([P, P[:1]]), axis=0), axis=1)
        knots = np.concatenate([[0.0], np.cumsum(chords)])
        self.points = P
        self.knots = knots
        self.period = float(knots[-1])
        self._spline = CubicSpline(knots, np.vstack([P, P[:1]]), bc_type="periodic")
        self._d1 = self._spline.derivative(1)
        self._d2 = self._spline.derivative(2)
        # the star shape of the spline itself: its polar angle must rise all the way round
        ts = np.linspace(0.0, self.period, self._SAMPLES * len(P) + 1)
        c, d = self._spline(ts), self._d1(ts)
        cross = c[:, 0] * d[:, 1] - c[:, 1] * d[:, 0]
        if np.any(cross <= 0):
            i = int(np.searchsorted(knots, ts[int(np.argmin(cross))], side="right")) - 1
            raise SectionError(f"the spline through the points turns back near point {i} "
                               "(not star-shaped about the axis, or self-intersecting); "
                               "expected each ray from the axis to cross the outline once "
                               "(add points there)")
        rs = np.hypot(c[:, 0], c[:, 1])
        check_rho_range(float(rs.min()), float(rs.max()), "outline")
        self._ts = ts
        self._angle = ang[0] + np.concatenate([[0.0], np.cumsum(_wrap(np.diff(
            np.arctan2(c[:, 1], c[:, 0]))))])
        self._rho_range = (float(rs.min()), float(rs.max()))

    def curve(self, t, order: int = 0):
        t = np.mod(np.asarray(t, dtype=float), self.period)
        return (self._spline, self._d1, self._d2)[order](t)

    def param_at(self, theta):
        theta = np.asarray(theta, dtype=float)
        a0 = self._angle[0]
        k = np.floor((theta - a0) / (2.0 * math.pi))
        th = theta - 2.0 * math.pi * k
        t = np.interp(th, self._angle, self._ts)
        for _ in range(30):   # Newton on the polar angle (monotone in t)
            c, d = self._spline(t), self._d1(t)
            f = _wrap(np.arctan2(c[..., 1], c[..., 0]) - th)
            dfdt = (c[..., 0] * d[..., 1] - c[..., 1] * d[..., 0]) / np.sum(c * c, axis=-1)
            step = f / dfdt
            t = np.clip(t - step, 0.0, self.period)
            if np.all(np.abs(step) <= 1e-15 * self.period):
                break
        return t + self.period * k

    def _breaks(self, t0, t1):
        n0, n1 = math.floor(t0 / self.period), math.floor(t1 / self.period)
        out = []
        for m in range(n0, n1 + 1):
            out.extend(v for v in self.knots + m * self.period if t0 < v < t1)
        return sorted(out)

    def rho_range(self):
        return self._rho_range


class StrapSection:
    """The outline at any axial position x: rho linearly interpolated between the two
    nearest rows' sections, the nearest row's beyond the ends (docs/model.md section 13)."""

    def __init__(self, row_x, sections):
        order = np.argsort(np.asarray(row_x, dtype=float), kind="stable")
        self.row_x = np.asarray(row_x, dtype=float)[order]
        self.sections = tuple(sections[i] for i in order)

    def _pair(self, x: float):
        xs = self.row_x
        if len(xs) == 1 or x <= xs[0]:
            return self.sections[0], self.sections[0], 0.0
        if x >= xs[-1]:
            return self.sections[-1], self.sections[-1], 0.0
        i = int(np.searchsorted(xs, x, side="right")) - 1
        lam = (x - xs[i]) / (xs[i + 1] - xs[i])
        return self.sections[i], self.sections[i + 1], float(lam)

    def point_and_tangent(self, theta: float, x: float):
        """Point p (3,) [m] on the outline at (x, theta) and the outline's unit tangent
        t (3,) there, in the y-z plane, toward increasing theta."""
        s0, s1, lam = self._pair(float(x))
        rho = (1 - lam) * float(s0.rho(theta)) + lam * float(s1.rho(theta))
        slope = (1 - lam) * float(s0.rho_slope(theta)) + lam * float(s1.rho_slope(theta))
        c, s = math.cos(theta), math.sin(theta)
        # d/dtheta of rho (cos, sin): slope e_r + rho e_theta
        ty, tz = slope * c - rho * s, slope * s + rho * c
        norm = math.hypot(ty, tz)
        return (np.array([float(x), rho * c, rho * s]),
                np.array([0.0, ty / norm, tz / norm]))


def outlines_at(x, row_x, sections=None, radius=None, k: int = 256) -> list:
    """The skin outline at each axial position of ``x``, as (k, 2) arrays of (y, z) [m].

    The outline is sampled on k rays theta = 2 pi i / k (so its vertices are the section's
    points on those rays). At a row's own position it is that row's section; between two
    rows the distance from the axis on each ray is interpolated linearly in x, and beyond
    the ends it is the nearest row's (as a free layout's patches are placed, docs/model.md
    section 14).

    Parameters
    ----------
    x : array_like, shape (m,)
        Axial positions [m] (e.g. the rows' own ``row_x``, or a band of patches' centre).
    row_x : array_like, shape (R,)
        Where the sections are given [m].
    sections : sequence of Section, length R, optional
        The outlines there; None for circles of ``radius``.
    radius : array_like, shape (R,), optional
        The circles' radii [m] when ``sections`` is None.
    k : int
        Points per outline.
    """
    row_x = np.atleast_1d(np.asarray(row_x, dtype=float))
    theta = 2.0 * math.pi * np.arange(k) / k
    if sections is None:
        if radius is None:
            raise ValueError("outlines_at: expected sections or radius")
        rho_rows = np.outer(np.broadcast_to(np.asarray(radius, float), row_x.shape),
                            np.ones(k))
    else:
        if len(sections) != len(row_x):
            raise ValueError(f"outlines_at: {len(sections)} sections for {len(row_x)} rows")
        rho_rows = np.array([s.rho(theta) for s in sections])
    order = np.argsort(row_x, kind="stable")
    xs, rs = row_x[order], rho_rows[order]
    ray = np.column_stack([np.cos(theta), np.sin(theta)])
    out = []
    for xv in np.atleast_1d(np.asarray(x, dtype=float)):
        if len(xs) == 1:
            rho = rs[0]
        else:   # linear between the two rows around xv, the nearest row's beyond the ends
            i = int(np.clip(np.searchsorted(xs, xv, side="right") - 1, 0, len(xs) - 2))
            gap = xs[i + 1] - xs[i]
            lam = min(max((xv - xs[i]) / gap, 0.0), 1.0) if gap > 0 else 0.0
            rho = (1.0 - lam) * rs[i] + lam * rs[i + 1]
        out.append(rho[:, None] * ray)
    return out
