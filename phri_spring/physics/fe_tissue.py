"""Built-in 3D finite-element model of the tissue layer (docs/model.md section 10).

The arm's soft tissue is a linear elastic tube between a rigid, fixed bone
(r = R - t) and the skin (r = R), meshed with structured triquadratic hexahedra
(27 nodes, ``ElementHex2`` on a ``MeshHex2`` of scikit-fem) in cylindrical
coordinates. Quadratic elements converge for Poisson ratios up to 0.45 (above it they
lock: the stiffness converges slowly from above, by 7-8 % per refinement at 0.49, so
:data:`~phri_spring.physics.fe_mesh.MAX_POISSON_RATIO` refuses it), and
since the mesh is isoparametric (its nodes lie on the true cylinders) every
rigid motion of the skin is represented exactly.

Two products:

* :func:`condensed_surface_stiffness` -- the 6n x 6n stiffness of the skin
  under the n cuff patches, each patch a rigid plate bonded to the skin, every
  other skin point free, the bone fixed (see ``docs/coupled-fe.md``).
* :func:`flat_punch_stiffness` / :func:`modulus_from_indenter` -- a rigid,
  frictionless flat cylindrical punch on a layer bonded to a rigid base
  (axisymmetric quadratic FE), to turn indenter stiffness into a modulus.

Everything is linear in Young's modulus: the matrices are built for E = 1 Pa
and scaled. scikit-fem is an optional dependency (extra ``fe``), imported only
inside the functions that need it. The mesh (grading, patch facets, the periodic
seam) is built in :mod:`phri_spring.physics.fe_mesh`.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .fe_mesh import (FE_EXTRA_HINT, _build_mesh, _check_material, _graded,  # noqa: F401
                      _periodic_map, _reduce_matrix, _reduce_rows, _single_radius, _skfem)

__all__ = [
    "FE_EXTRA_HINT",
    "DEFAULT_LEVEL",
    "DEFAULT_LENGTH_FACTOR",
    "PUNCH_RADIUS",
    "SurfaceOperators",
    "condensed_surface_stiffness",
    "condensed_surface_operators",
    "translational_block",
    "rigid_cuff_map",
    "rigid_cuff_patch_forces",
    "direct_rigid_cuff_response",
    "flat_punch_stiffness",
    "modulus_from_indenter",
    "sneddon_punch_stiffness",
]

#: Mesh level shipped by default: level L puts L x L quadratic elements on each patch.
DEFAULT_LEVEL = 3
#: Tissue modelled beyond each axial edge of the cuff, in tissue thicknesses.
DEFAULT_LENGTH_FACTOR = 6.0
#: Radius of the paper's 9 mm flat indenter [m].
PUNCH_RADIUS = 0.0045


def _lame(E, nu):
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


# ----------------------------------------------------------------- assembly + solve

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
    info : dict
        Mesh size and timings: ``level``, ``n_dofs``, ``n_elements``, ``n_surface_dofs``,
        ``length`` (modelled tissue length [m]), ``ends``, ``asymmetry`` (relative, before
        symmetrisation), ``seconds``.
    """

    K: np.ndarray
    N: np.ndarray
    info: dict


def _rigid_modes(X, p):
    """The 6 rigid modes about point p at points X: list of 6 arrays shape (3, ...)."""
    d = [X[i] - p[i] for i in range(3)]
    z = np.zeros_like(X[0])
    o = np.ones_like(X[0])
    modes = [np.stack([o, z, z]), np.stack([z, o, z]), np.stack([z, z, o])]
    # w_k e_k x d
    modes.append(np.stack([z, -d[2], d[1]]))   # e_x x d
    modes.append(np.stack([d[2], z, -d[0]]))   # e_y x d
    modes.append(np.stack([-d[1], d[0], z]))   # e_z x d
    return modes


def _inward_normal(X):
    r = np.sqrt(X[1] ** 2 + X[2] ** 2)
    return np.stack([np.zeros_like(X[0]), -X[1] / r, -X[2] / r])


