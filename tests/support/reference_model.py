"""An independent implementation of the model of docs/model.md sections 1-6, for tests only.

Written from docs/model.md, not from the package: it never imports
``phri_spring``. It favours plainness over speed (explicit loops over
elements) and solves the equilibrium of docs/model.md section 4 by a different method
than the package:

1. minimise the energy Pi(u) with ``scipy.optimize.minimize`` (trust-exact,
   analytic gradient and the generalised Hessian of the current active set),
   in scaled variables (rotations times a length), then
2. polish exactly: solve the 6x6 linear system of the active set read from the
   minimiser and check that the set is consistent with the displacement
   (the KKT conditions of the strictly convex problem; a consistent set gives
   the exact minimiser). Elements whose compression is too close to zero to
   decide are resolved by enumerating their subsets.

:func:`solve_bruteforce` enumerates every active set (small cuffs only) and is
used to check the reference itself.
"""

from __future__ import annotations

import csv
import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

#: 1 lbf in N: the avoirdupois pound (0.45359237 kg) times standard gravity (9.80665 m/s^2)
LBF_IN_N = 0.45359237 * 9.80665


# --------------------------------------------------------------------------- small helpers
def cross_matrix(p) -> np.ndarray:
    """[p]x with [p]x v = p x v."""
    x, y, z = (float(c) for c in p)
    return np.array([[0.0, -z, y],
                     [z, 0.0, -x],
                     [-y, x, 0.0]])


def jacobian(p) -> np.ndarray:
    """B_e = [I3, -[p]x] (3 x 6): d_e = t + w x p_e = B_e u."""
    B = np.zeros((3, 6))
    B[:, :3] = np.eye(3)
    B[:, 3:] = -cross_matrix(p)
    return B


def tangent(theta_rad: float) -> np.ndarray:
    return np.array([0.0, -math.sin(theta_rad), math.cos(theta_rad)])


def _per_row(value, n_rows):
    if isinstance(value, (list, tuple, np.ndarray)):
        vals = [float(v) for v in value]
        assert len(vals) == n_rows
        return vals
    return [float(value)] * n_rows


# --------------------------------------------------------------------------- geometry
@dataclass
class Geometry:
    labels: list
    row_labels: list
    n_rows: int
    n_angles: int
    row_x: list
    row_radius: list
    row_width: list
    theta_deg: list          # per angular location
    width_deg: float
    points: np.ndarray       # (n, 3)
    normals: np.ndarray      # (n, 3)
    areas: np.ndarray        # (n,)
    b: np.ndarray            # (n, 6)
    elem_row_width: np.ndarray  # (n,)


def make_geometry(rows, radius, row_width, start, step, count, width=None) -> Geometry:
    """docs/model.md section 1. ``rows``: a mapping label -> axial position (m), proximal first."""
    row_labels = [str(k) for k in rows]
    row_x = [float(v) for v in rows.values()]
    n_rows = len(row_labels)
    R = _per_row(radius, n_rows)
    w = _per_row(row_width, n_rows)
    width_deg = float(step if width is None else width)
    theta_deg = [float(start) + j * float(step) for j in range(int(count))]
    labels, pts, nrm, areas, bs, erw = [], [], [], [], [], []
    for r in range(n_rows):
        for j in range(int(count)):
            th = math.radians(theta_deg[j])
            p = np.array([row_x[r], R[r] * math.cos(th), R[r] * math.sin(th)])
            nv = -np.array([0.0, math.cos(th), math.sin(th)])
            labels.append(f"{row_labels[r]}{j}")
            pts.append(p)
            nrm.append(nv)
            areas.append(w[r] * R[r] * math.radians(width_deg))
            # b_e = B_e^T n_e, computed from the Jacobian (not from the closed form)
            bs.append(jacobian(p).T @ nv)
            erw.append(w[r])
    return Geometry(labels=labels, row_labels=row_labels, n_rows=n_rows, n_angles=int(count),
                    row_x=row_x, row_radius=R, row_width=w, theta_deg=theta_deg,
                    width_deg=width_deg, points=np.array(pts), normals=np.array(nrm),
                    areas=np.array(areas), b=np.array(bs), elem_row_width=np.array(erw))


