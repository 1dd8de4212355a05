"""Assembly of the built-in tissue FE on its mesh (docs/model.md section 10).

The pipeline head shared by the condensed surface operators
(:mod:`phri_spring.physics.continuum.tissue`) and the reference rigid-cuff FE
(:mod:`references.rigid_cuff_fe`, outside the package): mesh (:mod:`phri_spring.physics.continuum.mesh`),
volume stiffness, the forms on the skin under the cuff, the tie of the angular seam
and the split of the dofs into skin under the cuff, fixed and free
(:func:`assemble_tissue_fe`); and the solve for the reactions of displacements
imposed on the skin.

Everything is for E = 1 Pa (the matrices are linear in E). scikit-fem is an optional
dependency (extra ``fe``), imported only inside the functions that need it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .mesh import (DEFAULT_PATCH_GAP, build_mesh, periodic_map, reduce_matrix,
                      reduce_rows, import_skfem)
from ..cuff.geometry import rigid_body_map

__all__ = ["TissueFE", "assemble_tissue_fe"]


def _inward_normal(X):
    r = np.sqrt(X[1] ** 2 + X[2] ** 2)
    return np.stack([np.zeros_like(X[0]), -X[1] / r, -X[2] / r])


def assemble(tm, poisson_ratio, ends, intorder=4, chunk=256):
    """Volume stiffness for E = 1 Pa, vectorised over elements (batched matrix products).

    Returns the vector basis and the (N, N) sparse stiffness matrix.
    """
    sk = import_skfem()
    e = sk["ElementVector"](sk["ElementHex2"]())
    ib = sk["Basis"](tm.mesh, e, intorder=intorder)
    lam, mu = sk["lame_parameters"](1.0, float(poisson_ratio))
    nb = len(ib.basis)
    G = np.stack([np.asarray(ib.basis[i][0].grad) for i in range(nb)])  # (nb, 3, 3, nel, nq)
    nel = G.shape[3]
    dx = np.asarray(ib.dx)                                               # (nel, nq)
    rows, cols, vals = [], [], []
    edofs = ib.element_dofs                                              # (nb, nel)
    for c0 in range(0, nel, chunk):
        c1 = min(nel, c0 + chunk)
        g = G[..., c0:c1, :]                                             # (nb, 3, 3, m, nq)
        eps = 0.5 * (g + g.transpose(0, 2, 1, 3, 4))
        tr = eps[:, 0, 0] + eps[:, 1, 1] + eps[:, 2, 2]                  # (nb, m, nq)
        w = dx[c0:c1]                                                    # (m, nq)
        # (m, nb, nq*9) and (m, nb, nq)
        Ev = eps.reshape(nb, 9, c1 - c0, -1).transpose(2, 0, 3, 1).reshape(c1 - c0, nb, -1)
        Ew = (eps.reshape(nb, 9, c1 - c0, -1) * w[None, None]).transpose(2, 0, 3, 1)
        Ew = Ew.reshape(c1 - c0, nb, -1)
        Tv = tr.transpose(1, 0, 2)
        Tw = (tr * w[None]).transpose(1, 0, 2)
        Ke = (2 * mu * np.matmul(Ev, Ew.transpose(0, 2, 1))
              + lam * np.matmul(Tv, Tw.transpose(0, 2, 1)))
        d = edofs[:, c0:c1].T                                            # (m, nb)
        rows.append(np.repeat(d, nb, axis=1).ravel())
        cols.append(np.tile(d, (1, nb)).ravel())
        vals.append(Ke.ravel())
    K = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(ib.N, ib.N))
    return ib, K


def _facet_arrays(tm, ib, facets, intorder=5):
    """Values of the facet basis on the given skin facets, their weights and points.

    Returns
    -------
    phi : ndarray, shape (nb, 3, nf, nq)
    dx : ndarray, shape (nf, nq)
    X : ndarray, shape (3, nf, nq)
    edofs : ndarray, shape (nb, nf)
    """
    sk = import_skfem()
    fb = sk["FacetBasis"](tm.mesh, ib.elem, facets=facets, intorder=intorder)
    phi = np.stack([np.array(fb.basis[i][0]) for i in range(len(fb.basis))])
    return phi, np.asarray(fb.dx), np.array(fb.global_coordinates()), fb.element_dofs


def _surface_forms(tm, geometry, ib, rigid=True):
    """Mass matrix on the cuff area and the patch load vectors (rigid modes, local normal).

    Returns
    -------
    M : sparse (N, N)
        int phi_i . phi_j dA over the skin under the cuff [m^2].
    B : ndarray, shape (N, 6n) or None
        int_patch e phi_i . m_ej dA, m_ej the six rigid modes of patch e about p_e
        [m^2, m^3].
    C : ndarray, shape (N, n)
        int_patch e phi_i . n(x) dA with the local inward normal n(x) [m^2].
    """
    phi, dx, X, edofs = _facet_arrays(tm, ib, tm.cuff_facets)
    nb, nf = phi.shape[0], phi.shape[2]
    Mloc = np.einsum("iafq,jafq,fq->fij", phi, phi, dx)
    d = edofs.T
    M = sp.csr_matrix((Mloc.ravel(), (np.repeat(d, nb, axis=1).ravel(),
                                      np.tile(d, (1, nb)).ravel())),
                      shape=(ib.N, ib.N))
    # patch of every cuff facet
    owner = np.empty(nf, int)
    pos = {f: k for k, f in enumerate(tm.cuff_facets)}
    for ep, fs in enumerate(tm.patch_facets):
        owner[[pos[f] for f in fs]] = ep
    n = geometry.n
    # the skin's inward unit normal: toward the axis on a circular cylinder, else the
    # normal of the limb's skin on the ray through each point (shape.py)
    nrm = _inward_normal(X) if tm.shape is None else tm.shape.inward_normal(X)
    Cloc = np.einsum("iafq,afq,fq->fi", phi, nrm, dx)
    C = np.zeros((ib.N, n))
    np.add.at(C, (d.ravel(), np.repeat(owner, nb)), Cloc.ravel())
    B = None
    if rigid:
        P = np.asarray(geometry.points, float)[owner]                    # (nf, 3)
        # the rigid motions of patch e about p_e at every quadrature point
        modes = rigid_body_map(np.moveaxis(X - P.T[:, :, None], 0, -1))  # (nf, nq, 3, 6)
        B = np.zeros((ib.N, 6 * n))
        for j in range(6):
            m = np.ascontiguousarray(np.moveaxis(modes[..., j], -1, 0))  # (3, nf, nq)
            Bl = np.einsum("iafq,afq,fq->fi", phi, m, dx)
            np.add.at(B, (d.ravel(), np.repeat(6 * owner + j, nb)), Bl.ravel())
    return M, B, C


def _dof_sets(tm, ib, ends, g, n_red):
    """Reduced dof indices: skin under the cuff (s), fixed (bone and maybe ends), free (I)."""
    x, th, r = tm.comp
    R, t = tm.radius, tm.thickness
    sdofs_full = ib.get_dofs(facets=tm.cuff_facets).all()
    bone = np.nonzero(np.abs(r - (R - t)) <= 1e-9 * R)[0]
    fixed_nodes = bone
    if ends == "fixed":
        xe = np.nonzero((np.abs(x - tm.x_range[0]) <= 1e-12 + 1e-9 * abs(tm.x_range[0]))
                        | (np.abs(x - tm.x_range[1]) <= 1e-12 + 1e-9 * abs(tm.x_range[1])))[0]
        fixed_nodes = np.union1d(bone, xe)
    elif ends != "free":
        raise ValueError(f"ends: expected 'free' or 'fixed', got {ends!r}")
    fixed_full = (3 * fixed_nodes[:, None] + np.arange(3)).ravel()
    s = np.unique(g[sdofs_full])
    fixed = np.setdiff1d(np.unique(g[fixed_full]), s)
    free = np.setdiff1d(np.arange(3 * n_red), np.union1d(s, fixed))
    return s, fixed, free


def factor(A):
    return spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A",
                     options=dict(SymmetricMode=True))


def _solve_imposed(Kr, s, free, Us):
    """Reactions on s of the displacements Us imposed on s (others fixed at 0 or free)."""
    Kss = Kr[s][:, s]
    Ksi = Kr[s][:, free]
    Kis = Kr[free][:, s]
    Kii = Kr[free][:, free]
    lu = factor(Kii)
    Ui = -lu.solve(np.asarray(Kis @ Us))
    return np.asarray(Kss @ Us) + np.asarray(Ksi @ Ui)


@dataclass
class TissueFE:
    """The tissue FE under one cuff for E = 1 Pa, its angular seam tied (reduced dofs).

    Attributes
    ----------
    mesh : fe_mesh._TissueMesh
        The mesh (``mesh.mesh`` the scikit-fem ``MeshHex2``, ``x_range`` [m], ...).
    basis : skfem.Basis
        The vector basis of the volume stiffness (unreduced dofs).
    dof_map : ndarray of int, shape (3 * nnodes,)
        Reduced index of every vector dof (node k, component c -> 3 k + c).
    n_nodes : int
        Number of nodes after the seam is tied (3 n_nodes reduced dofs).
    K : sparse matrix, shape (3 n_nodes, 3 n_nodes)
        Volume stiffness [N/m per Pa].
    M : sparse matrix, shape (3 n_nodes, 3 n_nodes)
        int phi_i . phi_j dA over the skin under the cuff [m^2].
    B : ndarray, shape (3 n_nodes, 6n), or None
        Per patch e and rigid mode j about p_e, int_patch phi_i . m_ej dA [m^2, m^3].
    C : ndarray, shape (3 n_nodes, n)
        Per patch, int_patch phi_i . n(x) dA with the local inward normal [m^2].
    skin, free : ndarray of int
        Reduced dofs on the skin under the cuff and those neither there nor fixed.
    """

    mesh: object
    basis: object
    dof_map: np.ndarray
    n_nodes: int
    K: object
    M: object
    B: np.ndarray | None
    C: np.ndarray
    skin: np.ndarray
    free: np.ndarray

    def skin_mass_lu(self):
        """LU factors of M on the skin dofs: solves for the L2-projected traction [Pa]."""
        s = self.skin
        return spla.splu(self.M[s][:, s].tocsc())

    def skin_reactions(self, Us):
        """Consistent nodal reactions on the skin dofs of displacements ``Us`` imposed there.

        Parameters
        ----------
        Us : ndarray, shape (len(skin), k)
            k displacement fields of the skin dofs [m]; the fixed dofs stay at 0.

        Returns
        -------
        ndarray, shape (len(skin), k)
            Reactions [N per Pa of E].
        """
        return _solve_imposed(self.K, self.skin, self.free, Us)


def assemble_tissue_fe(geometry, thickness, poisson_ratio, level, length_factor, ends, *,
                       patch_modes: bool = True,
                       patch_gap: float = DEFAULT_PATCH_GAP, bone=None) -> TissueFE:
    """Mesh, assemble (E = 1 Pa) and tie the seam of the tissue under a cuff.

    Parameters
    ----------
    geometry : CuffGeometry
        The patches (all rows of one radius R [m]).
    thickness : float
        Tissue thickness t [m], 0 < t < R.
    poisson_ratio : float
        nu [-].
    level : int
        Mesh level: level x level triquadratic elements on each patch.
    length_factor : float
        Tissue modelled beyond each axial edge of the cuff, in thicknesses [-].
    ends : {'fixed', 'free'}
        The two end faces of the modelled tissue tube: clamped or traction-free.
    patch_modes : bool, optional
        Assemble B, the loads of the patches' rigid modes (else ``B`` is None).
    patch_gap : float, optional
        Free skin between neighbouring patches' plates [m]
        (:func:`~phri_spring.physics.continuum.mesh.patch_plates`).
    bone : sequence (y_c, z_c, r_b) [m], optional
        A circular bone; None: the skin moved inward by the thickness
        (:mod:`~phri_spring.physics.continuum.shape`, which also maps the mesh onto a
        non-circular or tapered limb).

    Returns
    -------
    TissueFE
    """
    tm = build_mesh(geometry, thickness, level, length_factor, patch_gap, bone)
    ib, Kfull = assemble(tm, poisson_ratio, ends)
    M, B, C = _surface_forms(tm, geometry, ib, rigid=patch_modes)
    g, n_red = periodic_map(tm.comp, tm.thickness)
    s, _, free = _dof_sets(tm, ib, ends, g, n_red)
    return TissueFE(mesh=tm, basis=ib, dof_map=g, n_nodes=n_red,
                    K=reduce_matrix(Kfull, g, n_red), M=reduce_matrix(M, g, n_red),
                    B=None if B is None else np.asarray(reduce_rows(B, g, n_red)),
                    C=np.asarray(reduce_rows(C, g, n_red)), skin=s, free=free)