def _assemble(tm, poisson_ratio, ends, intorder=4, chunk=256):
    """Volume stiffness for E = 1 Pa, vectorised over elements (batched matrix products).

    Returns the vector basis and the (N, N) sparse stiffness matrix.
    """
    sk = _skfem()
    e = sk["ElementVector"](sk["ElementHex2"]())
    ib = sk["Basis"](tm.mesh, e, intorder=intorder)
    lam, mu = _lame(1.0, float(poisson_ratio))
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
    sk = _skfem()
    fb = sk["FacetBasis"](tm.mesh, ib.elem, facets=facets, intorder=intorder)
    phi = np.stack([np.array(fb.basis[i][0]) for i in range(len(fb.basis))])
    return phi, np.asarray(fb.dx), np.array(fb.global_coordinates()), fb.element_dofs


def _surface_forms(tm, geometry, ib, rigid=True):
    """Mass matrix on the cuff area and the patch load vectors (rigid modes, local normal).

    Returns
    -------
    M : sparse (N, N)
        int phi_i . phi_j dA over the skin under the cuff.
    B : ndarray, shape (N, 6n) or None
        int_patch e phi_i . m_ej dA, m_ej the six rigid modes of patch e about p_e.
    C : ndarray, shape (N, n)
        int_patch e phi_i . n(x) dA with the local inward normal n(x).
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
    nrm = _inward_normal(X)                                              # (3, nf, nq)
    Cloc = np.einsum("iafq,afq,fq->fi", phi, nrm, dx)
    C = np.zeros((ib.N, n))
    np.add.at(C, (d.ravel(), np.repeat(owner, nb)), Cloc.ravel())
    B = None
    if rigid:
        P = np.asarray(geometry.points, float)[owner]                    # (nf, 3)
        modes = _rigid_modes(X, P.T[:, :, None])                         # 6 x (3, nf, nq)
        B = np.zeros((ib.N, 6 * n))
        for j, m in enumerate(modes):
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


def _factor(A):
    return spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A",
                     options=dict(SymmetricMode=True))


def _solve_imposed(Kr, s, free, Us):
    """Reactions on s of the displacements Us imposed on s (others fixed at 0 or free)."""
    Kss = Kr[s][:, s]
    Ksi = Kr[s][:, free]
    Kis = Kr[free][:, s]
    Kii = Kr[free][:, free]
    lu = _factor(Kii)
    Ui = -lu.solve(np.asarray(Kis @ Us))
    return np.asarray(Kss @ Us) + np.asarray(Ksi @ Ui)


#: the last few E = 1 results of this process, most recent last
_UNIT_CACHE: "OrderedDict[tuple, tuple]" = OrderedDict()
_UNIT_CACHE_SIZE = 8


def _geometry_key(geometry):
    arrays = (np.asarray(geometry.points, float), np.asarray(geometry.span, float),
              np.asarray(geometry.row_width, float), np.asarray(geometry.radius, float),
              np.asarray(geometry.theta, float), np.asarray(geometry.x, float))
    return (tuple(geometry.labels),) + tuple(a.tobytes() for a in arrays)


def _build_unit_operators(geometry, thickness, poisson_ratio, level, length_factor, ends):
    import time
    t0 = time.perf_counter()
    tm = _build_mesh(geometry, thickness, level, length_factor)
    ib, Kfull = _assemble(tm, poisson_ratio, ends)
    M, B, C = _surface_forms(tm, geometry, ib)
    g, n_red = _periodic_map(tm.comp, tm.thickness)
    Kr = _reduce_matrix(Kfull, g, n_red)
    Mr = _reduce_matrix(M, g, n_red)
    Br = np.asarray(_reduce_rows(B, g, n_red))
    Cr = np.asarray(_reduce_rows(C, g, n_red))
    s, fixed, free = _dof_sets(tm, ib, ends, g, n_red)
    Mss = Mr[s][:, s].tocsc()
    mlu = spla.splu(Mss)
    Bs, Cs = Br[s], Cr[s]
    A = mlu.solve(Bs)                        # imposed skin displacement per patch dof
    Rs = _solve_imposed(Kr, s, free, A)      # consistent reactions on s
    lam = mlu.solve(Rs)                      # recovered (L2-projected) traction
    K = Bs.T @ lam
    N = Cs.T @ lam
    scale = np.max(np.abs(K))
    asym = float(np.max(np.abs(K - K.T)) / scale)
    K = 0.5 * (K + K.T)
    info = dict(level=int(level), n_dofs=int(3 * n_red), n_elements=int(tm.mesh.nelements),
                n_surface_dofs=int(len(s)), length=float(tm.x_range[1] - tm.x_range[0]),
                length_factor=float(length_factor), ends=ends, asymmetry=asym,
                seconds=time.perf_counter() - t0)
    return K, N, info


def condensed_surface_operators(geometry, thickness, young_modulus, poisson_ratio, *,
                                level: int = DEFAULT_LEVEL,
                                length_factor: float = DEFAULT_LENGTH_FACTOR,
                                ends: str = "fixed") -> SurfaceOperators:
    """K and the local-normal output N of the tissue under the cuff patches.

    Same parameters as :func:`condensed_surface_stiffness`, plus

    Parameters
    ----------
    length_factor : float
        Tissue modelled beyond each axial edge of the cuff, in thicknesses [-].
    ends : {'fixed', 'free'}
        The two end faces of the modelled tissue tube: clamped or traction-free.

    Returns
    -------
    SurfaceOperators
    """
    R = _single_radius(geometry)
    _check_material(thickness=thickness, poisson_ratio=poisson_ratio,
                    young_modulus=young_modulus, radius=R)
    if ends not in ("fixed", "free"):
        raise ValueError(f"ends: expected 'fixed' or 'free', got {ends!r}")
    lf = float(length_factor)
    if not (math.isfinite(lf) and lf > 0):
        raise ValueError(f"length_factor: expected a finite value > 0, got {length_factor!r}")
    if int(level) < 1:
        raise ValueError(f"level: expected an integer >= 1, got {level!r}")
    key = (_geometry_key(geometry), float(thickness), float(poisson_ratio), int(level), lf,
           str(ends))
    if key in _UNIT_CACHE:
        _UNIT_CACHE.move_to_end(key)
    else:
        _UNIT_CACHE[key] = _build_unit_operators(geometry, float(thickness),
                                                 float(poisson_ratio), int(level), lf, ends)
        while len(_UNIT_CACHE) > _UNIT_CACHE_SIZE:
            _UNIT_CACHE.popitem(last=False)
    K1, N1, info = _UNIT_CACHE[key]
    E = float(young_modulus)
    return SurfaceOperators(K=K1 * E, N=N1 * E, info=dict(info))


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
        ``length_factor``, ``ends``: see :func:`condensed_surface_operators`.

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
        Rows of different radii, overlapping patches, t, E or nu out of range.
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


def rigid_cuff_map(points, rotations: bool = True) -> np.ndarray:
    """T: cuff motion u = (t, w) about the cuff origin to the patch dofs q = T u.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Patch centres p_e [m].
    rotations : bool
        True: q per patch (t + w x p_e, w), shape (6n, 6); False: (t + w x p_e), (3n, 6).
    """
    points = np.asarray(points, float)
    n = len(points)
    k = 6 if rotations else 3
    T = np.zeros((n, k, 6))
    T[:, :3, :3] = np.eye(3)
    # w x p = -[p]x w
    px = np.zeros((n, 3, 3))
    px[:, 0, 1], px[:, 0, 2] = -points[:, 2], points[:, 1]
    px[:, 1, 0], px[:, 1, 2] = points[:, 2], -points[:, 0]
    px[:, 2, 0], px[:, 2, 1] = -points[:, 1], points[:, 0]
    T[:, :3, 3:] = -px
    if rotations:
        T[:, 3:, 3:] = np.eye(3)
    return T.reshape(n * k, 6)


def rigid_cuff_patch_forces(K, geometry, wrench, N=None) -> np.ndarray:
    """Patch normal forces of a rigid cuff bonded over the patches under a wrench.

    Solves (T^T K T) u = W, F = K T u; normal force f_e = n_e . F_e (or ``N @ q``).

    Parameters
    ----------
    K : array_like, shape (6n, 6n) or (3n, 3n)
    geometry : CuffGeometry
    wrench : array_like, shape (6,) or (m, 6)
        Wrench on the cuff about the cuff origin, cuff frame [N, N*m].
    N : array_like, shape (n, 6n), optional
        Local-normal output (6n K only).

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
                               length_factor=DEFAULT_LENGTH_FACTOR, ends="fixed"):
    """Reference FE: a rigid cuff imposed directly on the whole tiled area (E = 1 Pa).

    The six rigid motions of the cuff (about the cuff origin) are imposed on every skin
    node under the cuff; the consistent nodal reactions give the cuff stiffness
    (6 x 6, E = 1) and, through the recovered traction, each patch's normal force (the
    integral over the patch of n(x) . lambda with the local normal).

    Returns
    -------
    Kc : ndarray, shape (6, 6)
        Cuff stiffness about the cuff origin for E = 1 Pa.
    Fn : ndarray, shape (n, 6)
        Patch normal forces per unit cuff motion (columns t_x .. w_z).
    info : dict
    """
    import time
    t0 = time.perf_counter()
    tm = _build_mesh(geometry, thickness, level, length_factor)
    ib, Kfull = _assemble(tm, poisson_ratio, ends)
    M, _, C = _surface_forms(tm, geometry, ib, rigid=False)
    g, n_red = _periodic_map(tm.comp, tm.thickness)
    Kr = _reduce_matrix(Kfull, g, n_red)
    Mr = _reduce_matrix(M, g, n_red)
    Cr = np.asarray(_reduce_rows(C, g, n_red))
    s, fixed, free = _dof_sets(tm, ib, ends, g, n_red)
    # node coordinates of reduced dofs
    xyz_full = np.repeat(tm.mesh.doflocs, 3, axis=1)            # (3, 3 nnodes)
    comp_full = np.tile(np.arange(3), tm.mesh.doflocs.shape[1])
    xyz = np.zeros((3, 3 * n_red))
    cmp_ = np.zeros(3 * n_red, int)
    xyz[:, g] = xyz_full
    cmp_[g] = comp_full
    X = xyz[:, s]
    Us = np.zeros((len(s), 6))
    for j, m in enumerate(_rigid_modes(X, np.zeros(3))):
        Us[:, j] = m[cmp_[s], np.arange(len(s))]
    Rs = _solve_imposed(Kr, s, free, Us)
    # wrench of the nodal reactions about the origin
    Kc = Us.T @ Rs
    lam = spla.splu(Mr[s][:, s].tocsc()).solve(Rs)
    Fn = Cr[s].T @ lam
    info = dict(level=int(level), n_dofs=int(3 * n_red), seconds=time.perf_counter() - t0,
                length=float(tm.x_range[1] - tm.x_range[0]))
    return 0.5 * (Kc + Kc.T), Fn, info