# --------------------------------------------------------------------------- springs
def indenter_to_element(k_ind, area, diameter=0.009):
    """docs/model.md section 2: k_t,e = k_ind,e * A_e / (pi d^2 / 4)."""
    return np.asarray(k_ind, dtype=float) * np.asarray(area, dtype=float) / (
        math.pi * diameter * diameter / 4.0)


def series(k_t, k_c):
    """1 / (1/k_t + 1/k_c), elementwise, an infinite spring dropping out."""
    out = []
    for a, c in zip(np.ravel(k_t), np.ravel(k_c)):
        a, c = float(a), float(c)
        if math.isinf(c):
            out.append(a)
        elif math.isinf(a):
            out.append(c)
        else:
            out.append(a * c / (a + c))
    return np.array(out)


def shear_matrix(geom: Geometry, ks) -> np.ndarray:
    """K_s = sum_e k_s,e B_e^T (I3 - n_e n_e^T) B_e, by a plain loop."""
    Ks = np.zeros((6, 6))
    for e in range(len(geom.labels)):
        B = jacobian(geom.points[e])
        n = geom.normals[e]
        P = np.eye(3) - np.outer(n, n)
        Ks += float(ks[e]) * (B.T @ P @ B)
    return 0.5 * (Ks + Ks.T)


def hoop_f0(geom: Geometry, tension: float) -> np.ndarray:
    """docs/model.md section 3 hoop: f0_e = T * radians(width) * w_r / sum_r(w_r); on a
    section of any shape (section 13, a ``turning`` attribute)
    T * max(psi_e, 0) * w_r / sum_r(w_r) (a band bridges a concave stretch)."""
    total_w = sum(geom.row_width)
    turning = getattr(geom, "turning", None)
    if turning is not None:
        return np.array([tension * max(psi, 0.0) * w / total_w
                         for psi, w in zip(turning, geom.elem_row_width)])
    return np.array([tension * math.radians(geom.width_deg) * w / total_w
                     for w in geom.elem_row_width])


def handles_wrench(geom: Geometry, tension: float, handle_angles=None, axial_position=None):
    """docs/model.md section 3 handles: W_pre = T (t_b - t_a, p_b x t_b - p_a x t_a)."""
    if handle_angles is None:
        half = geom.width_deg / 2.0
        handle_angles = (geom.theta_deg[0] - half, geom.theta_deg[-1] + half)
    xa = float(np.mean(geom.row_x)) if axial_position is None else float(axial_position)
    ta, tb = (math.radians(a) for a in handle_angles)
    handle = getattr(geom, "handle", None)
    if handle is not None:      # section 13: the outline at the strap, its tangent
        (pa, Ta), (pb, Tb) = handle(ta, xa), handle(tb, xa)
        return tension * np.concatenate([Tb - Ta, np.cross(pb, Tb) - np.cross(pa, Ta)])
    Rm = float(np.mean(geom.row_radius))
    pa = np.array([xa, Rm * math.cos(ta), Rm * math.sin(ta)])
    pb = np.array([xa, Rm * math.cos(tb), Rm * math.sin(tb)])
    Ta, Tb = tangent(ta), tangent(tb)
    return tension * np.concatenate([Tb - Ta, np.cross(pb, Tb) - np.cross(pa, Ta)])


