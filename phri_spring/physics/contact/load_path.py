"""What the load goes through: the share of the transmitted force each kind of contact carries.

docs/model.md section 12.4. Every element (or patch) passes two forces to the skin: its
normal force f_e and its tangential force t_e (axial, circumferential). Three kinds:

* normal -- the normal forces of the elements or patches in contact, abs(f_e);
* tangential -- the tangential forces of those in contact, abs(t_e): friction with
  ``interface.friction_coefficient``, the bonded ties without it;
* lifted -- the tangential forces of elements or patches that have lifted off, which only
  the bonded model has (its shear springs and ties hold a lifted element), and with which
  a user sees where the bonded assumption carries load it should not.

A kind's share is its summed magnitude over the elements (and the samples of a log) over
the sum of all three: each share is in [0, 1] and the three add up to one.

:func:`force_parts` keeps the per-sample split of the applied force F into the three
kinds' vector sums (F_normal + F_tangential + F_lifted = F).
"""

from __future__ import annotations

import numpy as np

from ..cuff.geometry import element_jacobians
from ..springs.model import SpringModel
from .solver import normal_forces

__all__ = ["force_parts", "shear_rows", "transmitted", "transmitted_sums", "share_sums",
           "load_shares", "ChunkedShares"]

#: rows of a chunk handled at a time by :func:`_bonded_blocks`: its (rows, n) temporaries
#: then stay in the processor's cache instead of going out to memory and back per step
_BLOCK_ROWS = 2048


def _axes(geometry):
    """The shear directions of every element, (n, 3) each: the skin's meridian a_e (+x on
    an untapered limb) and the circumferential c_e (the geometry's own, docs/model.md
    section 13)."""
    return geometry.meridian, geometry.circumferential


