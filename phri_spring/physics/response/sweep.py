"""Load-controlled sweeps at the load cell: force-displacement curves of the cuff on the arm.

The robot applies a wrench s e_i at the load-cell origin, along or about load-cell
axis i (s [N] for i = 0, 1, 2, s [N*m] for i = 3, 4, 5), every other component zero;
s runs from 0 to a maximum in both signs. With the load-cell rotation R
(v_cuff = R v_lc) and origin p in the cuff frame (docs/model.md section 5), the
wrench on the cuff about its origin is

    W = (R F_lc,  R M_lc + p x R F_lc) ,

the equilibrium u = (t, w) of the cuff follows from the solver, and the motion of
the load-cell point, in the load-cell axes, is the rigid-body map

    u_lc = (R^T (t + w x p),  R^T w) ,

which is the displacement work-conjugate to the applied wrench (W . u = W_lc . u_lc).
The curve of axis i is s against u_lc,i, measured from the preloaded state (zero
wrench); each branch (axis and sign) is loaded from that state, 0 outward, a loading path
of its own (with friction or lift-off the answer depends on the path). Its slope at
s = 0 is 1 / (K^-1)_ii with K the tangent stiffness at the load cell
(:func:`phri_spring.physics.response.stiffness.stiffness_at_loadcell`): under load
control the other five components of the load are zero and the other five of the
motion are free, so the slope is the inverse of the compliance's diagonal, not
K_ii (which holds the other five motions at zero). This is how Schiebl et al.
(2025, Sensors 25(15):4605) loaded the upper-arm interface of 21 people: forces and
torques along and about three orthogonal axes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cuff.geometry import rigid_body_map
from ..cuff.loadcell import loadcell_to_cuff

__all__ = ["SIGNS", "axis_loads", "loadcell_motion", "LoadSweep", "sweep_loadcell_axes"]

#: the two branches of every axis: the load along +e_i, then along -e_i
SIGNS = (1, -1)


def axis_loads(max_force: float, max_moment: float, points: int) -> np.ndarray:
    """Signed load magnitudes of every axis and branch, from 0 outward.

    Parameters
    ----------
    max_force : float
        Largest force [N] (axes 0-2), > 0.
    max_moment : float
        Largest moment [N*m] (axes 3-5), > 0.
    points : int
        Samples per branch, including the zero load (>= 2).

    Returns
    -------
    ndarray, shape (6, 2, points)
        [axis, branch, sample]: s e_i with s = sign * max * k / (points - 1), k = 0..points-1.

    Examples
    --------
    >>> axis_loads(60.0, 3.0, 3)[[0, 3], 1]
    array([[  0. , -30. , -60. ],
           [  0. ,  -1.5,  -3. ]])
    """
    if int(points) < 2:
        raise ValueError("points: expected >= 2")
    ramp = np.linspace(0.0, 1.0, int(points))
    top = np.array([max_force] * 3 + [max_moment] * 3, dtype=float)
    # + 0.0 turns the negative branch's -0.0 into 0.0 (a table shows "-0" otherwise)
    return top[:, None, None] * np.array(SIGNS, dtype=float)[None, :, None] * ramp + 0.0


def loadcell_motion(u, rotation=None, position=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Motion of the load-cell point for cuff displacements u, in the load-cell axes.

    Parameters
    ----------
    u : array_like, shape (..., 6)
        Cuff displacement (t [m], w [rad]) about the cuff origin, cuff axes.
    rotation : array_like, shape (3, 3), optional
        R with v_cuff = R v_lc (identity by default).
    position : array_like, shape (3,)
        Load-cell origin in the cuff frame [m].

    Returns
    -------
    ndarray, shape (..., 6)
        (R^T (t + w x p) [m], R^T w [rad]).

    Examples
    --------
    A rotation of 0.01 rad about the arm axis moves a load cell 70 mm below it
    sideways by 0.7 mm:

    >>> loadcell_motion([0, 0, 0, 0.01, 0, 0], position=(0.0, -0.07, 0.0)).round(6)
    array([ 0.    ,  0.    , -0.0007,  0.01  ,  0.    ,  0.    ])
    """
    u = np.asarray(u, dtype=float)
    R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    at_p = rigid_body_map(np.asarray(position, dtype=float).reshape(3))   # (3, 6)
    return np.concatenate([(u @ at_p.T) @ R, u[..., 3:] @ R], axis=-1)