# --------------------------------------------------------------------------- the model
@dataclass
class RefModel:
    geom: Geometry
    k: np.ndarray
    ks: np.ndarray
    Ks: np.ndarray
    delta0: np.ndarray
    f0: np.ndarray
    W_pre: np.ndarray
    length: float            # scale of rotations (mean radius) [m]

    @property
    def n(self):
        return len(self.geom.labels)

    def compression(self, u):
        return self.delta0 + self.geom.b @ np.asarray(u, dtype=float)

    def forces(self, u):
        return self.k * np.maximum(self.compression(u), 0.0)

    def shear(self, u):
        """s_e = k_s,e (I3 - n n^T) B_e u, shape (n, 3)."""
        out = np.zeros((self.n, 3))
        for e in range(self.n):
            n = self.geom.normals[e]
            d = jacobian(self.geom.points[e]) @ u
            out[e] = self.ks[e] * (d - n * (n @ d))
        return out

    def energy(self, u, W):
        g = np.maximum(self.compression(u), 0.0)
        return (0.5 * np.sum(self.k * g * g) + 0.5 * u @ self.Ks @ u
                - (np.asarray(W, float) + self.W_pre) @ u)


def build(geom: Geometry, k_tissue_element, k_cuff, *, arm="compliant", shear_ratio=None,
          poisson_ratio=0.45, tension=15.0, strap_model="hoop", handle_angles=None,
          axial_position=None) -> RefModel:
    """docs/model.md sections 2 and 3, from element tissue stiffness (already converted)."""
    n = len(geom.labels)
    kt = np.broadcast_to(np.asarray(k_tissue_element, float), (n,))
    kc = np.broadcast_to(np.asarray(k_cuff, float), (n,))
    if arm == "compliant":
        k = series(kt, kc)
    elif arm == "rigid":
        k = kc.astype(float).copy()
    else:
        raise ValueError(arm)
    if not np.all(np.isfinite(k) & (k > 0)):
        raise ValueError("infinitely stiff or non-positive element")
    eta = 1.0 / (2.0 * (1.0 + poisson_ratio)) if shear_ratio is None else float(shear_ratio)
    ks = eta * k
    Ks = shear_matrix(geom, ks)
    if strap_model == "hoop":
        f0 = hoop_f0(geom, tension)
        delta0 = f0 / k
        W_pre = np.zeros(6)
        for e in range(n):
            W_pre += f0[e] * geom.b[e]
    elif strap_model == "handles":
        f0 = np.zeros(n)
        delta0 = np.zeros(n)
        W_pre = handles_wrench(geom, tension, handle_angles, axial_position)
    else:
        raise ValueError(strap_model)
    return RefModel(geom=geom, k=k, ks=ks, Ks=Ks, delta0=delta0, f0=f0, W_pre=W_pre,
                    length=float(np.mean(geom.row_radius)))


def scaled_shear_conditioning(model: RefModel) -> float:
    """min/max eigenvalue of K_s with rotations scaled by the cuff's length (1 = round)."""
    inv_l = 1.0 / model.length                       # u = D z with z = (t, L w)
    D = np.diag([1, 1, 1, inv_l, inv_l, inv_l])
    ev = np.linalg.eigvalsh(D @ model.Ks @ D)
    return float(ev[0] / ev[-1])


# --------------------------------------------------------------------------- equilibrium
def _set_solution(model: RefModel, S, W):
    """u for the active set S: (sum_S k b b^T + K_s) u = W + W_pre - sum_S k delta0 b."""
    b, k = model.geom.b, model.k
    H = model.Ks.copy()
    rhs = np.asarray(W, float) + model.W_pre
    for e in np.flatnonzero(S):
        H += k[e] * np.outer(b[e], b[e])
        rhs = rhs - k[e] * model.delta0[e] * b[e]
    return np.linalg.solve(H, rhs)


def compression_tolerance(model: RefModel, u, rtol):
    """rtol times the size of the terms of delta0_e + b_e . u (its round-off scale)."""
    terms = np.abs(model.delta0) + np.abs(model.geom.b) @ np.abs(np.asarray(u, float))
    return rtol * (float(np.max(terms)) + 1e-300)