# --------------------------------------------------------------------------- punch

def sneddon_punch_stiffness(young_modulus, poisson_ratio, radius=PUNCH_RADIUS):
    """Sneddon's flat punch on a half-space: 2 a E / (1 - nu^2) [N/m]."""
    return 2.0 * radius * np.asarray(young_modulus, float) / (1.0 - float(poisson_ratio) ** 2)


@lru_cache(maxsize=64)
def _unit_punch(thickness, poisson_ratio, radius, level):
    sk = _skfem()
    a, t = radius, thickness
    # element sizes: h0 at the punch edge, growing geometrically away from it
    h0 = a / (100.0 * level ** 2)
    q = 1.25 ** (1.0 / level)
    inner = a - _graded(a, h0, q)[::-1]
    inner = np.concatenate([[0.0], inner[1:], [a]]) if inner[0] > 0 else inner
    outer = a + _graded(10.0 * max(t, a), h0, q)
    rn = np.unique(np.concatenate([[0.0], inner, [a], outer]))
    zn = np.unique(np.concatenate([[0.0], -_graded(t, h0, q)]))
    zn[0] = -t
    m = sk["MeshQuad"].init_tensor(rn, zn)
    e = sk["ElementVector"](sk["ElementQuad2"]())
    ib = sk["Basis"](m, e, intorder=4)
    lam, mu = _lame(1.0, poisson_ratio)

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
    _check_material(thickness=thickness, poisson_ratio=poisson_ratio,
                    young_modulus=young_modulus)
    a = float(radius)
    if not (math.isfinite(a) and a > 0):
        raise ValueError(f"radius: expected a finite value > 0 m, got {radius!r}")
    if int(level) < 1:
        raise ValueError(f"level: expected an integer >= 1, got {level}")
    return float(young_modulus) * _unit_punch(float(thickness), float(poisson_ratio), a,
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
    radius : float, optional
        Indenter radius [m].

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
