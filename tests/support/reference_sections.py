"""An independent implementation of the limb sections of docs/model.md section 13, for tests.

Written from the docs, never importing ``phri_spring``, and by other methods than the
package (which integrates arc and turning numerically on every section and inverts the
ray by Newton's method):

- ellipse: the ray's parameter by root bracketing (brentq), the arc by Legendre's
  incomplete elliptic integral of the second kind, the turning from the closed-form
  tangent angle;
- outline: its own periodic cubic spline (the cyclic system for the knots' second
  derivatives, solved densely), the ray's parameter by brentq inside the bracketing
  piece, the arc by Gauss-Legendre quadrature on each piece, the turning by summing the
  angles between tangents at closely spaced parameters.

It builds a :class:`reference_model.Geometry` carrying the turning and a handle
function, which :func:`reference_model.build` reads.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq
from scipy.special import ellipeinc

from support import reference_model as ref

TWO_PI = 2.0 * math.pi


def _angle_between(u, v) -> float:
    """Signed angle from 2-vector u to v, in (-pi, pi]."""
    return math.atan2(u[0] * v[1] - u[1] * v[0], u[0] * v[0] + u[1] * v[1])


class RefEllipse:
    def __init__(self, a, b, rotation_deg=0.0):
        self.a, self.b, self.phi = float(a), float(b), math.radians(rotation_deg)

    def _local(self, t, order=0):
        a, b = self.a, self.b
        v = [(a * math.cos(t), b * math.sin(t)), (-a * math.sin(t), b * math.cos(t)),
             (-a * math.cos(t), -b * math.sin(t))][order]
        cp, sp = math.cos(self.phi), math.sin(self.phi)
        return np.array([cp * v[0] - sp * v[1], sp * v[0] + cp * v[1]])

    def param(self, theta):
        """t in [q - pi/2, q + pi/2] (q = theta - phi) with the point at polar angle theta."""
        q = theta - self.phi

        def f(t):   # angle from the ray to the local point, continuous near the root
            return _angle_between((math.cos(q), math.sin(q)),
                                  (self.a * math.cos(t), self.b * math.sin(t)))
        return brentq(f, q - math.pi / 2 + 1e-12, q + math.pi / 2 - 1e-12, xtol=1e-15,
                      rtol=1e-15)

    def point(self, theta):
        return self._local(self.param(theta))

    def tangent(self, theta):
        d = self._local(self.param(theta), 1)
        return d / np.linalg.norm(d)

    def rho_slope(self, theta):
        # rho = (cos^2 q / a^2 + sin^2 q / b^2)^(-1/2): d rho/dq = -rho^3 sin q cos q (1/b^2 - 1/a^2)
        q = theta - self.phi
        rho = (math.cos(q) ** 2 / self.a ** 2 + math.sin(q) ** 2 / self.b ** 2) ** -0.5
        return -rho ** 3 * math.sin(q) * math.cos(q) * (1 / self.b ** 2 - 1 / self.a ** 2)

    def _arc_from_zero(self, t):
        # |c'| = sqrt(a^2 sin^2 t + b^2 cos^2 t) = b sqrt(1 - m sin^2 t), m = 1 - a^2/b^2
        return self.b * ellipeinc(t, 1.0 - self.a ** 2 / self.b ** 2)

    def arc_turn(self, th_lo, th_hi):
        t0 = self.param(th_lo)
        t1 = self.param(th_hi)
        while t1 <= t0:
            t1 += TWO_PI
        arc = self._arc_from_zero(t1) - self._arc_from_zero(t0)

        # tangent angle of the local curve: t + pi/2 + atan2(-(b - a) sin t cos t,
        # a sin^2 t + b cos^2 t) (the offset from the circle's tangent stays within +-pi/2)
        def tau(t):
            s, c = math.sin(t), math.cos(t)
            return t + math.pi / 2 + math.atan2(-(self.b - self.a) * s * c,
                                                self.a * s * s + self.b * c * c)
        return arc, tau(t1) - tau(t0)


class RefOutline:
    """Periodic cubic spline through points, chord-length parameters."""

    def __init__(self, points):
        P = np.array(points, dtype=float)
        if np.allclose(P[-1], P[0], rtol=0, atol=1e-12):
            P = P[:-1]
        self.P = P
        N = len(P)
        self.N = N
        h = np.array([np.linalg.norm(P[(i + 1) % N] - P[i]) for i in range(N)])
        self.h = h
        self.knots = np.concatenate([[0.0], np.cumsum(h)])
        self.L = float(self.knots[-1])
        # second derivatives M_i at the knots: the cyclic tridiagonal system
        A = np.zeros((N, N))
        rhs = np.zeros((N, 2))
        for i in range(N):
            hp, hn = h[i - 1], h[i]
            A[i, i - 1] += hp
            A[i, i] += 2.0 * (hp + hn)
            A[i, (i + 1) % N] += hn
            rhs[i] = 6.0 * ((P[(i + 1) % N] - P[i]) / hn - (P[i] - P[i - 1]) / hp)
        self.M = np.linalg.solve(A, rhs)

    def _piece(self, t):
        t = t % self.L
        i = min(int(np.searchsorted(self.knots, t, side="right")) - 1, self.N - 1)
        return i, t - self.knots[i]

    def eval(self, t, order=0):
        i, s = self._piece(t)
        h = self.h[i]
        j = (i + 1) % self.N
        Pi, Pj, Mi, Mj = self.P[i], self.P[j], self.M[i], self.M[j]
        r = h - s
        if order == 0:
            return (Mi * r ** 3 + Mj * s ** 3) / (6 * h) + (Pi / h - Mi * h / 6) * r \
                + (Pj / h - Mj * h / 6) * s
        if order == 1:
            return (-Mi * r ** 2 + Mj * s ** 2) / (2 * h) - (Pi / h - Mi * h / 6) \
                + (Pj / h - Mj * h / 6)
        return (Mi * r + Mj * s) / h

    def param(self, theta):
        """t in [0, L) with the point at polar angle theta (mod 2 pi)."""
        angs = [math.atan2(p[1], p[0]) for p in self.P]
        for i in range(self.N):    # the piece whose end rays bracket theta
            lo = angs[i]
            span = (angs[(i + 1) % self.N] - lo) % TWO_PI
            off = (theta - lo) % TWO_PI
            if off > TWO_PI - 1e-12:     # theta on this piece's first point, rounded below
                off = 0.0
            if off <= span + 1e-12:
                a, b = self.knots[i], self.knots[i + 1]

                def f(t):
                    c = self.eval(min(t, self.L * (1 - 1e-16)))
                    return _angle_between((math.cos(theta), math.sin(theta)), c)
                fa, fb = f(a), f(b - 1e-15 * self.L)
                if abs(fa) < 1e-15:
                    return a
                if abs(fb) < 1e-15:
                    return b
                if fa * fb > 0:
                    continue
                return brentq(f, a, b - 1e-15 * self.L, xtol=1e-16, rtol=1e-15)
        raise RuntimeError("ray does not cross the outline")

    def point(self, theta):
        return self.eval(self.param(theta))

    def tangent(self, theta):
        d = self.eval(self.param(theta), 1)
        return d / np.linalg.norm(d)

    def rho_slope(self, theta):
        t = self.param(theta)
        c, d = self.eval(t), self.eval(t, 1)
        return np.linalg.norm(c) * (c @ d) / (c[0] * d[1] - c[1] * d[0])

    def arc_turn(self, th_lo, th_hi):
        t0, t1 = self.param(th_lo), self.param(th_hi)
        while t1 <= t0:
            t1 += self.L
        # break at the knots in between, Gauss-Legendre on each sub-piece
        brk = [t0] + [k + m * self.L for m in range(0, 3) for k in self.knots
                      if t0 < k + m * self.L < t1] + [t1]
        brk = sorted(set(brk))
        xg, wg = np.polynomial.legendre.leggauss(40)
        arc, turn = 0.0, 0.0
        for u, v in zip(brk[:-1], brk[1:]):
            mid, half = 0.5 * (u + v), 0.5 * (v - u)
            # nudge inside the piece so eval picks the right cubic at the ends
            arc += half * sum(w * np.linalg.norm(self.eval(mid + half * x, 1))
                              for x, w in zip(xg, wg))
            ts = np.linspace(u + 1e-13 * self.L, v - 1e-13 * self.L, 17)
            for p, q in zip(ts[:-1], ts[1:]):
                turn += _angle_between(self.eval(p, 1), self.eval(q, 1))
        return arc, turn


class RefStrap:
    """The outline at axial position x: rho interpolated linearly between the two nearest
    rows, the nearest row's beyond the ends."""

    def __init__(self, row_x, sections):
        self.xs = [float(v) for v in row_x]
        self.secs = list(sections)

    def point_tangent(self, theta, x):
        xs = self.xs
        if len(xs) == 1 or x <= xs[0]:
            pairs = [(self.secs[0], 1.0)]
        elif x >= xs[-1]:
            pairs = [(self.secs[-1], 1.0)]
        else:
            i = max(k for k in range(len(xs)) if xs[k] <= x)
            lam = (x - xs[i]) / (xs[i + 1] - xs[i])
            pairs = [(self.secs[i], 1 - lam), (self.secs[i + 1], lam)]
        rho = sum(w * np.linalg.norm(s.point(theta)) for s, w in pairs)
        drho = sum(w * s.rho_slope(theta) for s, w in pairs)
        er = np.array([0.0, math.cos(theta), math.sin(theta)])
        et = np.array([0.0, -math.sin(theta), math.cos(theta)])
        t = drho * er + rho * et
        return np.array([x, 0.0, 0.0]) + rho * er, t / np.linalg.norm(t)


