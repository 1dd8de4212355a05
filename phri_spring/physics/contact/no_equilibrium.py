"""Why a sample with friction has no answer (docs/model.md section 12.7).

With Coulomb friction (``interface.friction_coefficient`` mu) a wrench can be beyond
what the interface holds: the cuff would slide along the arm, twist around it or come
off it, and the solvers flag the sample (NaN forces, ``converged`` False). This module
says why, from the model's geometry and forces alone, the same for every arm model:

* **friction capacity.** The normal forces of a cuff around the arm act through the
  arm's axis (x): they carry no axial force F_a and no torsion M_a about the axis. Those
  two are carried by the tangential forces alone, each ``|t_e| <= mu f_n,e``, so an element
  contributes (t_axial, t_circ) to (F_a, M_a / R) (R the radius at the elements) and the
  set the interface can hold is the disc sqrt(F_a^2 + (M_a/R)^2) <= mu sum_e f_n,e. The
  normal forces are those the model gives the same wrench with bonded ties (mu -> inf,
  the paper's model): what the wrench presses into the arm. Beyond the disc the reason
  is the larger of the two demands: ``torsion beyond friction capacity`` with its
  shortfall ``|M_a| - R sqrt((mu sum f_n)^2 - F_a^2)`` [N*m], or ``axial force beyond friction
  capacity`` with ``|F_a| - sqrt((mu sum f_n)^2 - (M_a/R)^2)`` [N]: how much less would be
  held, the other demand kept.
* **the strap.** Contacts only push; what holds the cuff against a pull is the strap's
  preload (the constant W_pre). The radial force and the bending moments of W + W_pre
  must be a sum of element pushes f_e b_e with f_e >= 0; when they are not (a pull off
  through the cuff's open side beyond the preload), the reason is ``pull beyond the
  strap`` and the shortfall the distance [N] of that wrench from the pushes' cone (its
  moments counted as forces at the radius R), by non-negative least squares.
* **not converged**: none of those; the solver did not settle (shortfall NaN).

For the coupled arm the patches also carry moments about their centres, which friction
does not limit: the capacity above counts the tangential forces only, so it is a lower
bound of what that arm holds.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["REASONS", "NONE", "TORSION", "AXIAL", "PULL", "NOT_CONVERGED", "explain",
           "arm_radius", "friction_shortfall"]

NONE, TORSION, AXIAL, PULL, NOT_CONVERGED = range(5)
#: the reason of each code ("" for a sample with an answer)
REASONS = ("", "torsion beyond friction capacity", "axial force beyond friction capacity",
           "pull beyond the strap", "not converged")
#: a demand beyond capacity by less than this share of the wrench is round-off
_RTOL = 1e-9


def arm_radius(geometry) -> float:
    """Mean distance [m] of the elements' centres from the arm's axis (x)."""
    p = np.asarray(geometry.points, dtype=float)
    return float(np.mean(np.hypot(p[:, 1], p[:, 2])))


def friction_shortfall(r, normal_sum, mu, radius):
    """(code, shortfall [N], shortfall [N*m]) of wrenches r (m, 6) on the cuff (applied plus
    the strap's) against friction's capacity mu * normal_sum (m,) [N]: TORSION or AXIAL
    where sqrt(F_a^2 + (M_a/R)^2) exceeds it (NONE otherwise; NaN normal sums give NONE)."""
    r = np.atleast_2d(np.asarray(r, dtype=float))
    Fa, Mr = r[:, 0], r[:, 3] / radius
    cap = mu * np.asarray(normal_sum, dtype=float)
    demand = np.hypot(Fa, Mr)
    tol = _RTOL * (np.abs(r).max(axis=1) + 1e-300)
    with np.errstate(invalid="ignore"):
        over = demand > cap + tol
        torsion = over & (np.abs(Mr) >= np.abs(Fa))
        axial = over & ~torsion
        code = np.where(torsion, TORSION, np.where(axial, AXIAL, NONE)).astype(np.int8)
        s_N = np.where(axial, np.abs(Fa) - np.sqrt(np.maximum(cap ** 2 - Mr ** 2, 0.0)), np.nan)
        s_Nm = np.where(torsion, radius * (np.abs(Mr) - np.sqrt(np.maximum(cap ** 2 - Fa ** 2,
                                                                           0.0))), np.nan)
    return code, s_N, s_Nm


def pull_shortfall(b, r, radius):
    """Distance [N] of the radial force and bending moments of wrenches r (m, 6) from the
    cone of element pushes b (n, 6) (moments over ``radius``), per row."""
    from scipy.optimize import nnls  # on demand: simulate imports this module at start-up
    cols = [1, 2, 4, 5]
    w = np.array([1.0, 1.0, 1.0 / radius, 1.0 / radius])
    A = (np.asarray(b, dtype=float)[:, cols] * w).T
    out = np.empty(len(r))
    for i, row in enumerate(np.atleast_2d(r)):
        out[i] = nnls(A, row[cols] * w)[1]
    return out


def _bonded_normal_sum(model, W):
    """Sum of the normal forces [N] the model gives wrenches W (m, 6) with bonded ties."""
    from .solver import solve

    # bonded ties everywhere: the coupled arm without friction would run its lift-off cone;
    # a model stiffened by activation is estimated on its unactivated layer (the capacity's
    # normal forces move only through the cuff's share of the compliance)
    model = getattr(model, "base", model)
    changes = {"friction_coefficient": None}
    if hasattr(model, "lift_off"):
        changes["lift_off"] = False
    bonded = dataclasses.replace(model, **changes)
    sol = solve(bonded, W)
    total = np.sum(sol.forces, axis=1)
    return np.where(sol.converged, total, np.nan)


def explain(model, W, converged):
    """Why each sample of wrenches W (m, 6) on the cuff has no answer.

    Parameters
    ----------
    model : SpringModel or CoupledModel with ``friction_coefficient`` set
    W : ndarray, shape (m, 6)
        Wrenches on the cuff [N, N*m] (the strap's W_pre is added here).
    converged : ndarray of bool, shape (m,)

    Returns
    -------
    code : ndarray of int8, shape (m,)
        An index into :data:`REASONS` (NONE where converged).
    shortfall_N, shortfall_Nm : ndarray, shape (m,)
        The shortfall of the reason in its unit [N] or [N*m]; NaN where it is in the other
        unit, for NONE and for NOT_CONVERGED.
    """
    W = np.atleast_2d(np.asarray(W, dtype=float))
    m = len(W)
    code = np.zeros(m, dtype=np.int8)
    s_N = np.full(m, np.nan)
    s_Nm = np.full(m, np.nan)
    bad = np.flatnonzero(~np.asarray(converged, dtype=bool))
    if not bad.size:
        return code, s_N, s_Nm
    with np.errstate(over="ignore", invalid="ignore"):
        r = W[bad] + model.W_pre
    finite = np.isfinite(r).all(axis=1)
    mu = float(model.friction_coefficient)
    radius = arm_radius(model.geometry)
    fsum = np.full(len(bad), np.nan)
    if finite.any():
        fsum[finite] = _bonded_normal_sum(model, W[bad][finite])
    c, a, t = friction_shortfall(np.where(finite[:, None], r, 0.0), fsum, mu, radius)
    c[~finite] = NONE
    rest = np.flatnonzero((c == NONE) & finite)
    if rest.size:
        gap = pull_shortfall(model.geometry.b, r[rest], radius)
        scale = np.abs(r[rest]).max(axis=1) + np.abs(model.W_pre).max()
        pull = gap > 1e-6 * scale
        c[rest[pull]] = PULL
        a[rest[pull]] = gap[pull]
    c[c == NONE] = NOT_CONVERGED
    code[bad], s_N[bad], s_Nm[bad] = c, a, t
    return code, s_N, s_Nm
