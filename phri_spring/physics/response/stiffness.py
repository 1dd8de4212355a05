"""Interface stiffness: the 6x6 tangent stiffness of the cuff on the arm.

At an equilibrium u* with contact set S, a small extra displacement du of the
cuff needs the extra wrench dW = K du, with the tangent stiffness

    K = K_s + sum_{e in S} k_e b_e b_e^T          (docs/model.md, sections 2 and 4)

in the cuff frame, about the cuff origin, in SI units: blocks N/m (force per
translation), N/rad (force per rotation), N*m/m and N*m/rad.  Seen from the
load cell (rotation R with v_cuff = R v_lc, origin p in the cuff frame), a cuff
wrench is W = J W_lc with J = [[R, 0], [P R, R]] (P the cross-product matrix of
p), and work conjugacy (W . u = W_lc . u_lc) gives u_lc = J^T u and

    K_lc = J^-1 K J^-T .
"""

from __future__ import annotations

import numpy as np

from ..cuff.geometry import skew

__all__ = ["interface_stiffness", "stiffness_at_loadcell", "principal_stiffness"]


def interface_stiffness(model, wrench=None, *, max_iterations: int = 100) -> np.ndarray:
    """Tangent stiffness K (6, 6) of the cuff on the arm at the equilibrium under ``wrench``.

    Parameters
    ----------
    model : SpringModel or CoupledModel
        An assembled model (any arm).
    wrench : array_like, shape (6,), optional
        Wrench on the cuff, cuff frame [N, N*m]; default zero (the preloaded state).
    max_iterations : int
        Solver budget.

    Returns
    -------
    ndarray, shape (6, 6)
        dW/du in the cuff frame about its origin [N/m, N/rad; N*m/m, N*m/rad].

    Raises
    ------
    RuntimeError
        If the equilibrium does not converge.
    """
    from ..contact.solver import solve

    W = np.zeros(6) if wrench is None else np.asarray(wrench, dtype=float)
    sol = solve(model, W, max_iterations=max_iterations)
    if not bool(sol.converged):
        raise RuntimeError("the equilibrium did not converge; no tangent stiffness")
    return model.tangent_stiffness(sol.u, sol.contact)


def stiffness_at_loadcell(K, rotation=None, position=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Express a cuff-frame stiffness (6, 6) at the load-cell origin in the load-cell axes.

    Parameters
    ----------
    K : array_like, shape (6, 6)
        Stiffness in the cuff frame about the cuff origin (SI).
    rotation : array_like, shape (3, 3), optional
        R with v_cuff = R v_lc (identity by default).
    position : array_like, shape (3,)
        Load-cell origin in the cuff frame [m].

    Returns
    -------
    ndarray, shape (6, 6)
        K_lc = J^-1 K J^-T (the sign convention cancels).

    Examples
    --------
    A pure translational spring of 1000 N/m seen from 0.1 m away gains rotational
    stiffness k d^2 = 10 N*m/rad about the axes across the offset:

    >>> K = np.diag([1000.0, 1000.0, 1000.0, 0.0, 0.0, 0.0])
    >>> np.round(np.diag(stiffness_at_loadcell(K, position=(0.0, -0.1, 0.0))), 9)
    array([1000., 1000., 1000.,   10.,    0.,   10.])
    """
    R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    P = skew(np.asarray(position, dtype=float).reshape(3))
    Jinv = np.zeros((6, 6))
    Jinv[:3, :3] = R.T
    Jinv[3:, 3:] = R.T
    Jinv[3:, :3] = -R.T @ P
    K = np.asarray(K, dtype=float)
    out = Jinv @ K @ Jinv.T
    return 0.5 * (out + out.T)


def principal_stiffness(K) -> tuple:
    """Principal values of the translational and rotational blocks of a stiffness (6, 6).

    A 6x6 stiffness mixes units, so its eigenvalues have no physical meaning; the
    3x3 force-per-translation block and the 3x3 moment-per-rotation block do.

    Parameters
    ----------
    K : array_like, shape (6, 6)
        Stiffness in SI units (e.g. from :func:`stiffness_at_loadcell`).

    Returns
    -------
    translational : ndarray, shape (3,)
        Eigenvalues of K[:3, :3], ascending [N/m].
    rotational : ndarray, shape (3,)
        Eigenvalues of K[3:, 3:], ascending [N*m/rad].
    """
    K = np.asarray(K, dtype=float)
    Kt = 0.5 * (K[:3, :3] + K[:3, :3].T)
    Kr = 0.5 * (K[3:, 3:] + K[3:, 3:].T)
    return np.linalg.eigvalsh(Kt), np.linalg.eigvalsh(Kr)
