"""Mirror symmetry of the reduced hyperelastic model (docs/model.md section 10.8).

A cuff and arm that are mirror symmetric, say about the plane x = 0 of the cuff frame,
answer a mirrored pose with the mirrored wrench and patch forces: the FE does so to every
digit. The reduced model's cubic corrections are fitted to FE poses on rays in random
directions, and nothing in the fit makes them symmetric: on the human preset's Ogden layer
the fitted model turned the cuff 2.75 mrad about z under a pure moment about y, which the
symmetric FE cannot do. Averaging each correction over the mirror group removes every
part that breaks the symmetry and keeps the rest; for a monomial of the pose this is only
a sign, so the averaged model is again a cubic with the same monomials.

A plane is used only when the geometry and the linear bonded model (the strap's preload,
the stiffness H, the normal-force and patch-force maps) are mirror symmetric about it to
:data:`SYMMETRY_RTOL`: a per-patch modulus, an off-centre strap or a cuff that covers one
side of the arm more than the other leaves that plane out.

Conventions. The pose u = (t, w) (translation, rotation vector) and the wrench (F, M)
mirror about the plane normal to axis a as t_a -> -t_a and w -> -S w (a rotation is a
pseudovector: its two components in the plane flip), i.e. with the signs sigma of
:func:`pose_signs`. Patch i lands on patch perm[i]; its forces in local axes (normal,
axial, circumferential, three moments) change by the signs c, the same for every patch,
read off the linear model.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .reduced import EXPONENTS, HyperReduction

__all__ = ["SYMMETRY_RTOL", "mirror_group", "pose_signs", "symmetrized"]

#: a mirror plane is used when the linear model is symmetric about it to this (relative)
SYMMETRY_RTOL = 1e-6
_AXES = "xyz"


def pose_signs(axis: int) -> np.ndarray:
    """sigma (6,): the signs a mirror about the plane normal to ``axis`` puts on a pose
    (t, w) and on a wrench (F, M)."""
    s = -np.ones(6)
    s[:3] = 1.0
    s[axis] = -1.0            # the translation along the axis flips
    s[3 + axis] = 1.0         # the rotation about it does not; the other two do
    return s


def _close(a, b, rtol) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return bool(np.abs(a - b).max() <= rtol * max(np.abs(a).max(), np.abs(b).max(), 1e-300))


def _patch_signs(linear, sigma, perm, rtol):
    """The local-axis signs c (6,) with P_perm[i](sigma u) = c P_i(u) in the linear model,
    or None where no such signs fit."""
    n = len(perm)
    G = linear["G"].reshape(n, 6, 6)
    P0 = linear["P0"].reshape(n, 6)
    Gm = G[perm] * sigma[None, None, :]          # what patch perm[i] does at the mirrored pose
    c = np.ones(6)
    for k in range(6):
        a = np.concatenate([G[:, k].ravel(), P0[:, k]])
        b = np.concatenate([Gm[:, k].ravel(), P0[perm, k]])
        c[k] = 1.0 if np.abs(a - b).max() <= np.abs(a + b).max() else -1.0
    ok = _close(Gm, c[None, :, None] * G, rtol) and _close(P0[perm], c * P0, rtol)
    return c if ok else None


def _mirror(points, linear, axis, rtol):
    """(sigma, perm, c) of the mirror about the plane normal to ``axis``, or None."""
    p = np.asarray(points, float)
    n = len(p)
    q = p.copy()
    q[:, axis] *= -1.0
    d = np.linalg.norm(q[:, None, :] - p[None, :, :], axis=2)
    perm = d.argmin(axis=1)
    size = max(np.abs(p).max(), 1e-300)
    if d[np.arange(n), perm].max() > 1e-9 * size or len(np.unique(perm)) != n:
        return None
    s = pose_signs(axis)
    if not (_close(linear["W_pre"], s * linear["W_pre"], rtol)
            and _close(linear["H"] * s[None, :], s[:, None] * linear["H"], rtol)
            and _close(linear["f0"][perm], linear["f0"], rtol)
            and _close(linear["N"][perm] * s[None, :], linear["N"], rtol)):
        return None
    c = _patch_signs(linear, s, perm, rtol)
    return None if c is None else (s, perm, c)


def mirror_group(points, linear: dict, rtol: float = SYMMETRY_RTOL):
    """The mirror symmetries the cuff and its linear bonded model share.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Patch centres in the cuff frame [m].
    linear : dict
        :func:`~phri_spring.physics.hyperelastic.reduced.linear_bonded` of the model.

    Returns
    -------
    planes : list of str
        The mirror planes used ("x" for the plane normal to the cuff's x axis, ...).
    group : list of (sigma (6,), perm (n,), c (6,))
        Every product of those mirrors, the identity first.
    """
    n = len(points)
    group = [(np.ones(6), np.arange(n), np.ones(6))]
    planes = []
    for axis in range(3):
        m = _mirror(points, linear, axis, rtol)
        if m is None:
            continue
        planes.append(_AXES[axis])
        s, perm, c = m
        # g then this mirror: signs multiply, patch i goes to perm[g's perm[i]]
        group += [(gs * s, perm[gp], gc * c) for gs, gp, gc in group]
    return planes, group


def symmetrized(red: HyperReduction, group) -> HyperReduction:
    """``red`` with its corrections averaged over ``group`` (:func:`mirror_group`).

    With x = u / s and a monomial m_k of exponents e_k, m_k(sigma x) = prod(sigma^e_k)
    m_k(x): the average of dR_a(x) = sigma_a dR_a(sigma x), of df_i(x) = df_perm[i](sigma x)
    and of dP_i(x) = c dP_perm[i](sigma x) over the group is a cubic again.
    """
    if len(group) == 1:
        return red
    K, n = red.normal.shape
    wrench = np.zeros_like(red.wrench)
    normal = np.zeros_like(red.normal)
    patch = np.zeros((K, n, 6))
    P3 = red.patch.reshape(K, n, 6)
    for sigma, perm, c in group:
        sk = np.prod(sigma[None, :] ** EXPONENTS, axis=1)    # +-1 per monomial
        wrench += sk[:, None] * red.wrench * sigma[None, :]
        normal += sk[:, None] * red.normal[:, perm]
        patch += sk[:, None, None] * c[None, None, :] * P3[:, perm, :]
    g = float(len(group))
    return replace(red, wrench=wrench / g, normal=normal / g, patch=(patch / g).reshape(K, -1),
                   info=dict(red.info))