def force_parts(model, u, contact, normal=None, tangential=None) -> np.ndarray:
    """(F_normal, F_tangential, F_lifted) of every sample, shape (m, 3, 3) [N], cuff frame:
    the vector sums of the three kinds, which add up to the applied force.

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
    normals = model.geometry.normals
    axial, circ = _axes(model.geometry)
    if hasattr(model, "patch_forces") and tangential is None:
        # the coupled model's program forces (the normal force along n_e, not the traction
        # integral it reports): these are what balance the wrench
        P = model.patch_forces(u, S)
        fn, ft = P[..., 0], P[..., 1:3]
    elif tangential is not None:
        ft = np.asarray(tangential, dtype=float)
        fn = np.asarray(normal, dtype=float)
    else:
        ft = model.shear_components(u, S)
        fn = normal_forces(model, u)
    fn = np.where(S, fn, 0.0)
    vec_t = ft[..., 0, None] * axial + ft[..., 1, None] * circ
    normal = np.einsum("me,ei->mi", fn, normals)
    touch = np.einsum("me,mei->mi", S.astype(float), vec_t)
    lifted = np.einsum("me,mei->mi", (~S).astype(float), vec_t)
    return np.stack([normal, touch, lifted], axis=1)


def shear_rows(model) -> np.ndarray:
    """R (6, 2n) with u @ R = the bonded shear springs' (axial, circumferential) forces
    [N] of every element, axial ones first: ``model.shear_components`` without its
    (m, n, 3) temporaries.

    Row e of each half is k_s,e B_e^T (I3 - n_e n_e^T) v for v = a, c_e (docs/model.md
    section 2): the shear force k_s,e (I3 - n_e n_e^T) B_e u is linear in u.
    """
    g = model.geometry
    n = g.normals
    axial, circ = _axes(g)
    B = element_jacobians(g.points)                                   # (n, 3, 6)
    rows = []
    for v in (axial, circ):
        tangential = v - np.sum(v * n, axis=1, keepdims=True) * n     # (I3 - n n^T) v
        rows.append(model.k_shear[:, None] * np.einsum("eij,ei->ej", B, tangential))
    return np.ascontiguousarray(np.concatenate(rows, axis=0).T)


def transmitted(model, u, contact, normal=None, tangential=None, rows=None) -> np.ndarray:
    """What every sample passes to the skin, by kind, shape (m, 3) [N]: the summed normal
    forces of the elements in contact, the summed tangential force magnitudes of those in
    contact, and of those lifted off (docs/model.md section 12.4).

    Parameters
    ----------
    model : SpringModel or CoupledModel
    u : ndarray, shape (m, 6)
    contact : ndarray of bool, shape (m, n)
    normal : ndarray, shape (m, n), optional
        The solution's normal forces (``Solution.forces``); recomputed from u if not
        given. The coupled model without ``tangential`` uses its program forces.
    tangential : ndarray, shape (m, n, 2), optional
        The solution's own tangential forces (friction: ``Solution.tangential``);
        otherwise the bonded ones from u.
    rows : ndarray, shape (6, 2n), optional
        :func:`shear_rows` of a spring model, to reuse across calls.

    A sample whose forces or u are NaN (not converged) gives NaN in some part.
    """
    u, S, fn, ft = _magnitudes(model, u, contact, normal, tangential)
    if ft is not None:
        touching = S.astype(float)
        return np.stack([np.einsum("me,me->m", fn, touching),
                         np.einsum("me,me->m", ft, touching),
                         np.einsum("me,me->m", ft, (~S).astype(float))], axis=1)
    out = np.empty((len(u), 3))
    for lo, hi, mag, touching in _bonded_blocks(model, u, S, rows):
        out[lo:hi, 0] = np.einsum("me,me->m", fn[lo:hi], touching)
        out[lo:hi, 1] = np.einsum("me,me->m", mag, touching)
        out[lo:hi, 2] = np.einsum("me,me->m", mag, 1.0 - touching)
    return out


def transmitted_sums(model, u, contact, normal=None, tangential=None, rows=None) -> np.ndarray:
    """:func:`transmitted` summed over the samples, (3,) [N], without its per-sample
    rows: what a streamed run adds up chunk by chunk. Every sample must be finite (leave
    out the ones that did not converge)."""
    u, S, fn, ft = _magnitudes(model, u, contact, normal, tangential)
    if ft is not None:
        touching = S.astype(float)
        return np.array([np.einsum("me,me->", fn, touching), np.einsum("me,me->", ft, touching),
                         np.einsum("me,me->", ft, (~S).astype(float))])
    out = np.zeros(3)
    for lo, hi, mag, touching in _bonded_blocks(model, u, S, rows):
        flat = touching.ravel()
        touch = np.dot(mag.ravel(), flat)
        out[0] += np.dot(fn[lo:hi].ravel(), flat)
        out[1] += touch
        # lifted = all - touching: the difference is round-off of the total
        out[2] += max(mag.sum() - touch, 0.0)
    return out


def _magnitudes(model, u, contact, normal, tangential):
    """(u, contact, normal magnitudes (m, n), tangential magnitudes (m, n) or None for the
    bonded spring network, which :func:`_bonded_blocks` gives block by block)."""
    u = np.atleast_2d(np.asarray(u, dtype=float))
    S = np.atleast_2d(np.asarray(contact, dtype=bool))
    if tangential is None and hasattr(model, "patch_forces"):
        P = model.patch_forces(u, S)
        return u, S, np.abs(P[..., 0]), np.hypot(P[..., 1], P[..., 2])
    if tangential is not None:
        ft = np.asarray(tangential, dtype=float)
        return u, S, np.abs(np.asarray(normal, dtype=float)), np.hypot(ft[..., 0], ft[..., 1])
    # f_e >= 0 by the element law
    fn = normal_forces(model, u) if normal is None else np.asarray(normal, dtype=float)
    if not isinstance(model, SpringModel):   # another arm's model: its own shear forces
        ft = model.shear_components(u, S)
        return u, S, fn, np.hypot(ft[..., 0], ft[..., 1])
    return u, S, fn, None


def _bonded_blocks(model, u, S, rows):
    """(lo, hi, tangential magnitudes (rows, n) [N], contact as 0/1 floats) of the bonded
    springs, block by block: the shear forces are linear in u, two small products per
    block instead of (m, n, 3) arrays."""
    R = shear_rows(model) if rows is None else rows
    n = R.shape[1] // 2
    Ra, Rc = np.ascontiguousarray(R[:, :n]), np.ascontiguousarray(R[:, n:])
    for lo in range(0, len(u), _BLOCK_ROWS):
        hi = min(lo + _BLOCK_ROWS, len(u))
        mag = u[lo:hi] @ Ra
        circ = u[lo:hi] @ Rc
        mag *= mag
        circ *= circ
        mag += circ
        np.sqrt(mag, out=mag)
        yield lo, hi, mag, S[lo:hi].astype(float)


def share_sums(parts: np.ndarray) -> np.ndarray:
    """Sum over samples of :func:`transmitted`'s ``parts`` (m, 3), samples with a
    non-finite part left out: what the load-weighted shares are the ratio of."""
    parts = np.asarray(parts, dtype=float)
    ok = np.isfinite(parts).all(axis=1)
    return parts[ok].sum(axis=0) if not ok.all() else parts.sum(axis=0)


def load_shares(parts: np.ndarray, weighted: bool = True) -> np.ndarray:
    """Shares (normal, tangential, lifted) [-] of the force transmitted to the skin.

    ``parts`` (m, 3) from :func:`transmitted`. ``weighted``: one share per kind over all
    samples (each kind's magnitudes summed over the log over the sum of all three, (3,));
    otherwise per sample, (m, 3). NaN where nothing is transmitted or a sample did not
    converge; otherwise each share is in [0, 1] and the three add up to one.
    """
    parts = np.asarray(parts, dtype=float)
    if weighted:
        sums = share_sums(parts)
        total = sums.sum()
        return sums / total if total > 0 else np.full(3, np.nan)
    total = parts.sum(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, parts / total, np.nan)


class ChunkedShares:
    """The load-weighted shares of a log solved chunk by chunk: :func:`transmitted_sums` of
    each chunk's converged samples, added in chunk order (the same round-off whichever
    thread adds a chunk first)."""

    def __init__(self):
        self._sums = {}     # chunk number -> (3,) [N]
        self._rows = None   # shear_rows of a bonded spring model, made once

    def add(self, number: int, model, sol) -> None:
        """Chunk ``number``'s :class:`~phri_spring.physics.contact.solution.Solution` of ``model``."""
        ok = np.asarray(sol.converged, dtype=bool)
        if not ok.any():
            return
        # the force along n_e where the solution has it (friction, the coupled arm's lift-off
        # cone): its reported forces are then what the patches' sensors read
        normal = getattr(sol, "normal", None)
        forces = sol.forces if normal is None else normal
        u, contact, tang = sol.u, sol.contact, sol.tangential
        if not ok.all():
            u, contact, forces = u[ok], contact[ok], forces[ok]
            tang = None if tang is None else tang[ok]
        if isinstance(model, SpringModel) and tang is None and self._rows is None:
            self._rows = shear_rows(model)
        self._sums[number] = transmitted_sums(model, u, contact, normal=forces,
                                              tangential=tang, rows=self._rows)

    def shares(self) -> tuple:
        """(normal, tangential, lifted) [-], NaN when nothing was passed to the skin."""
        sums = np.zeros(3)
        for number in sorted(self._sums):
            sums += self._sums[number]
        total = sums.sum()
        return tuple(sums / total) if total > 0 else (np.nan,) * 3
