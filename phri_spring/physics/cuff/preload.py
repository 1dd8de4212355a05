"""Strap pretension (docs/model.md sections 3 and 13)."""

from __future__ import annotations

import math

import numpy as np

from ...errors import ModelInputError
from .geometry import tangent

__all__ = ["hoop_preload", "handles_preload", "handles_preload_on", "handle_edges",
           "strap_preload"]


def hoop_preload(tension: float, span, row_width, n_rows_widths) -> np.ndarray:
    """Initial normal force of each element under the ``hoop`` strap model [N].

    f0_e = T * psi_e * w_r / sum_r(w_r) (Laplace's law: a band of tension T presses an
    element with T times the angle its tangent turns through there)

    Parameters
    ----------
    tension : float
        Strap tension T [N].
    span : array_like, shape (n,)
        Turning psi_e of the skin outline across each element [rad] (on a circle the
        element's angular width).
    row_width : array_like, shape (n,)
        Axial width w_r of each element's row [m].
    n_rows_widths : array_like, shape (n_rows,)
        The axial widths of all rows [m] (their sum normalises the split).
    """
    total = float(np.sum(n_rows_widths))
    return float(tension) * np.asarray(span, dtype=float) * np.asarray(row_width, dtype=float) / total


def handles_preload(tension: float, theta_a: float, theta_b: float, axial_position: float,
                    radius: float) -> np.ndarray:
    """Constant wrench of a strap pulling at two handles (the paper's FEA setup).

    W_pre = T * (t_b - t_a, p_b x t_b - p_a x t_a)

    Parameters
    ----------
    tension : float
        Strap tension T [N].
    theta_a, theta_b : float
        Handle angles [rad].
    axial_position : float
        Axial position of the handles [m].
    radius : float
        Radius of the handles [m].

    Returns
    -------
    ndarray, shape (6,)
        Wrench [N, N*m] about the cuff origin, in the cuff frame.
    """
    t_a, t_b = tangent(theta_a), tangent(theta_b)
    p_a = np.array([axial_position, radius * np.cos(theta_a), radius * np.sin(theta_a)])
    p_b = np.array([axial_position, radius * np.cos(theta_b), radius * np.sin(theta_b)])
    return float(tension) * np.concatenate([t_b - t_a, np.cross(p_b, t_b) - np.cross(p_a, t_a)])


def handles_preload_on(strap_section, tension: float, theta_a: float, theta_b: float,
                       axial_position: float) -> np.ndarray:
    """:func:`handles_preload` with the handles on a section of any shape (docs/model.md
    section 13): p and t the outline's point and unit tangent (toward increasing theta)
    at each handle angle [rad], at the axial position [m]."""
    p_a, t_a = strap_section.point_and_tangent(theta_a, axial_position)
    p_b, t_b = strap_section.point_and_tangent(theta_b, axial_position)
    return float(tension) * np.concatenate([t_b - t_a, np.cross(p_b, t_b) - np.cross(p_a, t_a)])


def handle_edges(geometry, handle_angles_deg=None, handle_axial_position=None):
    """Where the ``handles`` strap pulls and the ``band`` strap's ends sit: the angles
    theta_a, theta_b [rad] and the axial position [m]; by default the cuff's edges (start -
    width/2 and the last location + width/2; a free layout's extreme patch edges) and the
    mean row position."""
    if handle_angles_deg is None and geometry.free_layout:
        # a free layout's edges: its extreme patch edges in angle (a cuff opening
        # that does not wrap past 180 deg from its middle)
        mid = math.atan2(np.sin(geometry.theta).mean(), np.cos(geometry.theta).mean())
        rel = (geometry.theta - mid + math.pi) % (2 * math.pi) - math.pi
        handle_angles_deg = (math.degrees(mid + np.min(rel - geometry.span / 2)),
                             math.degrees(mid + np.max(rel + geometry.span / 2)))
    if handle_angles_deg is None:
        th = np.degrees(geometry.theta[: geometry.n_angles])
        half = np.degrees(geometry.span[0]) / 2.0
        handle_angles_deg = (th[0] - half, th[-1] + half)
    xs = geometry.x if geometry.free_layout else geometry.x[:: geometry.n_angles]
    ax = float(np.mean(xs)) if handle_axial_position is None else float(handle_axial_position)
    ta, tb = np.radians(np.asarray(handle_angles_deg, dtype=float))
    return float(ta), float(tb), ax


def strap_preload(geometry, tension: float, model: str = "hoop", handle_angles_deg=None,
                  handle_axial_position=None):
    """The strap's preload on a cuff geometry, for every arm model (docs/model.md section 3).

    Returns
    -------
    f0 : ndarray, shape (n,)
        ``hoop``: initial normal force of every element [N]; ``handles``: zeros.
    W_handles : ndarray, shape (6,), or None
        ``handles`` (and ``band``, at its preload tension): the strap's wrench on the
        cuff [N, N*m] (at :func:`handle_edges`); ``hoop``: None (the wrench follows
        from f0 and the arm model).
    """
    if model == "hoop" and geometry.hoop_share is not None:
        turning = np.maximum(geometry.turning, 0.0)
        return float(tension) * turning * geometry.hoop_share, None
    if model == "hoop":
        row_w = geometry.row_width[:: geometry.n_angles]
        turning = geometry.span if geometry.turning is None else geometry.turning
        # a band cannot pull skin outward: across a concave stretch (psi_e < 0) it bridges
        # the hollow and presses nothing, so that u = 0 stays the unloaded equilibrium
        return hoop_preload(tension, np.maximum(turning, 0.0), geometry.row_width, row_w), None
    if model in ("handles", "band"):   # band: the handles' wrench at the preload tension
        ta, tb, ax = handle_edges(geometry, handle_angles_deg, handle_axial_position)
        if geometry.strap_section is not None:
            return np.zeros(geometry.n), handles_preload_on(geometry.strap_section, tension,
                                                            ta, tb, ax)
        if geometry.handles_radius is None:
            raise ModelInputError("the handles strap model needs the limb's outline at the "
                                  "strap (this geometry has none); use strap.model: hoop",
                                  "strap_model")
        return np.zeros(geometry.n), handles_preload(tension, ta, tb, ax,
                                                     geometry.handles_radius)
    raise ValueError(f"strap model: expected 'hoop', 'handles' or 'band', got {model!r}")
