"""What the load goes through: the share of the applied force each kind of contact carries.

docs/model.md section 12.4. The patch forces of a solution balance the wrench on the cuff,
so the applied force F (the force part of W + W_pre, cuff frame [N]) splits exactly into

* F_normal -- the normal forces of the elements or patches in contact, sum f_e n_e;
* F_tangential -- the tangential forces of those in contact: friction with
  ``interface.friction_coefficient``, the bonded ties without it;
* F_lifted -- the tangential forces of elements or patches that have lifted off, which
  only the bonded model has (its shear springs and ties hold a lifted element), and with
  which a user sees where the bonded assumption carries load it should not.

The share of each is its projection on F, (F_k . F) / |F|^2, so the three add up to one.
"""

from __future__ import annotations

import numpy as np

from .solver import normal_forces

__all__ = ["force_parts", "load_shares", "share_sums"]


def force_parts(model, u, contact, normal=None, tangential=None) -> np.ndarray:
    """(F_normal, F_tangential, F_lifted) of every sample, shape (m, 3, 3) [N], cuff frame.

    Parameters
    ----------
    model : SpringModel or CoupledModel
    u : ndarray, shape (m, 6)
        Solutions.
    contact : ndarray of bool, shape (m, n)
        Their contact sets.
    normal, tangential : ndarray, shape (m, n) and (m, n, 2), optional
        The normal and tangential forces (axial, circumferential) [N] when the solution
        carries them (``Solution.forces``; with friction ``Solution.tangential``);
        otherwise they are recomputed from u (bonded). The coupled model's own patch
        forces are used in any case.
    """
    u = np.atleast_2d(np.asarray(u, dtype=float))
    S = np.atleast_2d(np.asarray(contact, dtype=bool))
    g = model.geometry
    normals = g.normals
    circ, axial = g.circumferential, g.meridian
    if hasattr(model, "patch_forces") and tangential is None:
        # the coupled model's program forces (the normal force along n_e, not the traction
        # integral it reports): these are what balance the wrench
        P = model.patch_forces(u, S)
        fn, ft = P[..., 0], P[..., 1:3]
    elif tangential is not None:
        ft = np.asarray(tangential, dtype=float)
        fn = np.asarray(normal, dtype=float)
    elif hasattr(model, "k_shear") and getattr(model, "friction_coefficient", None) is None:
        return _bonded_parts(model, u, S, normal)
    else:
        ft = model.shear_components(u, S)
        fn = normal_forces(model, u)
    fn = np.where(S, fn, 0.0)
    vec_t = ft[..., 0, None] * axial + ft[..., 1, None] * circ
    normal = np.einsum("me,ei->mi", fn, normals)
    touch = np.einsum("me,mei->mi", S.astype(float), vec_t)
    lifted = np.einsum("me,mei->mi", (~S).astype(float), vec_t)
    return np.stack([normal, touch, lifted], axis=1)


def _bonded_parts(model, u, S, normal, block: int = 2048) -> np.ndarray:
    """:func:`force_parts` of the bonded spring model, a block of samples at a time.

    s_e = k_s,e (d_e - (n_e . d_e) n_e) with d_e = t + w x p_e and n_e . d_e = b_e . u: a
    sum of shear forces over any set of elements needs per-element scalars only, never
    (samples, elements, 3) arrays; blocks keep the (samples, elements) ones small.
    """
    g = model.geometry
    k_s, p, normals = model.k_shear, g.points, g.normals
    t, w = u[:, :3], u[:, 3:]
    # every element's sum is linear in u: sum_e k_s,e (b_e . u) n_e = u @ sum_e k_s,e b_e n_e^T
    total = k_s.sum() * t + np.cross(w, k_s @ p) - u @ ((g.b * k_s[:, None]).T @ normals)
    normal_part, touch = np.empty((len(u), 3)), np.empty((len(u), 3))
    for i in range(0, len(u), block):
        sl = slice(i, i + block)
        Sb = S[sl]
        fn = normal_forces(model, u[sl]) if normal is None else np.array(normal[sl], float)
        fn[~Sb] = 0.0
        normal_part[sl] = fn @ normals
        W = Sb * k_s
        touch[sl] = W.sum(axis=1)[:, None] * t[sl] + np.cross(w[sl], W @ p)
        W *= u[sl] @ g.b.T                                      # k_s,e (b_e . u) on S
        touch[sl] -= W @ normals
    return np.stack([normal_part, touch, total - touch], axis=1)


def share_sums(parts: np.ndarray):
    """(sum over samples of F_k . F (3,), sum of |F|^2) of ``parts`` (m, 3, 3) from
    :func:`force_parts`, samples with a non-finite part left out: what the load-weighted
    shares are the ratio of, and what a streamed run adds up chunk by chunk."""
    F = parts.sum(axis=1)
    proj = np.einsum("mki,mi->mk", parts, F)
    mag2 = np.einsum("mi,mi->m", F, F)
    ok = np.isfinite(proj).all(axis=1) & np.isfinite(mag2)
    return proj[ok].sum(axis=0), float(mag2[ok].sum())


def load_shares(parts: np.ndarray, weighted: bool = True):
    """Shares (normal, tangential, lifted) [-] of the applied force.

    ``parts`` (m, 3, 3) from :func:`force_parts`. ``weighted``: one share per part over all
    samples, each sample weighted by |F|^2 (the load-weighted mean, (3,)); otherwise per
    sample, (m, 3), NaN where no force is applied.
    """
    if weighted:
        proj, tot = share_sums(parts)
        return proj / tot if tot > 0 else np.full(3, np.nan)
    F = parts.sum(axis=1)                                  # (m, 3)
    proj = np.einsum("mki,mi->mk", parts, F)
    mag2 = np.einsum("mi,mi->m", F, F)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(mag2[:, None] > 0, proj / mag2[:, None], np.nan)