def _consistent(model: RefModel, S, u, rtol=1e-11):
    g = model.compression(u)
    tol = compression_tolerance(model, u, rtol)
    return bool(np.all(g[S] >= -tol) and np.all(g[~S] <= tol))


def solve_one(model: RefModel, W) -> np.ndarray:
    """The minimiser u* of Pi for one wrench W (6,) [N, N*m]; raises if it cannot certify it."""
    W = np.asarray(W, float)
    L = model.length
    D = np.array([1, 1, 1, 1 / L, 1 / L, 1 / L])     # u = D z
    b = model.geom.b * D                               # compression = delta0 + b z
    Ks = model.Ks * np.outer(D, D)
    r = (W + model.W_pre) * D
    k, d0 = model.k, model.delta0
    fscale = float(np.sum(k) * L + np.linalg.norm(r) + 1.0)   # energy/force scale

    def fun(z):
        g = np.maximum(d0 + b @ z, 0.0)
        return (0.5 * np.sum(k * g * g) + 0.5 * z @ Ks @ z - r @ z) / fscale

    def jac(z):
        g = np.maximum(d0 + b @ z, 0.0)
        return (b.T @ (k * g) + Ks @ z - r) / fscale

    def hess(z):
        act = (d0 + b @ z) > 0
        return (Ks + (b[act].T * k[act]) @ b[act]) / fscale

    res = minimize(fun, np.zeros(6), jac=jac, hess=hess, method="trust-exact",
                   options={"gtol": 1e-13, "maxiter": 500})
    u0 = res.x * D
    g0 = model.compression(u0)
    S = g0 > 0
    # exact polish: a few "solve, re-read the set" steps from the minimiser's set
    for _ in range(20):
        u = _set_solution(model, S, W)
        if _consistent(model, S, u):
            return u
        S_new = model.compression(u) > 0
        if np.array_equal(S_new, S):
            break
        S = S_new
    # undecided elements: compression near zero at the minimiser -> enumerate them
    amb = np.flatnonzero(np.abs(g0) <= compression_tolerance(model, u0, 1e-5))
    if len(amb) > 14:
        raise RuntimeError(f"reference: {len(amb)} undecided contacts")
    base = g0 > 0
    for bits in itertools.product([False, True], repeat=len(amb)):
        S = base.copy()
        S[amb] = bits
        u = _set_solution(model, S, W)
        if _consistent(model, S, u):
            return u
    raise RuntimeError("reference: no consistent active set found")


def solve_bruteforce(model: RefModel, W) -> np.ndarray:
    """Enumerate every active set (n <= 14) and return the consistent one."""
    n = model.n
    assert n <= 14
    found = []
    for bits in itertools.product([False, True], repeat=n):
        S = np.array(bits)
        u = _set_solution(model, S, W)
        if _consistent(model, S, u, rtol=1e-9):
            found.append(u)
    assert found, "no consistent active set"
    # several sets may be consistent when a compression is exactly zero: same u then
    for u in found[1:]:
        assert np.allclose(u, found[0], rtol=1e-8, atol=1e-14)
    return found[0]


def solve_forces(model: RefModel, wrenches) -> np.ndarray:
    """f_e for each row of an (m, 6) wrench array, shape (m, n)."""
    W = np.atleast_2d(np.asarray(wrenches, float))
    return np.array([model.forces(solve_one(model, w)) for w in W])


# --------------------------------------------------------------------------- load cell
def rotation_from_config(lc: dict) -> np.ndarray:
    if lc.get("rotation") is not None:
        return np.array(lc["rotation"], dtype=float)
    if lc.get("euler_xyz_deg") is not None:
        # scipy: lower-case 'xyz' = extrinsic rotations about the fixed x, then y, then z
        return Rotation.from_euler("xyz", lc["euler_xyz_deg"], degrees=True).as_matrix()
    return np.eye(3)


