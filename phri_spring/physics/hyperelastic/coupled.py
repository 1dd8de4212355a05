"""The coupled arm with a hyperelastic (neo-Hookean or Ogden) tissue layer, at spring speed
(docs/model.md section 10.8).

A :class:`HyperCoupledModel` is the linear coupled model of a rigid cuff bonded over its
patches (:class:`~phri_spring.physics.continuum.coupled.CoupledModel`, its mesh level and preload)
plus the identified corrections of :mod:`phri_spring.physics.hyperelastic.reduced`. A sample is
the 6-unknown equation H u + dR(u / s) = W, solved by Newton's method from the reduced
model's tangent at the preload; its patch forces follow from u. The plates are bonded:
a patch's normal force can be negative (the skin held on the plate), every patch is in
contact. Samples whose pose leaves the identified range, or whose iteration fails, are
flagged as not converged (NaN forces), as every model does. The corrections are averaged
over the mirror planes the cuff and its linear model share
(:mod:`phri_spring.physics.hyperelastic.symmetry`; ``reduction.info["mirror_planes"]``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ..continuum.coupled import CoupledModel
from .reduced import HyperReduction, low_monomials, features, linear_bonded, solve_poses
from .symmetry import mirror_group, symmetrized
from ..springs.model import OnGeometry, field_unit
from .laws import continuum_law_names

__all__ = ["HyperCoupledModel", "CONTINUUM_LAWS"]

#: the names of the continuum laws of the coupled arm (``tissue.continuum.law``), in
#: registration order (:data:`~phri_spring.physics.hyperelastic.laws.CONTINUUM_LAW_MODELS`)
CONTINUUM_LAWS = continuum_law_names()


@dataclass(frozen=True, eq=False)
class HyperCoupledModel(OnGeometry):
    """A rigid bonded cuff on a hyperelastic tissue layer, reduced (module docstring).

    ``continuum_law`` names the layer's law (``neo_hookean`` or ``ogden``); the reduction
    is identified on the FE of that law and does not depend on it otherwise.

    Attributes
    ----------
    linear : CoupledModel
        The linear coupled model of the same config with a rigid cuff: the linear part,
        the preload (``delta``, ``f0``, ``W_pre``), the patches.
    reduction : HyperReduction
        The identified corrections, averaged over the cuff's mirror planes.
    H : ndarray, shape (6, 6)
        The linear bonded stiffness T^T C_t^-1 T [N/m, N/rad; N*m/m, N*m/rad].
    N : ndarray, shape (n, 6)
        Normal-force map N_out T [N/m, N/rad].
    G : ndarray, shape (n*6, 6)
        Patch-force map C_t^-1 T, local axes.
    """

    linear: CoupledModel = field(repr=False)
    reduction: HyperReduction = field(repr=False)
    pain_threshold_kpa: float = field(default=120.0,
                                      metadata=field_unit("kPa", "docs/model.md section 4"))
    arm: str = "coupled"
    dofs: int = 6
    friction_coefficient: None = None
    continuum_law: str = "neo_hookean"
    H: np.ndarray = field(init=False, repr=False, metadata=field_unit(
        "[[N/m, N/rad], [N*m/m, N*m/rad]]", "docs/model.md section 10.8"))
    N: np.ndarray = field(init=False, repr=False, metadata=field_unit(
        "[N/m, N/rad]", "docs/model.md section 10.8"))
    G: np.ndarray = field(init=False, repr=False, metadata=field_unit(
        "[[N/m, N/rad], [N*m/m, N*m/rad]]", "docs/model.md section 10.8"))
    P0: np.ndarray = field(init=False, repr=False, metadata=field_unit(
        "[N, N*m]", "docs/model.md section 10.8"))
    inv_area_kpa: np.ndarray = field(init=False, repr=False,
                                     metadata=field_unit("1/(1000 N)", "derived"))

    def __post_init__(self):
        if not np.all(np.isinf(self.linear.k_cuff)):
            raise ValueError("the hyperelastic coupled model needs a rigid cuff (k_cuff inf)")
        lin = linear_bonded(self.linear)
        for name in ("H", "N", "G", "P0"):
            object.__setattr__(self, name, lin[name])
        if "mirror_planes" not in self.reduction.info:
            planes, group = mirror_group(self.geometry.points, lin)
            red = symmetrized(self.reduction, group)
            object.__setattr__(self, "reduction", replace(
                red, info={**red.info, "mirror_planes": planes}))
        object.__setattr__(self, "inv_area_kpa", 1.0 / (1000.0 * self.geometry.areas))

    @property
    def geometry(self):
        return self.linear.geometry

    @property
    def f0(self) -> np.ndarray:
        """Normal patch forces of the linear model at zero wrench [N] (the strap's preload)."""
        return self.linear.f0

    @property
    def W_pre(self) -> np.ndarray:
        """The strap's wrench on the cuff [N, N*m] (the linear model's)."""
        return self.linear.W_pre

    @property
    def is_linear(self) -> bool:
        return False

    def solve_wrenches(self, W, max_iterations: int):
        """Every row of W (m, 6) [N, N*m]: (u (m, 6), normal forces (m, n) [N], iterations
        (m,), converged (m,), contact (m, n) bool). Not converged rows: NaN forces."""
        W = np.atleast_2d(np.asarray(W, float))
        red = self.reduction
        u, phi, its, conv = solve_poses(red, self.H, W, red.start(self.H, W, self._start_map),
                                        max_iterations=max(1, int(max_iterations)))
        forces = self.f0 + u @ self.N.T + phi @ red.normal
        if not conv.all():
            forces[~conv] = np.nan
        return u, forces, its, conv, np.repeat(conv[:, None], self.n, axis=1)

    @cached_property
    def _start_map(self) -> np.ndarray:
        """Newton's start map, computed once per model (:meth:`HyperReduction.start_map`)."""
        return self.reduction.start_map(self.H)

    def patch_forces(self, u, contact=None) -> np.ndarray:
        """Patch forces P (m, n, 6) in local axes [N, N*m] at poses u (m, 6): normal, axial,
        circumferential, then the moments about each patch centre (``contact`` unused:
        every patch is bonded)."""
        u = np.atleast_2d(np.asarray(u, float))
        red = self.reduction
        P = self.P0 + u @ self.G.T + features(u / red.scale) @ red.patch
        return P.reshape(len(u), self.n, 6)

    def shear_components(self, u, contact=None) -> np.ndarray:
        """Tangential patch forces on the arm, (m, n, 2) [N]: axial, circumferential."""
        return self.patch_forces(u, contact)[..., 1:3]

    def tangent_stiffness(self, u, contact=None) -> np.ndarray:
        """dW/du (6, 6) at the pose u (6,) [N/m, N/rad; N*m/m, N*m/rad] (``contact`` unused)."""
        red = self.reduction
        return red.jacobian(self.H, low_monomials(np.asarray(u, float).reshape(1, 6) / red.scale))[0]
