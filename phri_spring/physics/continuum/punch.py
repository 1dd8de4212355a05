"""Flat-punch FE: indenter stiffness of a tissue layer on the bone, and its inverse.

A rigid, frictionless flat cylindrical punch on a linear elastic layer bonded to a
rigid base (axisymmetric quadratic FE), to turn the indenter stiffness measured on
an arm into the Young's modulus of the tissue layer (docs/model.md section 10), with
Sneddon's half-space solution as its thick-layer limit.

Everything is linear in Young's modulus: the FE is solved for E = 1 Pa and scaled.
scikit-fem is an optional dependency (extra ``fe``), imported only inside the
functions that need it.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import scipy.sparse.linalg as spla

from .mesh import graded, import_skfem, check_material

__all__ = ["PUNCH_RADIUS", "sneddon_punch_stiffness", "flat_punch_stiffness",
           "modulus_from_indenter"]

#: Radius of the paper's 9 mm flat indenter [m].
PUNCH_RADIUS = 0.0045


def sneddon_punch_stiffness(young_modulus, poisson_ratio, radius=PUNCH_RADIUS):
    """Sneddon's flat punch on a half-space: 2 a E / (1 - nu^2) [N/m]."""
    return 2.0 * radius * np.asarray(young_modulus, float) / (1.0 - float(poisson_ratio) ** 2)


@lru_cache(maxsize=64)
def _punch_stiffness_per_pascal(thickness, poisson_ratio, radius, level):
    """Flat-punch stiffness [N/m] of the layer for E = 1 Pa (the FE of
    :func:`flat_punch_stiffness`)."""
    sk = import_skfem()
    a, t = radius, thickness
    # element sizes: h0 at the punch edge, growing geometrically away from it
    h0 = a / (100.0 * level ** 2)
    q = 1.25 ** (1.0 / level)
    inner = a - graded(a, h0, q)[::-1]
    inner = np.concatenate([[0.0], inner[1:], [a]]) if inner[0] > 0 else inner
    outer = a + graded(10.0 * max(t, a), h0, q)
    rn = np.unique(np.concatenate([[0.0], inner, [a], outer]))
    zn = np.unique(np.concatenate([[0.0], -graded(t, h0, q)]))
    zn[0] = -t
    m = sk["MeshQuad"].init_tensor(rn, zn)
    e = sk["ElementVector"](sk["ElementQuad2"]())
    ib = sk["Basis"](m, e, intorder=4)
    lam, mu = sk["lame_parameters"](1.0, poisson_ratio)

    @sk["BilinearForm"]
    def axi(u, v, w):
        r = w.x[0]
        eu = (u.grad[0][0], u.grad[1][1], u[0] / r)
        ev = (v.grad[0][0], v.grad[1][1], v[0] / r)
        gu = u.grad[0][1] + u.grad[1][0]
        gv = v.grad[0][1] + v.grad[1][0]
        tru, trv = eu[0] + eu[1] + eu[2], ev[0] + ev[1] + ev[2]
        return 2 * np.pi * r * (lam * tru * trv
                                + 2 * mu * (eu[0] * ev[0] + eu[1] * ev[1] + eu[2] * ev[2])
                                + mu * gu * gv)

    K = sk["asm"](axi, ib).tocsr()
    loc = ib.doflocs
    comp = np.tile(np.arange(2), ib.N // 2)
    tol = 1e-12 * max(a, t)
    base = np.nonzero(np.abs(loc[1] + t) <= tol)[0]
    axis_r = np.nonzero((np.abs(loc[0]) <= tol) & (comp == 0))[0]
    punch = np.nonzero((np.abs(loc[1]) <= tol) & (loc[0] <= a + tol) & (comp == 1))[0]
    D = np.unique(np.concatenate([base, axis_r, punch]))
    u = np.zeros(ib.N)
    u[punch] = -1.0
    I = np.setdiff1d(np.arange(ib.N), D)
    u[I] = spla.spsolve(K[I][:, I].tocsc(), -(K[I][:, D] @ u[D]))
    reaction = K[punch] @ u
    return float(-reaction.sum())


def flat_punch_stiffness(thickness, young_modulus, poisson_ratio, radius=PUNCH_RADIUS, *,
                         level: int = 2) -> float:
    """Stiffness of a rigid flat cylindrical punch on a layer bonded to a rigid base.

    Axisymmetric quadratic FE (9-node quadrilaterals, ``ElementQuad2``), mesh graded
    toward the punch edge; the punch face is frictionless (radial displacement free under
    it), the rest of the top surface is traction-free, the layer is bonded to the base
    and extends 10 max(t, a) beyond the punch edge (outer rim traction-free).

    Parameters
    ----------
    thickness : float
        Layer thickness h [m] > 0.
    young_modulus : float
        E [Pa] > 0 (the stiffness is linear in E).
    poisson_ratio : float
        nu [-], -1 < nu < 0.5.
    radius : float, optional
        Punch radius a [m] (default the paper's 9 mm indenter).
    level : int, optional
        Mesh level (>= 1).

    Returns
    -------
    float
        k = P / delta [N/m].
    """
    check_material(thickness=thickness, poisson_ratio=poisson_ratio,
                   young_modulus=young_modulus)
    a = float(radius)
    if not (math.isfinite(a) and a > 0):
        raise ValueError(f"radius: expected a finite value > 0 m, got {radius!r}")
    if int(level) < 1:
        raise ValueError(f"level: expected an integer >= 1, got {level}")
    return float(young_modulus) * _punch_stiffness_per_pascal(float(thickness),
                                                              float(poisson_ratio), a,
                                                              int(level))


def modulus_from_indenter(k_indenter, thickness, poisson_ratio, radius=PUNCH_RADIUS, *,
                          level: int = 2):
    """Young's modulus that gives a flat punch the measured indenter stiffness.

    Parameters
    ----------
    k_indenter : float or array_like
        Indenter stiffness [N/m] (> 0), any shape.
    thickness : float
        Tissue thickness over the bone [m].
    poisson_ratio : float
        nu [-].
    radius : float, optional
        Indenter radius [m].
    level : int, optional
        Mesh level of the punch FE (>= 1).

    Returns
    -------
    float or ndarray
        E [Pa], same shape as ``k_indenter``.
    """
    k = np.asarray(k_indenter, dtype=float)
    if not np.all(np.isfinite(k)) or np.any(k <= 0):
        raise ValueError("k_indenter: expected finite values > 0 N/m")
    k1 = flat_punch_stiffness(thickness, 1.0, poisson_ratio, radius, level=level)
    out = k / k1
    return float(out) if out.ndim == 0 else out