@dataclass(frozen=True, eq=False)
class LoadSweep:
    """Result of :func:`sweep_loadcell_axes` (arrays [axis, branch, sample], shape (6, 2, m)).

    Attributes
    ----------
    load : ndarray
        s: the force [N] (axes 0-2) or moment [N*m] (axes 3-5) applied at the load cell.
    displacement : ndarray
        u_lc,i: translation [m] or rotation [rad] of the load-cell point along or about
        the loaded axis, from the preloaded state; NaN where the solver did not converge.
    contacts : ndarray of int
        Elements (patches) in contact; 0 where not converged.
    converged : ndarray of bool
    motion : ndarray, shape (6, 2, m, 6)
        The whole motion u_lc of the load-cell point [m, rad] (NaN where not converged).
    """

    load: np.ndarray
    displacement: np.ndarray
    contacts: np.ndarray
    converged: np.ndarray
    motion: np.ndarray


def sweep_loadcell_axes(model, rotation=None, position=(0.0, 0.0, 0.0), *,
                        max_force: float = 60.0, max_moment: float = 3.0, points: int = 31,
                        max_iterations: int = 100) -> LoadSweep:
    """Solve the equilibrium under s e_i at the load cell, for every axis i and both signs.

    Parameters
    ----------
    model : SpringModel or CoupledModel
        Any model :func:`phri_spring.physics.contact.solver.solve` takes.
    rotation : array_like, shape (3, 3), optional
        Load-cell rotation R (v_cuff = R v_lc).
    position : array_like, shape (3,)
        Load-cell origin in the cuff frame [m].
    max_force, max_moment : float
        Largest force [N] and moment [N*m] applied, > 0 and finite.
    points : int
        Samples per branch, the zero load included.
    max_iterations : int
        Solver budget per sample.

    Returns
    -------
    LoadSweep
        Displacements from the preloaded state (the solution at zero wrench, u = 0 under
        the hoop strap, not under the handles).
    """
    from ..contact.active_set import FactorCache
    from ..contact.solver import solve

    for name, value in (("max_force", max_force), ("max_moment", max_moment)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name}: expected a finite number > 0, got {value!r}")
    loads = axis_loads(max_force, max_moment, points)
    W_lc = loads[..., None] * np.eye(6)[:, None, None, :]          # (6, 2, m, 6): s e_i
    W = loadcell_to_cuff(W_lc.reshape(-1, 6), rotation, position)
    # the zero-load state first: every displacement is measured from it. Each branch is a
    # loading path of its own from that state: with friction or lift-off the answer
    # depends on the path, and a branch solved after another would start where that one
    # ended (its slips and lifted patches), not from the preloaded cuff
    cache = FactorCache()
    parts = [solve(model, np.zeros((1, 6)), max_iterations=max_iterations, cache=cache)]
    per = loads.shape[-1]
    for b in range(0, len(W), per):
        cache.path_state = None
        parts.append(solve(model, W[b:b + per], max_iterations=max_iterations, cache=cache))
    u = np.concatenate([np.atleast_2d(p.u) for p in parts]).astype(float)
    ok = np.concatenate([np.atleast_1d(p.converged) for p in parts]).astype(bool)
    contact = np.concatenate([np.atleast_2d(p.contact) for p in parts])
    du = np.where((ok[1:] & ok[0])[:, None], u[1:] - u[0], np.nan)
    motion = loadcell_motion(du, rotation, position).reshape(loads.shape + (6,))
    shape = loads.shape
    i = np.arange(6)
    return LoadSweep(load=loads, displacement=motion[i, ..., i],      # component i of axis i
                     contacts=contact[1:].sum(axis=1).reshape(shape),
                     converged=(ok[1:] & ok[0]).reshape(shape), motion=motion)