def loadcell_to_cuff(wrench_lc, lc: dict | None) -> np.ndarray:
    """docs/model.md section 5: F = s R F_lc, M = s (R M_lc + p x (R F_lc)), after unit conversion.
    """
    lc = lc or {}
    R = rotation_from_config(lc)
    p = np.array(lc.get("position", [0.0, 0.0, 0.0]), dtype=float)
    s = {"robot_on_cuff": 1.0, "cuff_on_robot": -1.0}[lc.get("convention", "robot_on_cuff")]
    fu = {"N": 1.0, "lbf": LBF_IN_N}[lc.get("force_unit", "N")]
    mu = {"N*m": 1.0, "N*mm": 0.001}[lc.get("moment_unit", "N*m")]
    out = []
    for row in np.atleast_2d(np.asarray(wrench_lc, float)):
        F = R @ (row[:3] * fu)
        M = R @ (row[3:] * mu) + np.cross(p, F)
        out.append(s * np.concatenate([F, M]))
    return np.array(out)


# --------------------------------------------------------------------------- config dicts
def resolve_stiffness(value, geom: Geometry, base_dir=None) -> np.ndarray:
    """docs/model.md section 6 value forms -> (n,) row-major array."""
    nr, na = geom.n_rows, geom.n_angles
    if isinstance(value, (int, float)):
        return np.full(nr * na, float(value))
    if isinstance(value, str):
        path = Path(value)
        if not path.is_absolute():
            path = Path(base_dir or ".") / path
        with open(path, newline="") as fh:
            table = {row["location"].strip(): float(row["stiffness_N_per_m"])
                     for row in csv.DictReader(fh)}
        return np.array([table[lab] for lab in geom.labels])
    if isinstance(value, dict) and set(value) == {"per_row"}:
        return np.array([float(value["per_row"][r]) for r in range(nr) for _ in range(na)])
    if isinstance(value, dict) and set(value) == {"per_angle"}:
        return np.array([float(value["per_angle"][j]) for _ in range(nr) for j in range(na)])
    if isinstance(value, dict):
        return np.array([float(value[lab]) for lab in geom.labels])
    if isinstance(value, list):
        return np.array([float(value[r][j]) for r in range(nr) for j in range(na)])
    raise TypeError(value)


def geometry_from_config(cfg: dict) -> Geometry:
    g = cfg["geometry"]
    a = g["angles"]
    return make_geometry(g["rows"], g["radius"], g["row_width"], a["start"], a["step"],
                         a["count"], a.get("width"))


def model_from_config(cfg: dict, arm="compliant", base_dir=None) -> RefModel:
    """The reference model of a parsed config mapping (as written to YAML)."""
    geom = geometry_from_config(cfg)
    tissue = cfg["tissue"]
    kt_cfg = resolve_stiffness(tissue["stiffness"], geom, base_dir)
    if tissue.get("basis", "indenter") == "indenter":
        kt = indenter_to_element(kt_cfg, geom.areas, tissue.get("indenter_diameter", 0.009))
    else:
        kt = kt_cfg
    kc = resolve_stiffness(cfg["cuff"]["stiffness"], geom, base_dir)
    iface = cfg.get("interface", {}) or {}
    strap = cfg.get("strap", {}) or {}
    return build(geom, kt, kc, arm=arm, shear_ratio=iface.get("shear_ratio"),
                 poisson_ratio=tissue.get("poisson_ratio", 0.45),
                 tension=strap.get("tension", 15.0), strap_model=strap.get("model", "hoop"),
                 handle_angles=strap.get("handle_angles"),
                 axial_position=strap.get("axial_position"))


def simulate(cfg: dict, wrench_lc, arm="compliant", base_dir=None) -> np.ndarray:
    """Absolute forces (m, n) [N] for load-cell readings (m, 6) in the config's units."""
    model = model_from_config(cfg, arm, base_dir)
    W = loadcell_to_cuff(wrench_lc, cfg.get("load_cell"))
    return solve_forces(model, W)
