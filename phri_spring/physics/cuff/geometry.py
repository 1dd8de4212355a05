"""Element geometry of a cuff (docs/model.md sections 1 and 13).

Cuff frame: origin on the arm axis, x along the arm axis (proximal to distal);
an angle theta is measured in the y-z plane from +y toward +z. Elements are
rows (axial) x angular locations, ordered row-major (A0..A6, B0..B6, ...).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["CuffGeometry", "patch_frames", "cuff_geometry", "section_geometry", "skew", "rigid_body_map",
           "element_jacobians", "contact_vectors", "tangent"]


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
        Distance of each element's point from the arm axis [m] (the row's radius on a
        circular section).
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
        Element areas A_e [m^2] (w_r R_r span on a circular section).
    b : ndarray, shape (n, 6)
        Contact vectors b_e = (n_e, p_e x n_e) [-, m].
    turning : ndarray, shape (n,)
        Angle psi_e through which the skin outline's tangent turns across the element
        [rad] (the span on a circle); the hoop preload is T psi_e w_r / sum_r w_r.
    strap_section : StrapSection or None
        The outline at any axial position, where the ``handles`` strap model puts its
        handles; None on the circular cuff of section 1 (handles on the mean radius).
    handles_radius : float or None
        The circular cuff's handle radius (the mean row radius) [m]; None otherwise.
    hoop_share : ndarray, shape (n,), or None
        A free layout's (docs/model.md section 14) share of the hoop preload per unit
        turning: f0_e = T psi_e hoop_share_e; None on a grid (w_r / sum_r w_r).
    free_layout : bool
        True for sensor patches placed one by one (``cuff.patches``): one "row" holding
        every element, and no rows x angles structure to rely on.
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
    turning: np.ndarray = None
    strap_section: object = None
    handles_radius: float | None = None
    hoop_share: np.ndarray = None
    free_layout: bool = False

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

    @property
    def circumferential(self) -> np.ndarray:
        """Unit tangent ``c_e = (n_e x e_x) / |n_e x e_x|`` of every element, shape (n, 3): along
        the skin outline toward increasing angle theta."""
        c = np.cross(self.normals, np.array([1.0, 0.0, 0.0]))
        return c / np.linalg.norm(c, axis=1, keepdims=True)

    @property
    def meridian(self) -> np.ndarray:
        """Unit tangent a_e = c_e x n_e of every element, shape (n, 3): along the skin's
        meridian toward +x (distally). +x itself on an untapered limb; (a_e, c_e, n_e) is
        orthonormal (the ``axial`` and ``circumferential`` shear directions)."""
        return np.cross(self.circumferential, self.normals)

    @classmethod
    def from_elements(cls, labels, row_labels, n_rows: int, n_angles: int, x, row_width, theta,
                      span, points, normals, areas, turning, strap_section=None):
        """A geometry from explicit per-element arrays (e.g. computed from a surface scan).

        Parameters
        ----------
        labels, row_labels : sequence of str
            Element labels (row-major) and row labels.
        n_rows, n_angles : int
        x, row_width, theta, span : array_like, shape (n,)
            Axial position [m], row width [m], angle [rad] and angular span [rad].
        points : array_like, shape (n, 3)
            Surface points p_e [m].
        normals : array_like, shape (n, 3)
            Inward normals n_e (normalised here).
        areas : array_like, shape (n,)
            Element areas A_e [m^2].
        turning : array_like, shape (n,)
            Turning psi_e of the outline's tangent across each element [rad].
        strap_section : StrapSection, optional
            The outline at any axial position (needed by the ``handles`` strap model).
        """
        n = len(labels)
        f = lambda a, shape: np.array(a, dtype=float).reshape(shape)  # noqa: E731
        points, normals = f(points, (n, 3)), f(normals, (n, 3))
        normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
        if n != int(n_rows) * int(n_angles):
            raise ValueError(f"{n} labels for {n_rows} rows x {n_angles} angles")
        return cls(labels=tuple(labels), row_labels=tuple(row_labels), n_rows=int(n_rows),
                   n_angles=int(n_angles), x=f(x, (n,)),
                   radius=np.hypot(points[:, 1], points[:, 2]), row_width=f(row_width, (n,)),
                   theta=f(theta, (n,)), span=f(span, (n,)), points=points, normals=normals,
                   areas=f(areas, (n,)), b=contact_vectors(points, normals),
                   turning=f(turning, (n,)), strap_section=strap_section)


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


def _rows(row_x, angle_count, row_labels):
    """(row_x (n_rows,), n_rows, n_angles, row labels) of a grid, checked; labels default
    to A, B, C, ..."""
    row_x = np.atleast_1d(np.asarray(row_x, dtype=float))
    n_rows, n_ang = row_x.size, int(angle_count)
    if n_rows < 1 or n_ang < 1:
        raise ValueError("a cuff needs at least one row and one angular location")
    if row_labels is None:
        row_labels = [chr(ord("A") + i) for i in range(n_rows)]
    return row_x, n_rows, n_ang, tuple(str(r) for r in row_labels)


def cuff_geometry(row_x, radius, row_width, angle_start_deg: float, angle_step_deg: float,
                  angle_count: int, angle_width_deg: float | None = None,
                  row_labels=None, taper_deg: float = 0.0) -> CuffGeometry:
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
    taper_deg : float, optional
        Taper half-angle alpha [deg] (docs/model.md section 13): n_e tilts toward -x by
        alpha and A_e grows by 1 / cos(alpha). 0: the cylinder of section 1.

    Returns
    -------
    CuffGeometry
    """
    row_x, n_rows, n_ang, row_labels = _rows(row_x, angle_count, row_labels)
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
    areas = we * Re * span
    if taper_deg:
        ca, sa = math.cos(math.radians(taper_deg)), math.sin(math.radians(taper_deg))
        normals = -np.stack([np.full_like(c, sa), ca * c, ca * s], axis=1)
        areas = areas / ca
    else:
        normals = -np.stack([np.zeros_like(c), c, s], axis=1)
    labels = tuple(f"{r}{j}" for r in row_labels for j in range(n_ang))
    return CuffGeometry(labels=labels, row_labels=row_labels, n_rows=n_rows, n_angles=n_ang,
                        x=x, radius=Re, row_width=we, theta=theta, span=span, points=points,
                        normals=normals, areas=areas, b=contact_vectors(points, normals),
                        turning=span, handles_radius=float(np.mean(R)))


