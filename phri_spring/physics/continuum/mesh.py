"""Mesh of the tissue layer for the built-in FE model (docs/model.md section 10).

The structured, graded mesh of triquadratic hexahedra between the bone (r = R - t)
and the skin (r = R) in cylindrical coordinates, the skin facets under each cuff
patch's rigid plate (its cell, less the strips of free skin a patch gap opens between
neighbours: :func:`patch_plates`), and the renumbering that ties the angular seam into a
closed tube, with the checks of the FE's inputs. :mod:`phri_spring.physics.continuum.assembly`
assembles on this mesh; see ``docs/coupled-fe.md``, "The mesh" and "Patch gaps".

scikit-fem is an optional dependency (extra ``fe``), imported only inside the
functions that need it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ...errors import ModelInputError, UsageError
from .shape import layer_shape, reference_radius

FE_EXTRA_HINT = "the coupled model's built-in FE needs scikit-fem: pip install -e .[fe]"

#: Mesh level shipped by default: level L puts L x L quadratic elements on each patch.
DEFAULT_LEVEL = 3
#: Tissue modelled beyond each axial edge of the cuff, in tissue thicknesses.
DEFAULT_LENGTH_FACTOR = 6.0
#: Free skin left between neighbouring patches when ``tissue.continuum.patch_gap`` is not
#: given [m]: the smallest gap for which the presets' patch forces converge with the mesh
#: (docs/coupled-fe.md, "Patch gaps"; benchmarks/FE_CONVERGENCE.md section 7).
DEFAULT_PATCH_GAP = 0.002

_RIGID_TOL = 1e-9
# mesh grading (see docs/coupled-fe.md, "The mesh"): element sizes in units of the
# patch element size h = patch width / level
_FREE_SIZE = 1.5       # free skin between/around the patches, along the circumference
_RADIAL_SIZE = 1.5     # a layer thicker than 1.5 patch widths gets more radial elements
_AXIAL_GROWTH = 1.6    # growth ratio of the elements beyond the cuff's axial edges
_FREE_GROWTH = 1.6     # growth ratio of the elements over free skin between patches
_EDGE_GRADING = 2.0    # size ratio of neighbouring elements in a patch, toward a free edge
_RADIAL_GROWTH = 1.5   # size ratio of radial elements, from the skin inward


def import_skfem():
    """Import scikit-fem lazily; a one-line :class:`UsageError` when the extra is missing."""
    try:
        from skfem import (Basis, BilinearForm, ElementHex2, ElementQuad2, ElementVector,
                           FacetBasis, LinearForm, MeshHex, MeshHex2, MeshQuad, asm)
        from skfem.models.elasticity import lame_parameters, linear_elasticity
    except ImportError:  # pragma: no cover - exercised by monkeypatching in the tests
        raise UsageError(FE_EXTRA_HINT) from None
    return dict(Basis=Basis, BilinearForm=BilinearForm, ElementHex2=ElementHex2,
                ElementQuad2=ElementQuad2, ElementVector=ElementVector, FacetBasis=FacetBasis,
                LinearForm=LinearForm, MeshHex=MeshHex, MeshHex2=MeshHex2, MeshQuad=MeshQuad,
                asm=asm, lame_parameters=lame_parameters, linear_elasticity=linear_elasticity)


#: Largest Poisson ratio the built-in FE accepts. Displacement-based quadratic hexahedra
#: stiffen spuriously (volumetric locking) as nu -> 0.5, so the stiffness converges ever
#: more slowly with the mesh level. Up to 0.45 the shipped mesh is within the accuracy
#: documented in benchmarks/FE_CONVERGENCE.md; above it, it is not.
MAX_POISSON_RATIO = 0.45


def check_material(thickness=None, poisson_ratio=None, young_modulus=None, radius=None):
    """Refuse FE inputs out of range (each check only for an argument given).

    Parameters
    ----------
    thickness : float, optional
        Tissue thickness t [m]: finite, > 0 and, with ``radius``, < radius.
    poisson_ratio : float, optional
        nu [-]: in (-1, 0.5) and at most :data:`MAX_POISSON_RATIO`.
    young_modulus : float, optional
        E [Pa]: finite, > 0.
    radius : float, optional
        Cuff radius R [m].

    Raises
    ------
    ValueError
        One line naming the parameter and the range expected.
    """
    if young_modulus is not None:
        E = float(young_modulus)
        if not (math.isfinite(E) and E > 0):
            raise ValueError("young_modulus: expected a finite value > 0 Pa, "
                             f"got {young_modulus!r}")
    if poisson_ratio is not None:
        nu = float(poisson_ratio)
        if not (math.isfinite(nu) and -1.0 < nu < 0.5):
            raise ValueError(f"poisson_ratio: expected a value in (-1, 0.5), got {poisson_ratio!r}")
        if nu > MAX_POISSON_RATIO:
            raise ValueError(f"poisson_ratio: the built-in FE is converged up to "
                             f"{MAX_POISSON_RATIO} (its quadratic elements lock as nu -> 0.5), "
                             f"got {poisson_ratio!r}")
    if thickness is not None:
        t = float(thickness)
        if not (math.isfinite(t) and t > 0):
            raise ValueError(f"thickness: expected a finite value > 0 m, got {thickness!r}")
        if radius is not None and not t < radius:
            raise ValueError(f"thickness: expected less than the cuff radius {radius} m, "
                             f"got {thickness!r}")


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


def _line_nodes(lo, hi, level, h_max, start, end, start_free, end_free, start_h=None):
    """Element boundaries over [start, end] for sorted, non-overlapping patch intervals.

    ``start_free`` / ``end_free``: the first / last patch's outer edge borders free skin
    even where it coincides with ``start`` / ``end``. ``start_h``: the element size just
    before ``start`` (default ``h_max``). Returns the nodes and the sizes of the elements
    at the first patch's low edge and the last patch's high edge.
    """
    m = len(lo)
    nodes = [start]
    cur, cur_h = start, (h_max if start_h is None else start_h)
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


def _open_gaps(lo, hi, gap, period=None):
    """The plates in sorted, non-overlapping cells [lo, hi]: strips of free skin opened.

    Where two neighbouring cells are closer than ``gap`` (tiled cells: 0 apart), each
    gives up half of the difference, so that ``gap`` of free skin separates their
    plates; a cell edge with no neighbour closer than ``gap`` (the cuff's outer edges)
    stays. ``period``: the coordinate is periodic (the last cell neighbours the first).
    """
    lo, hi = np.array(lo, float), np.array(hi, float)
    m = len(lo)
    pairs = [(k, k + 1, 0.0) for k in range(m - 1)]
    if period is not None and m > 1:
        pairs.append((m - 1, 0, period))
    for a, b, wrap in pairs:
        cut = max(0.0, gap - (lo[b] + wrap - hi[a])) / 2
        hi[a] -= cut
        lo[b] += cut
    return lo, hi


def _angular_breakpoints(theta, span, level, gap=0.0):
    """Element boundaries in theta over one full turn [theta_seam, theta_seam + 2 pi].

    Parameters
    ----------
    theta, span : ndarray, shape (m,)
        Centre and width of the m distinct angular locations [rad].
    gap : float
        Free skin opened between neighbouring patches [rad] (:func:`_open_gaps`).
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
    h_max = _FREE_SIZE * float(np.min(s)) / level
    lo, hi = _open_gaps(lo, hi, float(gap), two_pi)      # the plates in the cells
    s = hi - lo
    gaps = np.array([lo[(k + 1) % m] + (two_pi if k == m - 1 else 0.0) - hi[k]
                     for k in range(m)])
    gaps[np.abs(gaps) < 1e-9] = 0.0
    # seam: the patch edge where the widest stretch of free skin starts; the walk round the
    # circle ends there, so that stretch is meshed as any other (from the last patch's edge
    # element), and patches with equal gaps closing the circle get a cyclic mesh
    kg = int(np.argmax(gaps))
    seam = hi[kg]
    # patches in walking order from the seam, unwrapped to [seam, seam + 2 pi]
    idx = [(kg + 1 + i) % m for i in range(m)]
    a = np.array([lo[k] for k in idx])
    a = seam + np.mod(a - seam + 1e-9, two_pi) - 1e-9
    b = a + s[idx]
    free = bool(gaps[kg] > 0)
    _, _, h_end = _line_nodes(a, b, level, h_max, seam, seam + two_pi, False, free)
    nodes, _, _ = _line_nodes(a, b, level, h_max, seam, seam + two_pi, False, free, h_end)
    nodes[-1] = seam + two_pi
    lo_out = np.empty(m)
    hi_out = np.empty(m)
    lo_out[order[idx]], hi_out[order[idx]] = a, b
    return _Intervals(nodes, lo_out, hi_out)


def graded(length, h0, ratio):
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


def _axial_breakpoints(x, width, level, extension, ratio=_AXIAL_GROWTH, gap=0.0):
    """Element boundaries along the arm; ``gap`` [m]: free skin opened between rows."""
    order = np.argsort(x)
    lo, hi = x[order] - width[order] / 2, x[order] + width[order] / 2
    for k in range(len(lo) - 1):
        if hi[k] > lo[k + 1] + 1e-9:
            raise ValueError("cuff rows overlap along the arm; expected rows that tile or "
                             "leave gaps (row distance >= row width)")
    h_max = _FREE_SIZE * float(np.min(width)) / level
    lo, hi = _open_gaps(lo, hi, float(gap))               # the plates in the rows
    inner, h_first, h_last = _line_nodes(lo, hi, level, h_max, lo[0], hi[-1], True, True)
    ext_lo = graded(extension, h_first, ratio)
    ext_hi = graded(extension, h_last, ratio)
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
    patch_gap: float = 0.0    # free skin between neighbouring patches' plates [m]
    shape: object = None      # LayerShape the nodes are mapped onto (shape.py); None: a circle


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


def single_radius(geometry) -> float:
    """The one cuff radius R [m] of all rows of a geometry (the FE models a cylinder).

    Raises
    ------
    ValueError
        Rows of different radii.
    """
    R = np.asarray(geometry.radius, float)
    if R.size == 0 or np.ptp(R) > 1e-12 * np.max(np.abs(R)):
        raise ValueError("the coupled tissue model needs one cuff radius for all rows; "
                         f"got radii {sorted(set(R.tolist()))} m")
    return float(R[0])


def _plates_1d(c, w, gap, period=None):
    """Plate bounds (lo, hi) of cells of centre c and width w (any order) for a gap."""
    key = np.mod(c, period) if period is not None else c
    order = np.argsort(key)
    lo, hi = _open_gaps(key[order] - w[order] / 2, key[order] + w[order] / 2, gap, period)
    lo_out, hi_out = np.empty(len(c)), np.empty(len(c))
    lo_out[order], hi_out[order] = lo, hi
    return lo_out, hi_out


def _no_plate(c, w, gap, period):
    """Index of the first cell a gap leaves without a plate, and the largest gap that leaves
    every cell a plate (bisection: the plates shrink monotonically with the gap); (None,
    None) for overlapping cells, which the mesh refuses with its own message."""
    lo, hi = _plates_1d(c, w, 0.0, period)
    key = np.mod(c, period) if period is not None else c
    o = np.argsort(key)
    wrap = lo[o][0] + period if period is not None and len(c) > 1 else np.inf
    nxt = np.append(lo[o][1:], wrap)
    if np.any(hi[o] > nxt + 1e-9):
        return None, None

    def left(g):
        lo, hi = _plates_1d(c, w, g, period)
        return (hi - lo) / w
    short = np.nonzero(left(gap) <= 1e-6)[0]
    if not len(short):
        return None, None
    a, b = 0.0, gap
    for _ in range(60):
        mid = 0.5 * (a + b)
        a, b = (mid, b) if np.all(left(mid) > 1e-6) else (a, mid)
    return int(short[0]), a


def patch_gap_problem(geometry, patch_gap):
    """Why a gap cannot be opened between the patches of a geometry (one line), or None.

    Parameters
    ----------
    geometry : CuffGeometry
    patch_gap : float
        Free skin between neighbouring patches [m] (around the arm: the arc on r = R).
    """
    g = float(patch_gap)
    if not (math.isfinite(g) and g >= 0):
        return f"expected a finite width >= 0 m, got {patch_gap!r}"
    R = reference_radius(geometry)
    th_c, th_s, _ = _distinct_angles(geometry)
    xr, wr, _ = _distinct_rows(geometry)
    for c, w, scale, period, what in ((xr, wr, 1.0, None, "along the arm"),
                                      (th_c, th_s, R, 2 * np.pi, "around the arm")):
        k, g_max = _no_plate(c, w, g / scale, period)
        if k is not None:
            where = (f"the row at x = {c[k] * 1e3:g} mm" if period is None
                     else f"the patches at {np.degrees(c[k]):g} deg")
            return (f"a gap of {g * 1e3:g} mm leaves no plate of {where} "
                    f"({w[k] * scale * 1e3:.4g} mm wide {what}); expected a gap below "
                    f"{g_max * scale * 1e3:.4g} mm (0: tiled patches)")
    return None


def patch_plates(geometry, patch_gap):
    """Where each patch's rigid plate lies in its cell once ``patch_gap`` is opened.

    Neighbouring cells closer than the gap (tiled cells: touching) each give up half of
    the difference; edges with no neighbour that close (the cuff's outer edges) stay.

    Returns
    -------
    x_lo, x_hi, theta_lo, theta_hi : ndarray, shape (n,)
        Per patch, in label order: the plate's extent along the arm [m] and around it
        [rad] (theta_lo may be negative or theta_hi above 2 pi: the cell's own branch).

    Raises
    ------
    ModelInputError
        ``quantity='patch_gap'``: a gap that leaves a patch no plate (or is negative).
    """
    problem = patch_gap_problem(geometry, patch_gap)
    if problem is not None:
        raise ModelInputError(f"patch_gap: {problem}", "patch_gap")
    R = reference_radius(geometry)
    g = float(patch_gap)
    th_c, th_s, th_inv = _distinct_angles(geometry)
    xr, wr, x_inv = _distinct_rows(geometry)
    xl, xh = _plates_1d(xr, wr, g)
    tl, th = _plates_1d(th_c, th_s, g / R, 2 * np.pi)
    shift = np.asarray(geometry.theta, float) - th_c[th_inv]     # back to each cell's branch
    return xl[x_inv], xh[x_inv], tl[th_inv] + shift, th[th_inv] + shift


def _radial_nodes(R, t, n_r, ratio=1.0):
    if ratio == 1.0:
        return np.linspace(R - t, R, n_r + 1)
    # finer at the skin
    sizes = ratio ** np.arange(n_r)[::-1]
    sizes = sizes / sizes.sum() * t
    return np.concatenate([[R - t], R - t + np.cumsum(sizes)])


def mesh_lines(geometry, thickness, level, length_factor, patch_gap):
    """The breakpoints of the mesh along the arm, around it and through the thickness
    (in the parametric coordinates (x, theta, r) of a cylinder of the reference radius,
    :func:`~phri_spring.physics.continuum.shape.reference_radius`)."""
    R = reference_radius(geometry)
    check_material(thickness=thickness, radius=R)
    level = int(level)
    if level < 1:
        raise ValueError(f"level: expected an integer >= 1, got {level}")
    t = float(thickness)
    th_c, th_s, _ = _distinct_angles(geometry)
    xr, wr, _ = _distinct_rows(geometry)
    ext = float(length_factor) * t
    _angular_breakpoints(th_c, th_s, level)              # overlapping cells refused first
    _axial_breakpoints(xr, wr, level, ext)
    patch_plates(geometry, patch_gap)                    # then a gap that leaves no plate
    gap = float(patch_gap)
    ang = _angular_breakpoints(th_c, th_s, level, gap / R)
    ax = _axial_breakpoints(xr, wr, level, ext, gap=gap)
    h_surf = min(float(np.min(wr)), R * float(np.min(th_s))) / level
    n_r = max(2, level) * max(1, math.ceil(t / (_RADIAL_SIZE * level * h_surf) - 1e-9))
    return ax, ang, _radial_nodes(R, t, n_r, _RADIAL_GROWTH)


def mesh_size(geometry, thickness, level=DEFAULT_LEVEL, length_factor=DEFAULT_LENGTH_FACTOR,
              patch_gap=DEFAULT_PATCH_GAP) -> tuple:
    """(hexahedra, dofs) of the mesh :func:`build_mesh` makes, without building it.

    Triquadratic hexahedra on the tensor grid of the breakpoints; dofs: 3 per node once the
    angular seam is tied. ``patch_gap`` None: :data:`DEFAULT_PATCH_GAP`.
    """
    gap = DEFAULT_PATCH_GAP if patch_gap is None else patch_gap
    ax, ang, rad = mesh_lines(geometry, thickness, level, length_factor, gap)
    a, b, c = len(ax.nodes) - 1, len(ang.nodes) - 1, len(rad) - 1
    return a * b * c, 3 * (2 * a + 1) * (2 * b) * (2 * c + 1)


def build_mesh(geometry, thickness, level, length_factor, patch_gap=DEFAULT_PATCH_GAP,
               bone=None):
    """The tissue mesh under a cuff; ``bone`` (y_c, z_c, r_b) [m]: a circular bone, None:
    the skin moved inward by the thickness (on a limb of any shape: shape.py)."""
    sk = import_skfem()
    patch_gap = DEFAULT_PATCH_GAP if patch_gap is None else patch_gap
    R = reference_radius(geometry)
    shape = layer_shape(geometry, thickness, bone)
    ax, ang, rad = mesh_lines(geometry, thickness, level, length_factor, patch_gap)
    if shape is not None:
        shape.check(ang.nodes, ax.nodes)
    _, _, th_inv = _distinct_angles(geometry)
    _, _, x_inv = _distinct_rows(geometry)
    t, gap = float(thickness), float(patch_gap)
    m1 = sk["MeshHex"].init_tensor(ax.nodes, ang.nodes, rad)
    m2c = sk["MeshHex2"].from_mesh(m1)
    comp = m2c.doflocs
    xx, th, rr = comp
    if shape is None:
        cart = np.vstack([xx, rr * np.cos(th), rr * np.sin(th)])
    else:
        cart = shape.map_nodes(xx, th, rr, R, float(thickness))
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
                       cuff_facets=cuff, x_range=(float(ax.nodes[0]), float(ax.nodes[-1])),
                       patch_gap=gap, shape=shape)


# ------------------------------------------------------------ periodic seam

def periodic_map(comp, thickness_tol):
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


def reduce_matrix(A, g, n_red):
    A = A.tocoo()
    return sp.csr_matrix((A.data, (g[A.row], g[A.col])), shape=(3 * n_red, 3 * n_red))


def reduce_rows(B, g, n_red):
    """P^T B for a dense (N, k) or sparse B: sum the rows of tied dofs."""
    P = sp.csr_matrix((np.ones(len(g)), (g, np.arange(len(g)))), shape=(3 * n_red, len(g)))
    return P @ B
