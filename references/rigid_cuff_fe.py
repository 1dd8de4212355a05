"""Reference rigid-cuff model: the checks of the condensed surface operators.

* :func:`direct_rigid_cuff_response` -- the FE of a rigid cuff imposed directly on the
  patches' plates (no condensation onto patches), from the same mesh and
  assembly (:func:`phri_spring.physics.continuum.assembly.assemble_tissue_fe`) as
  :func:`phri_spring.physics.continuum.tissue.condensed_surface_operators`.
* :func:`rigid_cuff_patch_forces` -- the patch normal forces of a rigid cuff bonded over
  the patches of a condensed stiffness K, solved independently of the contact solver.

scikit-fem is an optional dependency (extra ``fe``), imported only inside the
functions that need it.
"""

from __future__ import annotations

import time

import numpy as np

from phri_spring.physics.continuum.assembly import assemble_tissue_fe
from phri_spring.physics.continuum.mesh import DEFAULT_LENGTH_FACTOR, DEFAULT_PATCH_GAP
from phri_spring.physics.cuff.geometry import rigid_body_map

__all__ = ["rigid_cuff_map", "rigid_cuff_patch_forces", "direct_rigid_cuff_response"]


def rigid_cuff_map(points, rotations: bool = True) -> np.ndarray:
    """T: cuff motion u = (t, w) about the cuff origin to the patch dofs q = T u.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Patch centres p_e [m].
    rotations : bool
        True: q per patch (t + w x p_e, w), shape (6n, 6); False: (t + w x p_e), (3n, 6).

    Returns
    -------
    ndarray, shape (6n, 6) or (3n, 6)
        The :func:`~phri_spring.physics.cuff.geometry.rigid_body_map` of the patch centres,
        patch-major [-, m].
    """
    return rigid_body_map(points, rotations=rotations).reshape(-1, 6)


def rigid_cuff_patch_forces(K, geometry, wrench, N=None) -> np.ndarray:
    """Patch normal forces of a rigid cuff bonded over the patches under a wrench.

    Solves (T^T K T) u = W, F = K T u; normal force f_e = n_e . F_e (or ``N @ q``).

    Parameters
    ----------
    K : array_like, shape (6n, 6n) or (3n, 3n)
        Condensed surface stiffness [N/m, N/rad; N*m/m, N*m/rad].
    geometry : CuffGeometry
    wrench : array_like, shape (6,) or (m, 6)
        Wrench on the cuff about the cuff origin, cuff frame [N, N*m].
    N : array_like, shape (n, 6n), optional
        Local-normal output (6n K only) [N/m, N/rad].

    Returns
    -------
    ndarray, shape (n,) or (m, n)
        Normal force increments [N], compression positive.
    """
    K = np.asarray(K, float)
    n = geometry.n
    rot = K.shape[0] == 6 * n
    T = rigid_cuff_map(geometry.points, rotations=rot)
    W = np.atleast_2d(np.asarray(wrench, float))
    u = np.linalg.solve(T.T @ K @ T, W.T)
    q = T @ u
    if N is not None:
        out = (np.asarray(N, float) @ q).T
    else:
        F = (K @ q).T.reshape(W.shape[0], n, 6 if rot else 3)[:, :, :3]
        out = np.einsum("mej,ej->me", F, geometry.normals)
    return out[0] if np.ndim(wrench) == 1 else out


def direct_rigid_cuff_response(geometry, thickness, poisson_ratio, *, level,
                               length_factor=DEFAULT_LENGTH_FACTOR, ends="fixed",
                               patch_gap=DEFAULT_PATCH_GAP):
    """Reference FE: a rigid cuff imposed directly on all patches' plates (E = 1 Pa).

    The six rigid motions of the cuff (about the cuff origin) are imposed on every skin
    node under a plate (``patch_gap`` = 0: the whole tiled area; the strips of free skin
    between plates stay free); the consistent nodal reactions give the cuff stiffness
    (6 x 6, E = 1) and, through the recovered traction, each patch's normal force (the
    integral over the patch of n(x) . lambda with the local normal).

    Parameters
    ----------
    geometry, thickness, poisson_ratio, level
        The cuff's patches, tissue thickness [m], Poisson ratio [-] and mesh level, as
        :func:`~phri_spring.physics.continuum.assembly.assemble_tissue_fe`.
    length_factor, ends : optional
        Modelled tissue beyond the cuff [thicknesses] and its end faces ('fixed' or
        'free'), as :func:`~phri_spring.physics.continuum.tissue.condensed_surface_operators`.
    patch_gap : float, optional
        Free skin between neighbouring patches' plates [m], as
        :func:`~phri_spring.physics.continuum.tissue.condensed_surface_operators`.

    Returns
    -------
    Kc : ndarray, shape (6, 6)
        Cuff stiffness about the cuff origin for E = 1 Pa [N/m, N/rad; N*m/m, N*m/rad
        per Pa].
    Fn : ndarray, shape (n, 6)
        Patch normal forces per unit cuff motion (columns t_x .. w_z) [N/m, N/rad per Pa].
    info : dict
        ``level``, ``n_dofs``, ``seconds``, ``length`` (modelled tissue length [m]).
    """
    t0 = time.perf_counter()
    fe = assemble_tissue_fe(geometry, thickness, poisson_ratio, level, length_factor, ends,
                            patch_modes=False, patch_gap=patch_gap)
    s, g, n_red = fe.skin, fe.dof_map, fe.n_nodes
    # node coordinates and vector component of the reduced dofs
    doflocs = fe.mesh.mesh.doflocs
    xyz = np.zeros((3, 3 * n_red))
    cmp_ = np.zeros(3 * n_red, int)
    xyz[:, g] = np.repeat(doflocs, 3, axis=1)
    cmp_[g] = np.tile(np.arange(3), doflocs.shape[1])
    # each skin dof moves by its component of the cuff's rigid motion
    Us = rigid_body_map(xyz[:, s].T)[np.arange(len(s)), cmp_[s]]     # (len(s), 6)
    Rs = fe.skin_reactions(Us)
    # wrench of the nodal reactions about the origin
    Kc = Us.T @ Rs
    lam = fe.skin_mass_lu().solve(Rs)
    Fn = fe.C[s].T @ lam
    info = dict(level=int(level), n_dofs=int(3 * n_red), seconds=time.perf_counter() - t0,
                length=float(fe.mesh.x_range[1] - fe.mesh.x_range[0]),
                patch_gap=float(fe.mesh.patch_gap))
    return 0.5 * (Kc + Kc.T), Fn, info