def section_of(spec):
    if "ellipse" in spec:
        a, b = spec["ellipse"]
        return RefEllipse(a, b, spec.get("rotation", 0.0))
    return RefOutline(spec["outline"])


def make_section_geometry(rows, section, row_width, start, step, count, width=None,
                          taper_deg=0.0) -> ref.Geometry:
    """docs/model.md section 13: ``section`` a section mapping or {per_row: [...]}."""
    row_labels = [str(k) for k in rows]
    row_x = [float(v) for v in rows.values()]
    n_rows = len(row_labels)
    if "per_row" in section:
        secs = [section_of(s) for s in section["per_row"]]
        strap = RefStrap(row_x, secs)
    else:
        secs = [section_of(section)] * n_rows
        strap = RefStrap([row_x[0]], secs[:1])
    w = ref._per_row(row_width, n_rows)
    width_deg = float(step if width is None else width)
    half = math.radians(width_deg) / 2.0
    al = math.radians(taper_deg)
    theta_deg = [float(start) + j * float(step) for j in range(int(count))]
    labels, pts, nrm, areas, bs, erw, turn, rad = [], [], [], [], [], [], [], []
    for r in range(n_rows):
        for j in range(int(count)):
            th = math.radians(theta_deg[j])
            yz = secs[r].point(th)
            tg = secs[r].tangent(th)
            m = np.array([tg[1], -tg[0]])          # outward: the tangent turned by -90 deg
            p = np.array([row_x[r], yz[0], yz[1]])
            nv = -np.array([math.sin(al), math.cos(al) * m[0], math.cos(al) * m[1]])
            arc, psi = secs[r].arc_turn(th - half, th + half)
            labels.append(f"{row_labels[r]}{j}")
            pts.append(p)
            nrm.append(nv)
            areas.append(w[r] * arc / math.cos(al))
            bs.append(ref.jacobian(p).T @ nv)
            erw.append(w[r])
            turn.append(psi)
            rad.append(float(np.linalg.norm(yz)))
    g = ref.Geometry(labels=labels, row_labels=row_labels, n_rows=n_rows, n_angles=int(count),
                     row_x=row_x, row_radius=[float(np.mean(rad))] * n_rows, row_width=w,
                     theta_deg=theta_deg, width_deg=width_deg, points=np.array(pts),
                     normals=np.array(nrm), areas=np.array(areas), b=np.array(bs),
                     elem_row_width=np.array(erw))
    g.turning = np.array(turn)
    g.handle = strap.point_tangent
    return g


def model_from_config(cfg: dict, arm="compliant") -> ref.RefModel:
    """The reference model of a config mapping with geometry.section / taper_deg."""
    g = cfg["geometry"]
    a = g["angles"]
    geom = make_section_geometry(g["rows"], g["section"], g["row_width"], a["start"],
                                 a["step"], a["count"], a.get("width"),
                                 g.get("taper_deg", 0.0))
    tissue = cfg["tissue"]
    kt_cfg = ref.resolve_stiffness(tissue["stiffness"], geom)
    kt = ref.indenter_to_element(kt_cfg, geom.areas, tissue.get("indenter_diameter", 0.009)) \
        if tissue.get("basis", "indenter") == "indenter" else kt_cfg
    kc = ref.resolve_stiffness(cfg["cuff"]["stiffness"], geom)
    strap = cfg.get("strap", {}) or {}
    return ref.build(geom, kt, kc, arm=arm, shear_ratio=(cfg.get("interface") or {}).get(
        "shear_ratio"), poisson_ratio=tissue.get("poisson_ratio", 0.45),
        tension=strap.get("tension", 15.0), strap_model=strap.get("model", "hoop"),
        handle_angles=strap.get("handle_angles"), axial_position=strap.get("axial_position"))
