"""The affine maps of one interface state (docs/model.md section 12): u and the tied
patch forces from the wrench, made once per state and kept in the path's cache.

A state here has no patch sliding on an open cone: every touching patch is tied on its
normal and rotations, stuck ones on their tangential dofs too, and ``free`` ones (sliding
with a closed cone) carry no tangential force. The states with patches sliding on an open
cone build on these maps (:mod:`phri_spring.physics.friction.active`).
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from .form import RELEASED, STUCK, InterfaceForm

__all__ = ["StuckMaps", "stuck_maps", "kept", "MAPS_KEPT"]

#: states whose maps the cache keeps: a long log meets many contact sets, each map holds
#: a factor of the tied compliance (about 130 kB for 21 patches with rotations); the
#: oldest is dropped first
MAPS_KEPT = 512


class StuckMaps:
    """The affine maps of one state with no patch sliding on its cone: u and P from the
    wrench. ``free`` (n,) bool: touching patches sliding with a closed cone (their
    cone's normal force has reached 0, :attr:`InterfaceForm.cone_normal`), tied on the
    normal and rotations with no tangential force: as linear as a stuck patch."""

    def __init__(self, form: InterfaceForm, cls, free=None):
        n, d = form.n, form.d
        dof = np.arange(n * d).reshape(n, d)
        tied = np.zeros((n, d), dtype=bool)
        tied[cls == STUCK] = True
        if free is not None and free.any():
            tied[free] = True
            tied[free, 1:3] = False
        self.D = dof[tied]
        self.rel = np.flatnonzero(cls == RELEASED)
        self.free = np.flatnonzero(free) if free is not None else np.zeros(0, dtype=np.int64)
        D = self.D
        if form.diagonal:
            g = 1.0 / np.diag(form.C)[D]
            self._G = lambda x: g[:, None] * x if x.ndim == 2 else g * x
        else:
            cf = cho_factor(form.C[np.ix_(D, D)])
            self._G = lambda x: cho_solve(cf, x)
        TD = form.T[D]
        self.GT = self._G(TD)
        H = TD.T @ self.GT
        self.Hinv = np.linalg.inv(0.5 * (H + H.T))
        self.TD = TD
        # penetration of the released patches: affine in u and in P_D
        ni = form.normal[self.rel]
        if form.C_skin is not None and self.rel.size:
            self.Q = form.T[ni] - form.C_skin[np.ix_(ni, D)] @ self.GT
            self.Cs = form.C_skin[np.ix_(ni, D)]
        else:
            self.Q = form.T[ni]
            self.Cs = None
        self.d_rel = form.delta[ni]
        # the cone's normal force of the stuck patches from their forces P_D (the others
        # carry nothing), and the free ones' cone force (which must stay <= 0)
        self.cone = (None if form.cone_normal is None else
                     np.ascontiguousarray(form.cone_normal[np.ix_(cls == STUCK, D)]))
        self.cone_free = (None if not self.free.size or form.cone_normal is None else
                          np.ascontiguousarray(form.cone_normal[np.ix_(self.free, D)]))
        # where the stuck patches' forces, and the free ones' normal forces, sit in P_D
        # (free patches have no tangential dofs)
        self.stuck_at = np.flatnonzero(np.isin(self.D, dof[cls == STUCK].ravel()))
        self.free_normal_at = np.searchsorted(self.D, form.normal[self.free])

    def cone_force(self, PD, Pn):
        """The stuck patches' cone normal force from the tied forces P_D ((m, k) or (k,))
        and their normal forces Pn: Pn, or the smaller of Pn and the reading's integral."""
        return Pn if self.cone is None else np.minimum(Pn, PD @ self.cone.T)

    @cached_property
    def G(self):
        """C_DD^-1 as a matrix: the active-set events (:mod:`~phri_spring.physics.friction.active`)
        apply it once per state tried, where a product is much cheaper than a
        triangular solve's call."""
        return np.ascontiguousarray(self._G(np.eye(self.D.size)))

    def offsets(self, form, z):
        """For tie offsets z: (c, P0) with u = (r - c) @ Hinv.T, P_D = u @ GT.T + P0."""
        D = self.D
        x = form.delta[D] - z.ravel()[D]
        # with friction set, blocks are short (a few samples between events): the product
        # with the inverse, made once per state, rather than a triangular solve per block
        # (the default interface keeps the solve, and its outputs as they were)
        P0 = self.G @ x if form.cone_normal is not None else self._G(x)
        return self.TD.T @ P0, P0


def kept(cache: dict, key, make):
    """``cache[key]``, made by ``make()`` and kept there if new (the oldest entry dropped
    once MAPS_KEPT are kept)."""
    value = cache.get(key)
    if value is None:
        value = make()
        if len(cache) >= MAPS_KEPT:
            del cache[next(iter(cache))]
        cache[key] = value
    return value


def stuck_maps(form, cache: dict, cls, free=None):
    """The :class:`StuckMaps` of state ``cls`` (with ``free`` patches) from ``cache``, made
    and kept there if new; False where the state holds no cuff (a singular system)."""
    key = (cls == STUCK).tobytes()
    if free is not None and free.any():
        key += b"free" + free.tobytes()

    def make():
        try:
            return StuckMaps(form, cls, free)
        except np.linalg.LinAlgError:
            return False
    return kept(cache, key, make)