def section_geometry(row_x, sections, row_width, angle_start_deg: float, angle_step_deg: float,
                     angle_count: int, angle_width_deg: float | None = None, row_labels=None,
                     taper_deg: float = 0.0) -> CuffGeometry:
    """The element geometry on rows of any star-shaped section (docs/model.md section 13).

    For element (r, j) at theta_j spanning ``width``: p_e on row r's outline on the ray at
    theta_j; (m_y, m_z) the outline's outward unit normal there; s_e its arc and psi_e its
    turning between the rays at theta_j -/+ width / 2; with the taper half-angle alpha,
    n_e = -(sin alpha, cos alpha m_y, cos alpha m_z) and A_e = w_r s_e / cos alpha.

    Parameters
    ----------
    row_x : array_like, shape (n_rows,)
        Axial position x_r of each row [m].
    sections : Section or sequence of Section (one per row)
        The rows' outlines (:mod:`phri_spring.physics.limb.sections`).
    row_width, angle_start_deg, angle_step_deg, angle_count, angle_width_deg, row_labels
        As :func:`cuff_geometry`.
    taper_deg : float, optional
        Taper half-angle alpha [deg], positive when the limb narrows toward +x.

    Returns
    -------
    CuffGeometry
    """
    from ..limb.sections import StrapSection

    row_x, n_rows, n_ang, row_labels = _rows(row_x, angle_count, row_labels)
    single = not isinstance(sections, (list, tuple))
    secs = [sections] * n_rows if single else list(sections)
    if len(secs) != n_rows:
        raise ValueError(f"sections: expected one per row ({n_rows}), got {len(secs)}")
    w = _per_row(row_width, n_rows, "row_width")
    width = np.radians(angle_step_deg if angle_width_deg is None else angle_width_deg)
    theta_row = np.radians(angle_start_deg + angle_step_deg * np.arange(n_ang))
    ca, sa = math.cos(math.radians(taper_deg)), math.sin(math.radians(taper_deg))
    pts, nrm, arc, turn = [], [], [], []
    for r, sec in enumerate(secs):
        yz = sec.point(theta_row)
        m = sec.outward_normal(theta_row)
        pts.append(np.column_stack([np.full(n_ang, row_x[r]), yz]))
        nrm.append(-np.column_stack([np.full(n_ang, sa), ca * m]))
        arc.append(sec.arc(theta_row - width / 2, theta_row + width / 2))
        turn.append(sec.turning(theta_row - width / 2, theta_row + width / 2))
    we = np.repeat(w, n_ang)
    labels = tuple(f"{r}{j}" for r in row_labels for j in range(n_ang))
    strap = StrapSection(row_x[:1] if single else row_x, secs[:1] if single else secs)
    return CuffGeometry.from_elements(
        labels, row_labels, n_rows, n_ang, x=np.repeat(row_x, n_ang), row_width=we,
        theta=np.tile(theta_row, n_rows), span=np.full(n_rows * n_ang, width),
        points=np.vstack(pts), normals=np.vstack(nrm), areas=we * np.concatenate(arc) / ca,
        turning=np.concatenate(turn), strap_section=strap)


def patch_frames(geometry: CuffGeometry) -> np.ndarray:
    """Local axes of every patch, shape (n, 3, 3): rows normal n_e, axial a, circumferential c_e.

    n_e points into the arm; a = the skin's meridian toward +x (+x itself on an untapered
    limb); c_e = the direction of increasing angle theta (the geometry's ``meridian`` and
    ``circumferential``).
    """
    return np.stack([geometry.normals, geometry.meridian, geometry.circumferential], axis=1)
