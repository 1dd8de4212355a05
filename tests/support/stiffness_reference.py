"""The interface stiffness written out independently of the code under test (formulas of
docs/model.md sections 1-3) and the load-cell map by finite differences: shared by the
library and command-line stiffness tests."""

from __future__ import annotations

import copy
import math

import numpy as np

from phri_spring.io.config import config_from_dict
from phri_spring.physics.cuff.loadcell import loadcell_to_cuff

# --------------------------------------------------------------------------- a test config
CFG = {
    "name": "stiffness test cuff",
    "geometry": {"radius": [0.044, 0.046, 0.045], "rows": {"A": -0.025, "B": 0.0, "C": 0.03},
                 "row_width": [0.025, 0.02, 0.025],
                 "angles": {"start": 70.0, "step": 35.0, "count": 7}},
    "load_cell": {"position": [0.006, -0.07, 0.012], "euler_xyz_deg": [10.0, -5.0, 20.0]},
    "tissue": {"stiffness": {"per_row": [4000.0, 4300.0, 4500.0]}, "basis": "indenter",
               "indenter_diameter": 0.009, "poisson_ratio": 0.42},
    "cuff": {"stiffness": {"per_angle": [31250.0, 62500.0, 125000.0, 250000.0, 500000.0,
                                         1000000.0, 500000.0]}},
    "strap": {"tension": 12.0, "model": "hoop"},
}


def cfg_of(data=None):
    return config_from_dict(copy.deepcopy(CFG if data is None else data))


def rotation_xyz(deg):
    """Extrinsic x, then y, then z rotations (docs/model.md section 5), written out."""
    ax, ay, az = np.radians(deg)
    Rx = np.array([[1, 0, 0], [0, math.cos(ax), -math.sin(ax)], [0, math.sin(ax), math.cos(ax)]])
    Ry = np.array([[math.cos(ay), 0, math.sin(ay)], [0, 1, 0], [-math.sin(ay), 0, math.cos(ay)]])
    Rz = np.array([[math.cos(az), -math.sin(az), 0], [math.sin(az), math.cos(az), 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def spec_cuff_stiffness(data, arm):
    """K_s + sum_e k_e b_e b_e^T (6, 6) [SI] of a hoop-preloaded config, from the formulas."""
    g = data["geometry"]
    rows = list(g["rows"])
    xs = [g["rows"][r] for r in rows]
    nr = len(rows)
    R = np.broadcast_to(np.asarray(g["radius"], float), (nr,))
    w = np.broadcast_to(np.asarray(g["row_width"], float), (nr,))
    a = g["angles"]
    th = np.radians(a["start"] + a["step"] * np.arange(a["count"]))
    span = math.radians(a.get("width", a["step"]))
    d = data["tissue"]["indenter_diameter"]
    kind = data["tissue"]["stiffness"]["per_row"]
    kcs = data["cuff"]["stiffness"]["per_angle"]
    nu = data["tissue"]["poisson_ratio"]
    eta = 1.0 / (2.0 * (1.0 + nu))
    K = np.zeros((6, 6))
    for r in range(nr):
        for j in range(a["count"]):
            p = np.array([xs[r], R[r] * math.cos(th[j]), R[r] * math.sin(th[j])])
            n = -np.array([0.0, math.cos(th[j]), math.sin(th[j])])
            area = w[r] * R[r] * span
            kt = kind[r] * area / (math.pi * d * d / 4.0)
            kc = kcs[j]
            k = 1.0 / (1.0 / kt + 1.0 / kc) if arm == "compliant" else kc
            b = np.concatenate([n, np.cross(p, n)])
            px = np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
            B = np.hstack([np.eye(3), -px])
            P = np.eye(3) - np.outer(n, n)
            K += k * np.outer(b, b) + eta * k * B.T @ P @ B
    return K


def fd_loadcell_map(R, p, sign=1.0):
    """J (6, 6) = d W_cuff / d W_lc by central differences of loadcell_to_cuff (SI units)."""
    J = np.zeros((6, 6))
    h = 1.0
    for i in range(6):
        e = np.zeros(6)
        e[i] = h
        J[:, i] = (loadcell_to_cuff(e, R, p, sign) - loadcell_to_cuff(-e, R, p, sign)) / (2 * h)
    return J


def loadcell_point_displacement(u, R, p):
    """Translation of the load-cell origin and rotation, in the load-cell axes (6,)."""
    t, w = u[:3], u[3:]
    return np.concatenate([R.T @ (t + np.cross(w, p)), R.T @ w])
