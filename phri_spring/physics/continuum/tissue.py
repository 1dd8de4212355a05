"""Built-in 3D finite-element model of the tissue layer (docs/model.md section 10).

The arm's soft tissue is a linear elastic tube between a rigid, fixed bone
(r = R - t) and the skin (r = R), meshed with structured triquadratic hexahedra
(27 nodes, ``ElementHex2`` on a ``MeshHex2`` of scikit-fem) in cylindrical
coordinates. Quadratic elements converge for Poisson ratios up to 0.45 (above it they
lock: the stiffness converges slowly from above, so
:data:`~phri_spring.physics.continuum.mesh.MAX_POISSON_RATIO` refuses it), and
since the mesh is isoparametric (its nodes lie on the true cylinders) every
rigid motion of the skin is represented exactly.

This module condenses the FE onto the cuff: :func:`condensed_surface_stiffness` /
:func:`condensed_surface_operators` give the 6n x 6n stiffness of the skin under the n
cuff patches, each patch a rigid plate bonded to the skin, every other skin point
free, the bone fixed (see ``docs/coupled-fe.md``), and the patches' normal-force
output. The FE is split by job, and every public name of the split is importable here:

* :mod:`phri_spring.physics.continuum.mesh` -- the mesh and the checks of the FE's inputs;
* :mod:`phri_spring.physics.continuum.assembly` -- assembly on the mesh, shared with the
  reference FE;
* :mod:`phri_spring.physics.continuum.punch` -- :func:`flat_punch_stiffness` /
  :func:`modulus_from_indenter`, a rigid, frictionless flat cylindrical punch on a layer
  bonded to a rigid base (axisymmetric quadratic FE), to turn indenter stiffness into a
  modulus.

Everything is linear in Young's modulus: the matrices are built for E = 1 Pa
and scaled. scikit-fem is an optional dependency (extra ``fe``), imported only
inside the functions that need it.
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

# re-exported: tests, benchmarks and phri_spring.workflows reach these names here
from .assembly import assemble, assemble_tissue_fe  # noqa: F401
from .mesh import (DEFAULT_LENGTH_FACTOR, DEFAULT_LEVEL, DEFAULT_PATCH_GAP,  # noqa: F401
                      FE_EXTRA_HINT, build_mesh, periodic_map, reduce_matrix, import_skfem,
                      check_material, patch_gap_problem, patch_plates, single_radius)
from .reading import node_parts
from .shape import layer_shape, reference_radius
from .punch import (PUNCH_RADIUS, flat_punch_stiffness, modulus_from_indenter,  # noqa: F401
                       sneddon_punch_stiffness)

__all__ = [
    "FE_EXTRA_HINT",
    "DEFAULT_LEVEL",
    "DEFAULT_LENGTH_FACTOR",
    "DEFAULT_PATCH_GAP",
    "PUNCH_RADIUS",
    "SurfaceOperators",
    "check_material",
    "single_radius",
    "layer_shape",
    "reference_radius",
    "patch_plates",
    "patch_gap_problem",
    "condensed_surface_stiffness",
    "condensed_surface_operators",
    "translational_block",
    "flat_punch_stiffness",
    "modulus_from_indenter",
    "sneddon_punch_stiffness",
]


# ----------------------------------------------------------------- condensation

@dataclass
class SurfaceOperators:
    """Condensed operators of the tissue for one geometry, thickness and Poisson ratio.

    Attributes
    ----------
    K : ndarray, shape (6n, 6n)
        Condensed surface stiffness for E = ``young_modulus`` (see
        :func:`condensed_surface_stiffness`).
    N : ndarray, shape (n, 6n)
        Normal-force output: f_n = N q is, per patch, the integral over the patch
        of the recovered normal traction n(x) . lambda(x) with the local inward
        normal n(x) [N per m or N per rad].
    parts : ndarray, shape (k, 6n), optional
        The rows of N split by skin node: row j is node j's contribution to the
        integral of its patch ``part_patch[j]`` (``N`` is their sum per patch); what a
        patch's sensor reads is the sum of their positive parts
        (:mod:`~phri_spring.physics.continuum.reading`).
    part_patch : ndarray of int, shape (k,), optional
        The patch of each row of ``parts``, ascending.
    info : dict
        Mesh size and timings: ``level``, ``n_dofs``, ``n_elements``, ``n_surface_dofs``,
        ``length`` (modelled tissue length [m]), ``ends``, ``asymmetry`` (relative, before
        symmetrisation), ``seconds``.
    """

    K: np.ndarray
    N: np.ndarray
    info: dict
    parts: np.ndarray | None = None
    part_patch: np.ndarray | None = None


#: the last few E = 1 results of this process, most recent last
_UNIT_CACHE: "OrderedDict[tuple, tuple]" = OrderedDict()
_UNIT_CACHE_SIZE = 8


def _geometry_key(geometry):
    arrays = (np.asarray(geometry.points, float), np.asarray(geometry.span, float),
              np.asarray(geometry.row_width, float), np.asarray(geometry.radius, float),
              np.asarray(geometry.theta, float), np.asarray(geometry.x, float))
    return (tuple(geometry.labels),) + tuple(a.tobytes() for a in arrays)


def _build_unit_operators(geometry, thickness, poisson_ratio, level, length_factor, ends,
                          patch_gap=DEFAULT_PATCH_GAP, bone=None):
    """(K, N, parts, part_patch, info) of :func:`condensed_surface_operators` for E = 1 Pa,
    built."""
    t0 = time.perf_counter()
    fe = assemble_tissue_fe(geometry, thickness, poisson_ratio, level, length_factor, ends,
                            patch_gap=patch_gap, bone=bone)
    s = fe.skin
    mlu = fe.skin_mass_lu()
    Bs, Cs = fe.B[s], fe.C[s]
    A = mlu.solve(Bs)                        # imposed skin displacement per patch dof
    Rs = fe.skin_reactions(A)                # consistent reactions on s
    lam = mlu.solve(Rs)                      # recovered (L2-projected) traction
    K = Bs.T @ lam
    N = Cs.T @ lam
    parts, part_patch = node_parts(Cs, lam, s)
    scale = np.max(np.abs(K))
    asym = float(np.max(np.abs(K - K.T)) / scale)
    K = 0.5 * (K + K.T)
    tm = fe.mesh
    info = dict(level=int(level), n_dofs=int(3 * fe.n_nodes), n_elements=int(tm.mesh.nelements),
                n_surface_dofs=int(len(s)), length=float(tm.x_range[1] - tm.x_range[0]),
                length_factor=float(length_factor), ends=ends, patch_gap=float(patch_gap),
                asymmetry=asym,
                seconds=time.perf_counter() - t0)
    return K, N, parts, part_patch, info


def condensed_surface_operators(geometry, thickness, young_modulus, poisson_ratio, *,
                                level: int = DEFAULT_LEVEL,
                                length_factor: float = DEFAULT_LENGTH_FACTOR,
                                ends: str = "fixed",
                                patch_gap: float = DEFAULT_PATCH_GAP,
                                bone=None) -> SurfaceOperators:
    """K and the local-normal output N of the tissue under the cuff patches.

    Same parameters as :func:`condensed_surface_stiffness`, plus

    Parameters
    ----------
    length_factor : float
        Tissue modelled beyond each axial edge of the cuff, in thicknesses [-].
    ends : {'fixed', 'free'}
        The two end faces of the modelled tissue tube: clamped or traction-free.
    patch_gap : float
        Free skin left between neighbouring patches [m] (``tissue.continuum.patch_gap``):
        each patch's rigid plate is its cell less gap/2 at every edge it shares with a
        neighbour (:func:`~phri_spring.physics.continuum.mesh.patch_plates`); 0: tiled plates,
        whose independent motions the mesh does not converge for (docs/coupled-fe.md);
        None: :data:`DEFAULT_PATCH_GAP`.
    bone : sequence (y_c, z_c, r_b) [m], optional
        A circular bone (``geometry.bone``); None: the skin moved inward by the thickness.
        On a limb that is not a circular cylinder the mesh follows its rows' outlines and
        taper (:mod:`~phri_spring.physics.continuum.shape`).

    Returns
    -------
    SurfaceOperators
    """
    R = reference_radius(geometry)
    check_material(thickness=thickness, poisson_ratio=poisson_ratio,
                    young_modulus=young_modulus, radius=R)
    if ends not in ("fixed", "free"):
        raise ValueError(f"ends: expected 'fixed' or 'free', got {ends!r}")
    lf = float(length_factor)
    if not (math.isfinite(lf) and lf > 0):
        raise ValueError(f"length_factor: expected a finite value > 0, got {length_factor!r}")
    if int(level) < 1:
        raise ValueError(f"level: expected an integer >= 1, got {level!r}")
    patch_gap = DEFAULT_PATCH_GAP if patch_gap is None else float(patch_gap)
    patch_plates(geometry, patch_gap)            # refuses a gap that leaves no plate
    shape = layer_shape(geometry, float(thickness), bone)
    key = (_geometry_key(geometry), float(thickness), float(poisson_ratio), int(level), lf,
           str(ends), float(patch_gap), None if shape is None else shape.fingerprint())
    if key in _UNIT_CACHE:
        _UNIT_CACHE.move_to_end(key)
    else:
        _UNIT_CACHE[key] = _build_unit_operators(geometry, float(thickness),
                                                 float(poisson_ratio), int(level), lf, ends,
                                                 float(patch_gap), bone)
        while len(_UNIT_CACHE) > _UNIT_CACHE_SIZE:
            _UNIT_CACHE.popitem(last=False)
    K1, N1, parts1, owner, info = _UNIT_CACHE[key]
    E = float(young_modulus)
    return SurfaceOperators(K=K1 * E, N=N1 * E, info=dict(info), parts=parts1 * E,
                            part_patch=owner.copy())


def condensed_surface_stiffness(geometry, thickness, young_modulus, poisson_ratio, *,
                                level: int = DEFAULT_LEVEL, **kwargs) -> np.ndarray:
    """Condensed stiffness of the skin under the cuff patches (rigid plates bonded to it).

    Parameters
    ----------
    geometry : CuffGeometry
        The patches (all rows of one radius R [m]); patches must not overlap.
    thickness : float
        Tissue thickness t [m], 0 < t < R; the bone (r = R - t) is rigid and fixed.
    young_modulus : float
        E [Pa] of the tissue (K is linear in E).
    poisson_ratio : float
        nu [-], -1 < nu < 0.5.
    level : int, optional
        Mesh level: level x level triquadratic elements on each patch.
    **kwargs
        ``length_factor``, ``ends``, ``patch_gap``: see :func:`condensed_surface_operators`.

    Returns
    -------
    ndarray, shape (6n, 6n)
        Symmetric positive definite. Patch-major dofs q, per patch e (label order)
        (t_x, t_y, t_z, w_x, w_y, w_z): translation of p_e [m] and small rotation about
        p_e [rad] in cuff-frame axes. ``K @ q`` is, per patch, the force [N] and the
        moment about p_e [N*m] the patches apply to the skin. Blocks N/m, N/rad,
        N*m/m, N*m/rad.

    Raises
    ------
    ValueError
        Rows of different radii, overlapping patches, t, E or nu out of range, a
        ``patch_gap`` that leaves a patch no plate (a ``ModelInputError``).
    UsageError
        scikit-fem (extra ``fe``) not installed.
    """
    return condensed_surface_operators(geometry, thickness, young_modulus, poisson_ratio,
                                       level=level, **kwargs).K


def translational_block(K, rotations: str = "free") -> np.ndarray:
    """The 3n x 3n translational stiffness of a 6n x 6n patch stiffness.

    Parameters
    ----------
    K : array_like, shape (6n, 6n)
        Patch-major (t_x, t_y, t_z, w_x, w_y, w_z) per patch.
    rotations : {'free', 'fixed'}
        'free': patch rotations condensed out (each patch a hinge carrying no moment,
        the Schur complement K_tt - K_tr K_rr^-1 K_rt); 'fixed': patch rotations held at
        zero (the sub-block K_tt).

    Returns
    -------
    ndarray, shape (3n, 3n)
        Per patch (t_x, t_y, t_z) [N/m].
    """
    K = np.asarray(K, dtype=float)
    if K.ndim != 2 or K.shape[0] != K.shape[1] or K.shape[0] % 6:
        raise ValueError(f"K: expected a square matrix of size 6n, got shape {K.shape}")
    n = K.shape[0] // 6
    idx = np.arange(6 * n).reshape(n, 6)
    it = idx[:, :3].ravel()
    ir = idx[:, 3:].ravel()
    Ktt = K[np.ix_(it, it)]
    if rotations == "fixed":
        return Ktt
    if rotations != "free":
        raise ValueError(f"rotations: expected 'free' or 'fixed', got {rotations!r}")
    Ktr = K[np.ix_(it, ir)]
    Krr = K[np.ix_(ir, ir)]
    out = Ktt - Ktr @ np.linalg.solve(Krr, Ktr.T)
    return 0.5 * (out + out.T)
