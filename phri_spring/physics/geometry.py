"""Element geometry of a cylindrical cuff (docs/model.md section 1).

Cuff frame: origin on the arm axis, x along the arm axis (proximal to distal);
an angle theta is measured in the y-z plane from +y toward +z. Elements are
rows (axial) x angular locations, ordered row-major (A0..A6, B0..B6, ...).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CuffGeometry", "cuff_geometry", "skew", "rigid_body_map", "element_jacobians",
           "contact_vectors", "tangent"]


@dataclass(frozen=True, eq=False)
class CuffGeometry:
    """Arrays describing the n = rows x angles elements of a cuff.

    Attributes
    ----------
    labels : tuple of str
        Element labels, row label + angular index (``A0`` ... ``C6``), row-major.
    row_labels : tuple of str
        Row labels, proximal first.
    n_rows, n_angles : int
        Number of rows and of angular locations.
    x : ndarray, shape (n,)
        Axial position of each element [m].
    radius : ndarray, shape (n,)
        Radius of each element's row [m].
    row_width : ndarray, shape (n,)
        Axial width of each element's row [m].
    theta : ndarray, shape (n,)
        Angle of each element [rad].
    span : ndarray, shape (n,)
        Angular width of each element [rad].
    points : ndarray, shape (n, 3)
        Surface points p_e [m].
    normals : ndarray, shape (n, 3)
        Inward unit normals n_e (the cuff pushes the arm along n_e).
    areas : ndarray, shape (n,)
        Element areas A_e = w_r R_r span [m^2].
    b : ndarray, shape (n, 6)
        Contact vectors b_e = (n_e, p_e x n_e) [-, m].
    """

    labels: tuple
    row_labels: tuple
    n_rows: int
    n_angles: int
    x: np.ndarray
    radius: np.ndarray
    row_width: np.ndarray
    theta: np.ndarray
    span: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    b: np.ndarray

    @property
    def n(self) -> int:
        """Number of elements."""
        return len(self.labels)

    @property
    def row_index(self) -> np.ndarray:
        return np.repeat(np.arange(self.n_rows), self.n_angles)

    @property
    def angle_index(self) -> np.ndarray:
        return np.tile(np.arange(self.n_angles), self.n_rows)


def skew(p: np.ndarray) -> np.ndarray:
    """Cross-product matrices [p]x with [p]x v = p x v.

    Parameters
    ----------
    p : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    p = np.asarray(p, dtype=float)
    out = np.zeros(p.shape[:-1] + (3, 3))
    out[..., 0, 1] = -p[..., 2]
    out[..., 0, 2] = p[..., 1]
    out[..., 1, 0] = p[..., 2]
    out[..., 1, 2] = -p[..., 0]
    out[..., 2, 0] = -p[..., 1]
    out[..., 2, 1] = p[..., 0]
    return out


def rigid_body_map(points, rotations: bool = False) -> np.ndarray:
    """Map of a small rigid-body motion u = (t, w) to the motion of points attached to the body.

    A translation t [m] and a small rotation w [rad] about the origin move a point p
    by t + w x p = t - [p]x w; a body attached at p also turns by w.

    Parameters
    ----------
    points : array_like, shape (..., 3)
        Points p [m], in the frame of t and w.
    rotations : bool, optional
        False: the displacement of each point only; True: followed by the rotation w.

    Returns
    -------
    ndarray, shape (..., 3, 6), or (..., 6, 6) with ``rotations``
        [[I3, -[p]x]] or [[I3, -[p]x], [0, I3]] per point [-, m; -, -].

    Examples
    --------
    A rotation about z (w = e_z) moves the point on +y toward -x:

    >>> rigid_body_map([[0.0, 1.0, 0.0]]) @ np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    array([[-1.,  0.,  0.]])
    """
    p = np.asarray(points, dtype=float)
    k = 6 if rotations else 3
    out = np.zeros(p.shape[:-1] + (k, 6))
    out[..., :3, :3] = np.eye(3)
    out[..., :3, 3:] = skew(-p)       # -[p]x = [-p]x
    if rotations:
        out[..., 3:, 3:] = np.eye(3)
    return out


