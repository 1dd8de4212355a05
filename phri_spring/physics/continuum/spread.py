"""A per-patch modulus (``tissue.continuum.spread: per_patch``, docs/model.md section 10.5):
the condensed tissue operators of one modulus scaled patch by patch."""

from __future__ import annotations

import numpy as np

__all__ = ["scale_patches", "scale_parts"]


def scale_patches(K, N, s):
    """Each patch's tissue stiffened by its own factor s_e (n,) [-] (a per-patch modulus).

    K' = D K D with D = diag(sqrt(s_e)) on patch e's dofs: patch e's own stiffness scales
    by s_e, the coupling of patches e and f by sqrt(s_e s_f), and K' stays symmetric
    positive definite. The normal output N (n, n d), if given, follows: row e and the
    columns of patch f by sqrt(s_e) sqrt(s_f).
    """
    s = np.sqrt(np.asarray(s, dtype=float))
    d = np.repeat(s, K.shape[0] // len(s))
    K = K * d[:, None] * d[None, :]
    if N is not None:
        N = N * d[None, :] * s[:, None]
    return K, N


def scale_parts(rows, owner, s, dofs):
    """The node rows (k, n d) of the normal output (:mod:`.reading`, patch ``owner`` (k,)
    each) of a layer stiffened patch by patch, as :func:`scale_patches` scales N: row k and
    the columns of patch f by sqrt(s_owner(k)) sqrt(s_f)."""
    r = np.sqrt(np.asarray(s, dtype=float))
    return rows * r[owner][:, None] * np.repeat(r, dofs)[None, :]
