"""Load-cell wrench to cuff-frame wrench (docs/model.md section 5).

The log holds the wrench measured by the load cell, in its own axes, about its
own origin. With rotation R (v_cuff = R v_lc), origin position p in the cuff
frame and sign s (+1 ``robot_on_cuff``, -1 ``cuff_on_robot``):

    F = s R F_lc,    M = s (R M_lc + p x (R F_lc))
"""

from __future__ import annotations

import numpy as np

__all__ = ["LBF_TO_N", "rotation_from_euler_xyz", "loadcell_to_cuff", "cuff_to_loadcell",
           "convention_sign", "FORCE_UNITS", "MOMENT_UNITS"]

LBF_TO_N = 4.4482216152605
#: factor to newtons of each force unit
FORCE_UNITS = {"N": 1.0, "lbf": LBF_TO_N}
#: factor to newton-metres of each moment unit
MOMENT_UNITS = {"N*m": 1.0, "N*mm": 1e-3}


def convention_sign(convention: str) -> float:
    """+1 for ``robot_on_cuff`` (the reading is what the robot applies), -1 for ``cuff_on_robot``."""
    if convention == "robot_on_cuff":
        return 1.0
    if convention == "cuff_on_robot":
        return -1.0
    raise ValueError(f"convention: expected 'robot_on_cuff' or 'cuff_on_robot', got {convention!r}")


def rotation_from_euler_xyz(angles_deg) -> np.ndarray:
    """Rotation matrix of extrinsic x, then y, then z rotations, R = Rz Ry Rx.

    Parameters
    ----------
    angles_deg : array_like, shape (3,)
        Rotation angles about the fixed x, y and z axes [deg].

    Returns
    -------
    ndarray, shape (3, 3)
        R with v_cuff = R v_lc.
    """
    ax, ay, az = np.radians(np.asarray(angles_deg, dtype=float))
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def loadcell_to_cuff(wrench_lc, rotation=None, position=(0.0, 0.0, 0.0), sign: float = 1.0,
                     force_scale: float = 1.0, moment_scale: float = 1.0) -> np.ndarray:
    """Transform load-cell readings to the wrench W on the cuff, cuff frame, about its origin.

    Parameters
    ----------
    wrench_lc : array_like, shape (..., 6)
        (Fx, Fy, Fz, Mx, My, Mz) as logged [force unit, moment unit].
    rotation : array_like, shape (3, 3), optional
        R with v_cuff = R v_lc; identity by default.
    position : array_like, shape (3,)
        Load-cell origin in the cuff frame [m].
    sign : float
        +1 (``robot_on_cuff``) or -1 (``cuff_on_robot``).
    force_scale, moment_scale : float
        Factors to N and N*m.

    Returns
    -------
    ndarray, shape (..., 6)
        W = (F [N], M [N*m]).
    """
    w = np.asarray(wrench_lc, dtype=float)
    R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    p = np.asarray(position, dtype=float)
    out = np.empty(np.broadcast_shapes(w.shape, (6,)))
    F, M = out[..., :3], out[..., 3:]
    identity = np.array_equal(R, np.eye(3))
    np.multiply(w[..., :3], sign * force_scale, out=F)
    np.multiply(w[..., 3:], sign * moment_scale, out=M)
    if not identity:
        F[...] = F @ R.T
        M[...] = M @ R.T
    # M += p x F, written out (np.cross is slow on long arrays)
    px, py, pz = p
    if py or pz:
        M[..., 0] += py * F[..., 2] - pz * F[..., 1]
    if px or pz:
        M[..., 1] += pz * F[..., 0] - px * F[..., 2]
    if px or py:
        M[..., 2] += px * F[..., 1] - py * F[..., 0]
    return out


def cuff_to_loadcell(wrench_cuff, rotation=None, position=(0.0, 0.0, 0.0), sign: float = 1.0,
                     force_scale: float = 1.0, moment_scale: float = 1.0) -> np.ndarray:
    """Inverse of :func:`loadcell_to_cuff`: what the load cell reads for a cuff wrench."""
    W = np.asarray(wrench_cuff, dtype=float) / sign
    R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    p = np.asarray(position, dtype=float)
    F = W[..., :3]
    M = W[..., 3:] - np.cross(p, F)
    return np.concatenate([(F @ R) / force_scale, (M @ R) / moment_scale], axis=-1)