def element_jacobians(points: np.ndarray) -> np.ndarray:
    """B_e = [I3, -[p_e]x]: cuff displacement u = (t, w) to point displacement d_e = B_e u.

    The :func:`rigid_body_map` of the points.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Points on the cuff [m].

    Returns
    -------
    ndarray, shape (n, 3, 6)
    """
    return rigid_body_map(points)


def contact_vectors(points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """b_e = B_e^T n_e = (n_e, p_e x n_e), shape (n, 6)."""
    points = np.asarray(points, dtype=float)
    normals = np.asarray(normals, dtype=float)
    return np.hstack([normals, np.cross(points, normals)])


def tangent(theta) -> np.ndarray:
    """Unit tangent t(theta) = (0, -sin theta, cos theta) [-], theta in radians."""
    theta = np.asarray(theta, dtype=float)
    return np.stack([np.zeros_like(theta), -np.sin(theta), np.cos(theta)], axis=-1)


def _per_row(value, n_rows: int, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        return np.full(n_rows, float(arr))
    if arr.shape != (n_rows,):
        raise ValueError(f"{name}: expected a scalar or {n_rows} values (one per row), "
                         f"got shape {arr.shape}")
    return arr


def cuff_geometry(row_x, radius, row_width, angle_start_deg: float, angle_step_deg: float,
                  angle_count: int, angle_width_deg: float | None = None,
                  row_labels=None) -> CuffGeometry:
    """Build the element geometry of docs/model.md section 1.

    Parameters
    ----------
    row_x : array_like, shape (n_rows,)
        Axial position x_r of each row [m], proximal first.
    radius : float or array_like, shape (n_rows,)
        Cuff radius R_r [m].
    row_width : float or array_like, shape (n_rows,)
        Axial width w_r of each row [m].
    angle_start_deg, angle_step_deg : float
        theta_j = start + j * step [deg].
    angle_count : int
        Number of angular locations (>= 1).
    angle_width_deg : float, optional
        Angular width of an element [deg]; default ``angle_step_deg``.
    row_labels : sequence of str, optional
        Row labels; default A, B, C, ...

    Returns
    -------
    CuffGeometry
    """
    row_x = np.atleast_1d(np.asarray(row_x, dtype=float))
    n_rows = row_x.size
    n_ang = int(angle_count)
    if n_rows < 1 or n_ang < 1:
        raise ValueError("a cuff needs at least one row and one angular location")
    if row_labels is None:
        row_labels = [chr(ord("A") + i) for i in range(n_rows)]
    row_labels = tuple(str(r) for r in row_labels)
    R = _per_row(radius, n_rows, "radius")
    w = _per_row(row_width, n_rows, "row_width")
    width = angle_step_deg if angle_width_deg is None else angle_width_deg
    theta_row = np.radians(angle_start_deg + angle_step_deg * np.arange(n_ang))

    x = np.repeat(row_x, n_ang)
    Re = np.repeat(R, n_ang)
    we = np.repeat(w, n_ang)
    theta = np.tile(theta_row, n_rows)
    span = np.full(x.shape, np.radians(width))
    c, s = np.cos(theta), np.sin(theta)
    points = np.stack([x, Re * c, Re * s], axis=1)
    normals = -np.stack([np.zeros_like(c), c, s], axis=1)
    areas = we * Re * span
    labels = tuple(f"{r}{j}" for r in row_labels for j in range(n_ang))
    return CuffGeometry(labels=labels, row_labels=row_labels, n_rows=n_rows, n_angles=n_ang,
                        x=x, radius=Re, row_width=we, theta=theta, span=span, points=points,
                        normals=normals, areas=areas, b=contact_vectors(points, normals))
