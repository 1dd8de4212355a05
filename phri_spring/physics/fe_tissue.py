"""Built-in 3D finite-element model of the tissue layer (docs/model.md section 10).

The arm's soft tissue is a linear elastic tube between a rigid, fixed bone
(r = R - t) and the skin (r = R), meshed with structured triquadratic hexahedra
(27 nodes, ``ElementHex2`` on a ``MeshHex2`` of scikit-fem) in cylindrical
coordinates. Quadratic elements do not lock for Poisson ratios up to 0.45, and
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
inside the functions that need it.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import UsageError

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

FE_EXTRA_HINT = "the coupled model's built-in FE needs scikit-fem: pip install -e .[fe]"

#: Mesh level shipped by default: level L puts L x L quadratic elements on each patch.
DEFAULT_LEVEL = 3
#: Tissue modelled beyond each axial edge of the cuff, in tissue thicknesses.
DEFAULT_LENGTH_FACTOR = 6.0
#: Radius of the paper's 9 mm flat indenter [m].
PUNCH_RADIUS = 0.0045

_RIGID_TOL = 1e-9
# mesh grading (see docs/coupled-fe.md, "The mesh"): element sizes in units of the
# patch element size h = patch width / level
_FREE_SIZE = 1.5       # free skin between/around the patches, along the circumference
_RADIAL_SIZE = 1.5     # a layer thicker than 1.5 patch widths gets more radial elements
_AXIAL_GROWTH = 1.6    # growth ratio of the elements beyond the cuff's axial edges
_FREE_GROWTH = 1.6     # growth ratio of the elements over free skin between patches
_EDGE_GRADING = 2.0    # size ratio of neighbouring elements in a patch, toward a free edge
_RADIAL_GROWTH = 1.5   # size ratio of radial elements, from the skin inward


def _skfem():
    """Import scikit-fem lazily; a one-line :class:`UsageError` when the extra is missing."""
    try:
        import skfem  # noqa: F401
        from skfem import (Basis, BilinearForm, ElementHex2, ElementQuad2, ElementVector,
                           FacetBasis, LinearForm, MeshHex, MeshHex2, MeshQuad, asm)
        from skfem.models.elasticity import linear_elasticity
    except ImportError:  # pragma: no cover - exercised by monkeypatching in the tests
        raise UsageError(FE_EXTRA_HINT) from None
    return dict(Basis=Basis, BilinearForm=BilinearForm, ElementHex2=ElementHex2,
                ElementQuad2=ElementQuad2, ElementVector=ElementVector, FacetBasis=FacetBasis,
                LinearForm=LinearForm, MeshHex=MeshHex, MeshHex2=MeshHex2, MeshQuad=MeshQuad,
                asm=asm, linear_elasticity=linear_elasticity)


def _check_material(thickness=None, poisson_ratio=None, young_modulus=None, radius=None):
    if young_modulus is not None:
        E = float(young_modulus)
        if not (math.isfinite(E) and E > 0):
            raise ValueError("young_modulus: expected a finite value > 0 Pa, "
                             f"got {young_modulus!r}")
    if poisson_ratio is not None:
        nu = float(poisson_ratio)
        if not (math.isfinite(nu) and -1.0 < nu < 0.5):
            raise ValueError(f"poisson_ratio: expected a value in (-1, 0.5), got {poisson_ratio!r}")
    if thickness is not None:
        t = float(thickness)
        if not (math.isfinite(t) and t > 0):
            raise ValueError(f"thickness: expected a finite value > 0 m, got {thickness!r}")
        if radius is not None and not t < radius:
            raise ValueError(f"thickness: expected less than the cuff radius {radius} m, "
                             f"got {thickness!r}")


def _lame(E, nu):
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


# --------------------------------------------------------------------------- mesh

@dataclass
class _Intervals:
    """Breakpoints of one coordinate, which interval each patch/row covers."""

    nodes: np.ndarray      # element boundaries, increasing
    lo: np.ndarray         # per item: start of its interval
    hi: np.ndarray         # per item: end of its interval


def _patch_sizes(width, level, free_lo, free_hi):
    """Sizes of the ``level`` elements across one patch, graded toward free skin edges.

    At a patch edge bordering free skin the bonded plate's traction is singular; the
    elements there shrink geometrically (ratio ``_EDGE_GRADING``) toward that edge.
    """
    k = np.arange(level)
    if free_lo and free_hi:
        e = np.minimum(k, level - 1 - k)
    elif free_lo:
        e = k
    elif free_hi:
        e = level - 1 - k
    else:
        e = np.zeros(level)
    sz = _EDGE_GRADING ** e
    return sz / sz.sum() * width


def _gap_sizes(length, h_lo, h_hi, h_max):
    """Element sizes over free skin of ``length``, growing from h_lo / h_hi at its ends."""
    left, right = [], []
    sl, sr, tot = h_lo, h_hi, 0.0
    while True:
        if sl <= sr:
            if tot + sl > length * (1 + 1e-9):
                break
            left.append(sl)
            tot += sl
            sl = min(sl * _FREE_GROWTH, h_max)
        else:
            if tot + sr > length * (1 + 1e-9):
                break
            right.append(sr)
            tot += sr
            sr = min(sr * _FREE_GROWTH, h_max)
    sizes = np.array(left + right[::-1]) if (left or right) else np.array([length])
    return sizes / sizes.sum() * length


def _line_nodes(lo, hi, level, h_max, start, end, start_free, end_free):
    """Element boundaries over [start, end] for sorted, non-overlapping patch intervals.

    ``start_free`` / ``end_free``: the first / last patch's outer edge borders free skin
    even where it coincides with ``start`` / ``end``. Returns the nodes and the sizes of
    the elements at the first patch's low edge and the last patch's high edge.
    """
    m = len(lo)
    nodes = [start]
    cur, cur_h = start, h_max
    first_edge_h = last_edge_h = None
    for k in range(m):
        gap_before = lo[k] - cur
        gap_after = (lo[k + 1] if k + 1 < m else end) - hi[k]
        free_lo = gap_before > 1e-9 or (k == 0 and start_free)
        free_hi = gap_after > 1e-9 or (k == m - 1 and end_free)
        ps = _patch_sizes(hi[k] - lo[k], level, free_lo, free_hi)
        if gap_before > 1e-9:
            gs = _gap_sizes(gap_before, cur_h, ps[0], h_max)
            nodes.extend(cur + np.cumsum(gs)[:-1])
            nodes.append(lo[k])
        nodes.extend(lo[k] + np.cumsum(ps)[:-1])
        nodes.append(hi[k])
        if k == 0:
            first_edge_h = ps[0]
        last_edge_h = ps[-1]
        cur, cur_h = hi[k], ps[-1]
    if end - cur > 1e-9:
        gs = _gap_sizes(end - cur, cur_h, h_max, h_max)
        nodes.extend(cur + np.cumsum(gs)[:-1])
        nodes.append(end)
    return np.array(nodes), first_edge_h, last_edge_h


def _angular_breakpoints(theta, span, level):
    """Element boundaries in theta over one full turn [theta_seam, theta_seam + 2 pi].

    Parameters
    ----------
    theta, span : ndarray, shape (m,)
        Centre and width of the m distinct angular locations [rad].
    """
    two_pi = 2 * np.pi
    order = np.argsort(np.mod(theta, two_pi))
    c = np.mod(theta[order], two_pi)
    s = span[order]
    lo, hi = c - s / 2, c + s / 2
    total = float(np.sum(s))
    if total > two_pi * (1 + 1e-12):
        raise ValueError(f"the angular locations cover {np.degrees(total):.6g} deg; "
                         "expected at most 360 deg")
    m = len(c)
    for k in range(m):
        nxt = lo[(k + 1) % m] + (two_pi if k == m - 1 else 0.0)
        if hi[k] > nxt + 1e-9:
            raise ValueError("cuff patches overlap in angle; expected patches that tile or "
                             "leave gaps (angle width <= angle step)")
    gaps = np.array([lo[(k + 1) % m] + (two_pi if k == m - 1 else 0.0) - hi[k]
                     for k in range(m)])
    gaps[np.abs(gaps) < 1e-9] = 0.0
    h_max = _FREE_SIZE * float(np.min(s)) / level
    # seam: the middle of the largest gap (or a patch edge when the patches close the circle)
    kg = int(np.argmax(gaps))
    seam = hi[kg] + gaps[kg] / 2
    # patches in walking order from the seam, unwrapped to [seam, seam + 2 pi]
    idx = [(kg + 1 + i) % m for i in range(m)]
    a = np.array([lo[k] for k in idx])
    a = seam + np.mod(a - seam + 1e-9, two_pi) - 1e-9
    b = a + s[idx]
    nodes, _, _ = _line_nodes(a, b, level, h_max, seam, seam + two_pi, False, False)
    nodes[-1] = seam + two_pi
    lo_out = np.empty(m)
    hi_out = np.empty(m)
    lo_out[order[idx]], hi_out[order[idx]] = a, b
    return _Intervals(nodes, lo_out, hi_out)


def _graded(length, h0, ratio):
    """Node positions (0, length] of elements h0, h0 ratio, h0 ratio^2, ...

    The sizes do not depend on ``length`` except for the last element, which ends
    exactly at ``length``, so that meshes of different lengths agree near the start.
    """
    pos = []
    h, tot = h0, 0.0
    while tot + h < length * (1 - 1e-9):
        tot += h
        pos.append(tot)
        h *= ratio
    pos.append(length)
    return np.array(pos)


def _axial_breakpoints(x, width, level, extension, ratio=_AXIAL_GROWTH):
    order = np.argsort(x)
    lo, hi = x[order] - width[order] / 2, x[order] + width[order] / 2
    for k in range(len(lo) - 1):
        if hi[k] > lo[k + 1] + 1e-9:
            raise ValueError("cuff rows overlap along the arm; expected rows that tile or "
                             "leave gaps (row distance >= row width)")
    h_max = _FREE_SIZE * float(np.min(width)) / level
    inner, h_first, h_last = _line_nodes(lo, hi, level, h_max, lo[0], hi[-1], True, True)
    ext_lo = _graded(extension, h_first, ratio)
    ext_hi = _graded(extension, h_last, ratio)
    nodes = np.concatenate([inner[0] - ext_lo[::-1], inner, inner[-1] + ext_hi])
    lo_out, hi_out = np.empty(len(x)), np.empty(len(x))
    lo_out[order], hi_out[order] = lo, hi
    return _Intervals(nodes, lo_out, hi_out)


@dataclass
class _TissueMesh:
    mesh: object              # MeshHex2 in Cartesian coordinates
    comp: np.ndarray          # (3, ndofloc): (x, theta, r) of every mesh node
    radius: float
    thickness: float
    patch_facets: list        # per patch: facet indices on the skin under it
    cuff_facets: np.ndarray
    x_range: tuple


def _distinct_angles(geometry):
    th = np.asarray(geometry.theta, float)
    sp_ = np.asarray(geometry.span, float)
    key = np.round(np.column_stack([np.mod(th, 2 * np.pi), sp_]), 12)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    return uniq[:, 0], uniq[:, 1], inv.ravel()


def _distinct_rows(geometry):
    key = np.round(np.column_stack([geometry.x, geometry.row_width]), 12)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    return uniq[:, 0], uniq[:, 1], inv.ravel()


def _single_radius(geometry):
    R = np.asarray(geometry.radius, float)
    if R.size == 0 or np.ptp(R) > 1e-12 * np.max(np.abs(R)):
        raise ValueError("the coupled tissue model needs one cuff radius for all rows; "
                         f"got radii {sorted(set(R.tolist()))} m")
    return float(R[0])


def _radial_nodes(R, t, n_r, ratio=1.0):
    if ratio == 1.0:
        return np.linspace(R - t, R, n_r + 1)
    # finer at the skin
    sizes = ratio ** np.arange(n_r)[::-1]
    sizes = sizes / sizes.sum() * t
    return np.concatenate([[R - t], R - t + np.cumsum(sizes)])


def _build_mesh(geometry, thickness, level, length_factor):
    sk = _skfem()
    R = _single_radius(geometry)
    _check_material(thickness=thickness, radius=R)
    level = int(level)
    if level < 1:
        raise ValueError(f"level: expected an integer >= 1, got {level}")
    t = float(thickness)
    th_c, th_s, th_inv = _distinct_angles(geometry)
    xr, wr, x_inv = _distinct_rows(geometry)
    ang = _angular_breakpoints(th_c, th_s, level)
    ext = float(length_factor) * t
    ax = _axial_breakpoints(xr, wr, level, ext)
    h_surf = min(float(np.min(wr)), R * float(np.min(th_s))) / level
    n_r = max(2, level) * max(1, math.ceil(t / (_RADIAL_SIZE * level * h_surf) - 1e-9))
    rad = _radial_nodes(R, t, n_r, _RADIAL_GROWTH)
    m1 = sk["MeshHex"].init_tensor(ax.nodes, ang.nodes, rad)
    m2c = sk["MeshHex2"].from_mesh(m1)
    comp = m2c.doflocs
    xx, th, rr = comp
    cart = np.vstack([xx, rr * np.cos(th), rr * np.sin(th)])
    mesh = sk["MeshHex2"](cart, m2c.t)
    # skin facets: all four vertices on r = R
    fr = m1.p[2][m1.facets]
    on_skin = np.all(np.abs(fr - R) <= _RIGID_TOL * R, axis=0)
    fx = m1.p[0][m1.facets].mean(axis=0)
    ft = m1.p[1][m1.facets].mean(axis=0)
    patch_facets = []
    for e in range(geometry.n):
        a = th_inv[e]
        r_ = x_inv[e]
        sel = (on_skin & (ft > ang.lo[a]) & (ft < ang.hi[a])
               & (fx > ax.lo[r_]) & (fx < ax.hi[r_]))
        patch_facets.append(np.nonzero(sel)[0])
    cuff = np.unique(np.concatenate(patch_facets))
    return _TissueMesh(mesh=mesh, comp=comp, radius=R, thickness=t, patch_facets=patch_facets,
                       cuff_facets=cuff, x_range=(float(ax.nodes[0]), float(ax.nodes[-1])))


# ----------------------------------------------------------------- assembly + solve

def _periodic_map(comp, thickness_tol):
    """Global-dof renumbering that ties the seam theta_hi onto theta_lo.

    Returns
    -------
    g : ndarray, shape (3 * nnodes,)
        Reduced index of every vector dof (node k, component c -> 3 k + c).
    n_red : int
    """
    x, th, r = comp
    th_lo, th_hi = th.min(), th.max()
    tol = 1e-9 * max(1.0, abs(th_hi))
    lo = np.nonzero(np.abs(th - th_lo) <= tol)[0]
    hi = np.nonzero(np.abs(th - th_hi) <= tol)[0]
    key = lambda ix: np.lexsort((np.round(r[ix] / thickness_tol, 6),  # noqa: E731
                                 np.round(x[ix] / thickness_tol, 6)))
    lo, hi = lo[key(lo)], hi[key(hi)]
    if len(lo) != len(hi) or not (np.allclose(x[lo], x[hi], atol=1e-9 * thickness_tol * 1e3)
                                  and np.allclose(r[lo], r[hi])):
        raise RuntimeError("seam nodes of the tissue mesh do not match")  # pragma: no cover
    nn = comp.shape[1]
    node_map = np.arange(nn)
    node_map[hi] = lo
    keep = np.ones(nn, bool)
    keep[hi] = False
    new = np.cumsum(keep) - 1
    node_red = new[node_map]
    g = (3 * node_red[:, None] + np.arange(3)[None, :]).ravel()
    return g, int(keep.sum())


def _reduce_matrix(A, g, n_red):
    A = A.tocoo()
    return sp.csr_matrix((A.data, (g[A.row], g[A.col])), shape=(3 * n_red, 3 * n_red))


def _reduce_rows(B, g, n_red):
    """P^T B for a dense (N, k) or sparse B: sum the rows of tied dofs."""
    P = sp.csr_matrix((np.ones(len(g)), (g, np.arange(len(g)))), shape=(3 * n_red, len(g)))
    return P @ B


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
