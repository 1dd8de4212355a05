"""Cuff elements on a triangulated limb surface (a 3D scan), in the cuff frame (docs/scans.md).

Pure numpy/scipy on arrays: the mesh comes in as ``vertices`` (V, 3) [m], already in the cuff
frame (x along the arm axis, theta from +y toward +z), and ``faces`` (F, 3) vertex indices;
reading the file and placing it in the frame is :mod:`phri_spring.io.scan`'s job.

For row r at x_r and angular location j at theta_j with angular span width_j:

- **outline**: the mesh's cross-section by the plane x = x_r, as closed polylines; the one used
  is the loop that winds once around the axis (the largest such loop if there are several,
  e.g. a scan with an inner surface), oriented by increasing theta. Each loop point lies on a
  mesh edge; vertices exactly on the plane count as lying on its +x side (a consistent
  symbolic perturbation: every crossing triangle then has exactly two crossing edges, so the
  loops close whatever the rounding; a vertex within 1e-6 of the scan's size of the plane
  counts as on it, so that rounding cannot make the section zigzag about a ring of vertices).
- **point** p_e: where the ray from the axis at theta_j leaves the outline (the farthest
  crossing, should the outline not be star-shaped there).
- **normal** n_e: the inward unit normal of the scan around p_e: the area-weighted mean of
  the triangles' unit normals, each weighted (1 - d^2 / r^2)^2 by the distance d of its
  centroid from p_e, for r = h and r = 2h (``smoothing``), combined as (4 n_h - n_2h) / 3 to
  cancel the mean's r^2 error on a curved surface. The two purely local choices, the face
  normal of the triangle hit or vertex normals interpolated across it, carry a scan's
  facet-scale noise straight into n_e (0.03 rad for 20 micrometres of noise on 0.8 mm facets,
  against 0.004 here) and the first also jumps by a facet angle from one triangle to the next;
  the weighted mean is continuous in p_e, exact on a cylinder to second order in the facet
  angle, and carries the limb's local taper (its x component). Triangle normals are oriented
  away from the axis one by one, so inconsistently wound triangles give the same normals.
- **area** A_e: the exact area of the mesh inside the element's band ``|x - x_r| <= w_r / 2``,
  ``|theta - theta_j| <= width_j / 2`` (every triangle clipped by the four planes; only the
  surface connected to the row's outline counts).
- **turning** psi_e: the angle through which the outline's tangent turns between the rays at
  theta_j -+ width_j / 2, as the difference of the tangent angle at the two crossings. On a
  polyline the tangent angle is a staircase (it turns only at the vertices), so summing the
  exterior angles between two rays would make psi jump by a facet angle as a ray passes a
  vertex. Instead each segment's direction is taken at its midpoint with the angle linear in
  arc between midpoints (exact on a regular polygon), averaged over +-h around the crossing
  against a scan's noise (``smoothing`` h, see :func:`scan_element_geometry`), with the
  averaging's h^2 error cancelled by combining the averages over h and 2h. Neighbouring
  elements share their ray, so the turnings of a closed ring sum to exactly 2 pi, as the
  hoop preload needs.
- **arc** s_e: the outline's length between the same two rays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ...errors import ModelInputError

__all__ = ["ScanElements", "ScanMesh", "SectionLoop", "prepare_scan_mesh", "section_loops",
           "axis_loop", "scan_element_geometry", "clipped_area", "DEFAULT_SMOOTHING", "ray_hits",
           "tangent_angle"]

#: the least smoothing length h [m]: the half-length of the arc the outline's tangent angle
#: is averaged over, and the radius the surface normal is averaged over (then 2h for both):
#: larger than a scan's noise and facets, small against an element
DEFAULT_SMOOTHING = 0.004


#: distance from a section's plane, as a fraction of the scan's size, within which a vertex
#: counts as on the plane (well above float32 rounding, far below any scanner's resolution)
_ON_PLANE = 1e-6
#: [rad] consecutive outline segments turning less than this are one straight piece (a planar
#: facet cut on its diagonal, with float32 coordinates, turns by about 1e-7 rad; a limb's
#: facets turn by 1e-2 rad)
_COLLINEAR = 1e-5


@dataclass(frozen=True, eq=False)
class ScanElements:
    """Per-element geometry on a scan, row-major (n = rows x angles), SI units.

    Attributes
    ----------
    points : ndarray, shape (n, 3)
        Surface points p_e [m] in the cuff frame.
    normals : ndarray, shape (n, 3)
        Inward unit normals n_e of the scan surface at p_e.
    areas : ndarray, shape (n,)
        Scan surface area inside each element's band [m^2].
    turning : ndarray, shape (n,)
        Turning psi_e of the outline's tangent between the element's edge rays [rad].
    arcs : ndarray, shape (n,)
        Outline arc length between the element's edge rays [m].
    outlines : tuple of ndarray, each (k, 2)
        Per row, the outline's (y, z) points [m], by increasing theta, not repeating the first.
    smoothing : ndarray, shape (rows,)
        The smoothing length h [m] used for the turning and the normals, per row.
    """

    points: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    turning: np.ndarray
    arcs: np.ndarray
    outlines: tuple
    smoothing: np.ndarray


@dataclass(frozen=True, eq=False)
class ScanMesh:
    """A mesh with what every section needs computed once (:func:`prepare_scan_mesh`)."""

    vertices: np.ndarray        # (V, 3) [m]
    faces: np.ndarray           # (F, 3) int, no repeated index within a face
    edges: np.ndarray           # (E, 2) unique undirected edges, a < b
    face_edges: np.ndarray      # (F, 3) edge ids: (f0, f1), (f1, f2), (f2, f0)
    face_vectors: np.ndarray    # (F, 3) outward (away from the axis) normal times twice the area
    centroids: np.ndarray       # (F, 3)
    face_component: np.ndarray  # (F,) connected-component label of each face
    edge_length: float          # median edge length [m]


@dataclass(frozen=True, eq=False)
class SectionLoop:
    """One closed loop of a plane section: ``yz`` (k, 2) by increasing theta, and per point the
    mesh edge it lies on (``edge``), the fraction along it (``t``), and per segment k -> k+1 the
    face it crosses (``face``)."""

    yz: np.ndarray
    edge: np.ndarray
    t: np.ndarray
    face: np.ndarray

    @property
    def winding(self) -> int:
        """How many times the loop winds around the axis (the origin of the y-z plane)."""
        ang = np.arctan2(self.yz[:, 1], self.yz[:, 0])
        turn = np.diff(np.append(ang, ang[0]))
        turn = (turn + np.pi) % (2 * np.pi) - np.pi
        return int(np.rint(turn.sum() / (2 * np.pi)))

    @property
    def area(self) -> float:
        """Signed area enclosed (positive: counter-clockwise, increasing theta) [m^2]."""
        y, z = self.yz[:, 0], self.yz[:, 1]
        return 0.5 * float(np.sum(y * np.roll(z, -1) - np.roll(y, -1) * z))


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def prepare_scan_mesh(vertices, faces) -> ScanMesh:
    """Check a mesh and compute its edges, outward face normals and connected components.

    Raises :class:`ModelInputError` (quantity ``scan``) for arrays of the wrong shape,
    non-finite coordinates, indices out of range or a mesh with no triangle of non-zero area.
    """
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise ModelInputError(f"expected vertices (V, 3) and faces (F, 3), got {v.shape} and "
                              f"{f.shape}", "scan")
    if not np.all(np.isfinite(v)):
        raise ModelInputError("vertex coordinates must be finite numbers", "scan")
    if f.size and (not np.issubdtype(f.dtype, np.integer) or f.min() < 0 or f.max() >= len(v)):
        raise ModelInputError(f"face indices must be integers in 0..{len(v) - 1}", "scan")
    f = f.astype(np.int64)
    # a face with a repeated vertex has no area and would join an edge to itself
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    solid = np.einsum("ij,ij->i", cross, cross) > 0
    f, cross = f[solid], cross[solid]
    if len(f) == 0:
        raise ModelInputError("the mesh has no triangle of non-zero area", "scan")
    # outward = away from the axis: orient every triangle by the radial direction at its centroid
    centroid = v[f].mean(axis=1)
    flip = cross[:, 1] * centroid[:, 1] + cross[:, 2] * centroid[:, 2] < 0
    cross = np.where(flip[:, None], -cross, cross)
    # unique undirected edges, and each face's three edge ids
    pairs = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    keys, inverse = np.unique(pairs[:, 0] * len(v) + pairs[:, 1], return_inverse=True)
    edges = np.column_stack([keys // len(v), keys % len(v)])
    face_edges = inverse.reshape(-1, 3)
    # faces joined through shared edges: a bipartite face-edge graph
    nf, ne = len(f), len(edges)
    rows = np.repeat(np.arange(nf), 3)
    graph = coo_matrix((np.ones(3 * nf), (rows, nf + face_edges.ravel())), shape=(nf + ne,) * 2)
    _, labels = connected_components(graph, directed=False)
    edge_length = float(np.median(np.linalg.norm(v[edges[:, 1]] - v[edges[:, 0]], axis=1)))
    return ScanMesh(v, f, edges, face_edges, cross, centroid, labels[:nf], edge_length)


def _spaced(yz: np.ndarray, fraction: float) -> np.ndarray:
    """Which points of a closed polyline to keep so that none lies within ``fraction`` of the
    median segment of the last one kept (or of the first point).

    A mesh vertex on the plane ends several crossing edges, all giving the same point: one is
    kept (a segment of no length has no direction)."""
    gap = np.linalg.norm(np.roll(yz, -1, axis=0) - yz, axis=1)
    tol = fraction * float(np.median(gap[gap > 0])) if np.any(gap > 0) else 0.0
    keep = np.zeros(len(yz), bool)
    last = yz[0]
    keep[0] = True
    for i in range(1, len(yz)):
        if np.hypot(*(yz[i] - last)) >= tol and np.hypot(*(yz[i] - yz[0])) >= tol:
            keep[i], last = True, yz[i]
    return keep


def section_loops(mesh: ScanMesh, x: float):
    """The plane section x = ``x`` of the mesh: (closed loops, number of open chains).

    Each closed loop is a :class:`SectionLoop`; open chains (the plane crosses a hole or a
    boundary of the mesh, or a non-manifold edge) are only counted.
    """
    # a vertex within rounding of the plane counts as on it, as one exactly on it does: a
    # ring of vertices scattered +-1e-8 about the plane (float32 STL, a turned frame) would
    # otherwise zigzag across it, cutting the ring's edges into pieces of any length
    tol = _ON_PLANE * float(np.ptp(mesh.vertices, axis=0).max())
    above = mesh.vertices[:, 0] >= x - tol
    crossing_edge = above[mesh.edges[:, 0]] != above[mesh.edges[:, 1]]
    fe_cross = crossing_edge[mesh.face_edges]
    faces = np.flatnonzero(fe_cross.any(axis=1))
    if len(faces) == 0:
        return [], 0
    # each crossing triangle has exactly two crossing edges: one segment between them
    pair = mesh.face_edges[faces][fe_cross[faces]].reshape(-1, 2)
    nodes, local = np.unique(pair, return_inverse=True)
    local = local.reshape(-1, 2)
    m = len(nodes)
    degree = np.bincount(local.ravel(), minlength=m)
    graph = coo_matrix((np.ones(len(local)), (local[:, 0], local[:, 1])), shape=(m, m))
    n_comp, comp = connected_components(graph, directed=False)
    comp_ok = np.ones(n_comp, bool)
    comp_ok[comp[degree != 2]] = False
    # neighbours of every degree-2 node: (node, neighbour, face) both ways, grouped by node
    src = np.concatenate([local[:, 0], local[:, 1]])
    dst = np.concatenate([local[:, 1], local[:, 0]])
    via = np.concatenate([faces, faces])
    order = np.argsort(src, kind="stable")
    start = np.concatenate([[0], np.cumsum(degree)])
    nbr, nbr_face = dst[order], via[order]
    v = mesh.vertices
    loops = []
    for c in np.flatnonzero(comp_ok):
        first = int(np.flatnonzero(comp == c)[0])
        seq, seq_face = [first], []
        prev, cur = -1, first
        while True:
            i = start[cur]
            k = i if nbr[i] != prev else i + 1
            seq_face.append(int(nbr_face[k]))
            prev, cur = cur, int(nbr[k])
            if cur == first:
                break
            seq.append(cur)
        if len(seq) < 3:
            continue
        e, seq_face = nodes[np.asarray(seq)], np.asarray(seq_face)
        a, b = mesh.edges[e, 0], mesh.edges[e, 1]
        t = np.clip((x - v[a, 0]) / (v[b, 0] - v[a, 0]), 0.0, 1.0)
        t = np.where(np.abs(v[b, 0] - x) <= tol, 1.0, np.where(np.abs(v[a, 0] - x) <= tol, 0.0, t))
        yz = (v[a] + t[:, None] * (v[b] - v[a]))[:, 1:]
        keep = _spaced(yz, 1e-6)
        if keep.sum() < 3:
            continue
        # the segment from a kept point runs along the last dropped one's face
        nxt_keep = np.roll(np.flatnonzero(keep), -1)
        seg_face = seq_face[(nxt_keep - 1) % len(keep)]
        yz, e, t = yz[keep], e[keep], t[keep]
        loop = SectionLoop(yz, e, t, seg_face)
        if loop.area < 0:                       # by increasing theta
            loop = SectionLoop(yz[::-1].copy(), e[::-1].copy(), t[::-1].copy(),
                               np.roll(seg_face[::-1], -1))
        loops.append(loop)
    return loops, int(n_comp - comp_ok.sum())


def axis_loop(mesh: ScanMesh, x: float, row: str = "") -> SectionLoop:
    """The loop of the section x = ``x`` that winds once around the axis (the largest if several).

    Raises :class:`ModelInputError` (quantity ``scan``) naming the row and what was found: no
    section (the plane misses the scan), an open section (a hole or the scan's edge), or only
    loops that do not enclose the axis (the axis misses the limb).
    """
    where = f"{row + ' ' if row else ''}at x = {x:.4g} m"
    of = f"of {where}" if row else where
    loops, n_open = section_loops(mesh, x)
    around = [lp for lp in loops if abs(lp.winding) == 1]
    if around:
        return max(around, key=lambda lp: abs(lp.area))
    lo, hi = mesh.vertices[:, 0].min(), mesh.vertices[:, 0].max()
    if not loops and not n_open:
        raise ModelInputError(f"the plane {of} does not cut the scan (it spans x = "
                              f"{lo:.4g} .. {hi:.4g} m along the axis); expected the scan to "
                              "cover every row", "scan")
    if n_open:
        raise ModelInputError(f"the section {of} is not closed around the axis "
                              f"({n_open} open piece{'s' * (n_open > 1)}: a hole or an edge of "
                              "the scan there); expected a closed limb surface at every row",
                              "scan")
    raise ModelInputError(f"no loop of the section {of} encloses the axis (the axis "
                          "misses the limb there); expected origin and axis inside the limb",
                          "scan")


def _clip(poly: np.ndarray, count: np.ndarray, dist: np.ndarray):
    """Clip convex polygons (N, M, 3) with ``count`` vertices each to ``dist >= 0`` (N, M)."""
    n, m, _ = poly.shape
    idx = np.arange(m)
    valid = idx[None, :] < count[:, None]
    nxt = (idx[None, :] + 1) % np.maximum(count, 1)[:, None]
    q = np.take_along_axis(poly, nxt[:, :, None], axis=1)
    dq = np.take_along_axis(dist, nxt, axis=1)
    keep = valid & (dist >= 0)
    cut = valid & ((dist >= 0) != (dq >= 0))
    t = np.where(cut, dist / np.where(cut, dist - dq, 1.0), 0.0)
    out = np.empty((n, 2 * m, 3))
    out[:, 0::2], out[:, 1::2] = poly, poly + t[:, :, None] * (q - poly)
    mask = np.empty((n, 2 * m), bool)
    mask[:, 0::2], mask[:, 1::2] = keep, cut
    order = np.argsort(~mask, axis=1, kind="stable")[:, :m + 1]
    return np.take_along_axis(out, order[:, :, None], axis=1), mask.sum(axis=1)


def _polygon_areas(poly: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Areas of planar polygons (N, M, 3) with ``count`` vertices each."""
    fan = np.cross(poly[:, 1:-1] - poly[:, :1], poly[:, 2:] - poly[:, :1])
    used = np.arange(1, poly.shape[1] - 1)[None, :] + 1 < count[:, None]
    return 0.5 * np.linalg.norm(np.sum(fan * used[:, :, None], axis=1), axis=1)


def clipped_area(triangles: np.ndarray, planes) -> float:
    """Area of triangles (N, 3, 3) inside every half-space ``n . p >= c`` of ``planes``
    [(n (3,), c), ...] (exact: each triangle is clipped, Sutherland-Hodgman)."""
    triangles = np.asarray(triangles, float)
    if len(triangles) == 0:
        return 0.0
    # only the triangles a plane cuts need clipping: the others are wholly in or out
    dist = np.stack([triangles @ np.asarray(n, float) - c for n, c in planes])   # (P, N, 3)
    outside = np.any(np.all(dist < 0, axis=2), axis=0)
    inside = np.all(dist >= 0, axis=(0, 2))
    whole = triangles[inside]
    area = 0.5 * float(np.linalg.norm(np.cross(whole[:, 1] - whole[:, 0],
                                               whole[:, 2] - whole[:, 0]), axis=1).sum())
    poly = triangles[~inside & ~outside]
    count = np.full(len(poly), 3)
    for normal, offset in planes:
        if len(poly) == 0:
            return area
        poly, count = _clip(poly, count, poly @ np.asarray(normal, float) - offset)
        poly, count = poly[count >= 3], count[count >= 3]
    return area + (float(_polygon_areas(poly, count).sum()) if len(poly) else 0.0)


def _wedge_planes(lo: float, hi: float):
    """Half-spaces through the axis keeping lo <= theta <= hi (hi - lo < pi)."""
    return [((0.0, -np.sin(lo), np.cos(lo)), 0.0), ((0.0, np.sin(hi), -np.cos(hi)), 0.0)]


def ray_hits(yz: np.ndarray, angles: np.ndarray):
    """Farthest crossing of each ray (from the origin at ``angles``) with the closed polyline
    ``yz``: segment index (k,) and fraction along it; -1 where a ray misses."""
    p, d = yz, np.roll(yz, -1, axis=0) - yz
    u = np.column_stack([np.cos(angles), np.sin(angles)])
    ud = u[:, None, 0] * d[None, :, 1] - u[:, None, 1] * d[None, :, 0]     # u x d
    safe = np.where(ud != 0, ud, 1.0)
    s = (p[None, :, 0] * u[:, None, 1] - p[None, :, 1] * u[:, None, 0]) / safe
    t = (p[None, :, 0] * d[None, :, 1] - p[None, :, 1] * d[None, :, 0]) / safe
    tol = 1e-12
    ok = (ud != 0) & (s >= -tol) & (s <= 1 + tol) & (t > 0)
    t = np.where(ok, t, -np.inf)
    seg = np.argmax(t, axis=1)
    rows = np.arange(len(angles))
    hit = np.isfinite(t[rows, seg])
    return np.where(hit, seg, -1), np.clip(s[rows, seg], 0.0, 1.0)


def _mean_tangent_angle(yz: np.ndarray, pos: np.ndarray, h: float) -> np.ndarray:
    """The outline's tangent angle averaged over the arc [pos - h, pos + h], continuous along
    the loop (unwrapped from its first segment, + the loop's total turning per turn).

    Each segment's direction holds at its midpoint and the angle goes linearly from one
    midpoint to the next: a polyline's corner turns over the half-segments beside it, as the
    smooth curve it samples does, and on a regular polygon the angle is exactly linear in arc.
    """
    d = np.roll(yz, -1, axis=0) - yz
    length = np.linalg.norm(d, axis=1)
    keep = length > 0
    d, length = d[keep], length[keep]
    phi = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    # a plane cuts a triangulated surface on its facets' edges and on their diagonals: the
    # cut of one planar quad is two collinear pieces of unequal length, whose midpoints
    # would bend the piecewise-linear angle off a straight facet. Collinear runs are one
    # segment (a turn below _COLLINEAR is float rounding of a planar facet, not shape).
    turn = (np.roll(phi, -1) - phi + np.pi) % (2 * np.pi) - np.pi
    corner = np.abs(turn) > _COLLINEAR           # a real corner after segment k
    s0 = 0.0                                     # arc position where segment 0 starts
    if corner.any() and not corner.all():
        i0 = (int(np.flatnonzero(corner)[-1]) + 1) % len(phi)   # a segment that begins a run
        s0 = float(length[:i0].sum())
        d, length, corner = np.roll(d, -i0, axis=0), np.roll(length, -i0), np.roll(corner, -i0)
        run = np.concatenate([[0], np.cumsum(corner[:-1])])
        length = np.bincount(run, weights=length)
        d = np.column_stack([np.bincount(run, weights=d[:, 0]), np.bincount(run, weights=d[:, 1])])
        phi = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    # the whole loop's turning: the unwrapped turns plus the one at the closing vertex
    total = (phi[-1] - phi[0]) + ((phi[0] - phi[-1] + np.pi) % (2 * np.pi) - np.pi)
    perimeter = length.sum()
    # the angle at the segments' midpoints over five turns of the loop (-2 .. 3 perimeters),
    # so that pos +- 2h stays inside the table
    mid = s0 + np.concatenate([[0.0], np.cumsum(length)[:-1]]) + length / 2
    node_s = np.concatenate([mid + i * perimeter for i in range(-2, 3)])
    node_phi = np.concatenate([phi + i * total for i in range(-2, 3)])
    # its integral, exact for the piecewise-linear angle: trapezoids, then within a piece
    seg = np.diff(node_s)
    slope = np.diff(node_phi) / seg
    cum = np.concatenate([[0.0], np.cumsum(seg * (node_phi[:-1] + node_phi[1:]) / 2)])

    def integral(s):
        k = np.clip(np.searchsorted(node_s, s, side="right") - 1, 0, len(seg) - 1)
        ds = s - node_s[k]
        return cum[k] + ds * node_phi[k] + 0.5 * slope[k] * ds ** 2

    return (integral(pos + h) - integral(pos - h)) / (2 * h)


def _patch_normals(mesh: ScanMesh, comp: int, points: np.ndarray, h: float,
                   hit_faces: np.ndarray) -> np.ndarray:
    """Inward unit normals at ``points``: the area-weighted mean of the outward face normals
    around each point, weighted (1 - d^2 / r^2)^2 by the distance d of the face's centroid,
    for r = h and 2h; (4 n_h - n_2h) / 3 cancels the mean's r^2 error. Where no face lies
    within h, the face the ray hit (``hit_faces``) gives the normal."""
    near = (mesh.face_component == comp) & (np.abs(mesh.centroids[:, 0] - points[:, 0].mean())
                                            <= 2 * h + np.ptp(points[:, 0]))
    cen, vec = mesh.centroids[near], mesh.face_vectors[near]
    out = np.empty_like(points)
    for i, p in enumerate(points):
        d2 = np.einsum("ij,ij->i", cen - p, cen - p)
        means = []
        for radius in (h, 2 * h):
            weight = np.clip(1.0 - d2 / radius ** 2, 0.0, None) ** 2
            means.append(_unit(weight @ vec) if weight.any() else None)
        if means[0] is None:
            out[i] = -_unit(mesh.face_vectors[hit_faces[i]])
        else:
            out[i] = -_unit(4 * means[0] - means[1])
    return out


def tangent_angle(yz: np.ndarray, pos: np.ndarray, h: float) -> np.ndarray:
    """The outline's tangent angle at arc positions ``pos``, smoothed over +-h.

    A window average misses the true angle by h^2/6 times the rate of change of curvature (an
    ellipse's changes all along): (4 avg_h - avg_2h) / 3 cancels that term."""
    return (4 * _mean_tangent_angle(yz, pos, h) - _mean_tangent_angle(yz, pos, 2 * h)) / 3


def scan_element_geometry(vertices, faces, rows_x, row_widths, theta, span, *,
                          smoothing: float | None = None, row_names=None) -> ScanElements:
    """Per-element points, inward normals, areas and turnings of a cuff on a scanned surface.

    Parameters
    ----------
    vertices : array (V, 3) or ScanMesh
        Mesh vertices in the cuff frame [m], or a mesh from :func:`prepare_scan_mesh` (to
        place several layouts on one scan; ``faces`` is then ignored).
    faces : array (F, 3)
        Triangles as vertex indices.
    rows_x, row_widths : array (R,)
        Axial position and width of each row [m].
    theta, span : array (J,)
        Angle and angular width of each angular location [rad], span in (0, 2 pi].
    smoothing : float, optional
        Smoothing length h [m]: the half-length of the outline arc the tangent angle is
        averaged over for the turning, and the radius the surface normal is averaged over
        (both also at 2h). Default per row: the largest of :data:`DEFAULT_SMOOTHING`, two
        median mesh edges and three median outline segments, at most a quarter of the row's
        shortest element arc.
    row_names : sequence of str, optional
        Labels of the rows for the error messages (``A`` gives ``row A``; default 0, 1 ...).

    Returns
    -------
    ScanElements
        Row-major, n = R * J.

    Raises
    ------
    ModelInputError
        Quantity ``scan`` for a mesh or layout the elements cannot be placed on (see
        :func:`axis_loop`; a band reaching past the scan's end), ``geometry`` for bad arrays.
    """
    xr, wr = np.atleast_1d(np.asarray(rows_x, float)), np.atleast_1d(np.asarray(row_widths, float))
    th, sp = np.atleast_1d(np.asarray(theta, float)), np.atleast_1d(np.asarray(span, float))
    if xr.ndim != 1 or xr.shape != wr.shape or th.ndim != 1 or th.shape != sp.shape:
        raise ModelInputError("expected rows_x and row_widths of one shape (R,), theta and span "
                              "of one shape (J,)", "geometry")
    if not (np.all(np.isfinite(xr)) and np.all(np.isfinite(th)) and np.all(wr > 0)
            and np.all(sp > 0) and np.all(sp <= 2 * np.pi) and np.all(np.isfinite(wr))):
        raise ModelInputError("expected finite row positions, row widths > 0 and angular "
                              "widths in (0, 2 pi]", "geometry")
    if smoothing is not None and not (np.isfinite(smoothing) and smoothing > 0):
        raise ModelInputError(f"smoothing must be a length > 0 [m], got {smoothing!r}", "geometry")
    mesh = vertices if isinstance(vertices, ScanMesh) else prepare_scan_mesh(vertices, faces)
    names = [f"row {r}" for r in (row_names if row_names is not None else range(len(xr)))]
    v, f = mesh.vertices, mesh.faces
    lo_ray, hi_ray = th - sp / 2, th + sp / 2
    n = len(xr) * len(th)
    points, normals = np.empty((n, 3)), np.empty((n, 3))
    areas, turning, arcs = np.empty(n), np.empty(n), np.empty(n)
    outlines, used_h = [], np.empty(len(xr))
    for r, (x, w) in enumerate(zip(xr, wr)):
        loop = axis_loop(mesh, float(x), names[r])
        yz = loop.yz
        seg = np.linalg.norm(np.roll(yz, -1, axis=0) - yz, axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        # ray crossings: centre rays (points, normals) and edge rays (arcs, turning)
        angles = np.concatenate([th, lo_ray, hi_ray])
        k, s = ray_hits(yz, angles)
        if np.any(k < 0):
            raise ModelInputError(f"a ray from the axis misses the outline of {names[r]} at x = "
                                  f"{x:.4g} m; expected the axis inside the limb", "scan")
        hit_yz = yz[k] + s[:, None] * (np.roll(yz, -1, axis=0)[k] - yz[k])
        pos = cum[k] + s * seg[k]
        J = len(th)
        sl = slice(r * J, (r + 1) * J)
        points[sl] = np.column_stack([np.full(J, x), hit_yz[:J]])
        pos_lo, pos_hi = pos[J:2 * J], pos[2 * J:]
        # an element going once around ends a full perimeter after it starts
        pos_hi = np.where(pos_hi <= pos_lo, pos_hi + cum[-1], pos_hi)
        arcs[sl] = pos_hi - pos_lo
        if smoothing is None:
            h = max(DEFAULT_SMOOTHING, 2 * mesh.edge_length, 3 * float(np.median(seg)))
            h = min(h, 0.25 * float(arcs[sl].min()))
        else:
            h = float(smoothing)
        used_h[r] = h
        turning[sl] = tangent_angle(yz, pos_hi, h) - tangent_angle(yz, pos_lo, h)
        comp = mesh.face_component[loop.face[0]]
        normals[sl] = _patch_normals(mesh, comp, points[sl], h, loop.face[k[:J]])
        # areas: the surface connected to this outline, clipped to each element's band
        fx = v[f[:, 0], 0], v[f[:, 1], 0], v[f[:, 2], 0]
        tri_lo, tri_hi = np.minimum.reduce(fx), np.maximum.reduce(fx)
        own = mesh.face_component == comp
        if tri_lo[own].min() > x - w / 2 or tri_hi[own].max() < x + w / 2:
            raise ModelInputError(
                f"the band of {names[r]} (x = {x - w / 2:.4g} .. {x + w / 2:.4g} m) reaches past "
                f"the scan's end (it spans x = {tri_lo[own].min():.4g} .. "
                f"{tri_hi[own].max():.4g} m there); expected the scan to cover every row's "
                "band", "scan")
        band = own & (tri_hi >= x - w / 2) & (tri_lo <= x + w / 2)
        tri = v[f[band]]
        x_planes = [((1.0, 0.0, 0.0), x - w / 2), ((-1.0, 0.0, 0.0), -(x + w / 2))]
        for j in range(J):
            # a wedge is the intersection of two half-spaces only below pi: split wider ones
            cuts = np.linspace(lo_ray[j], hi_ray[j], int(np.ceil(sp[j] / (0.75 * np.pi))) + 1)
            areas[r * J + j] = sum(clipped_area(tri, x_planes + _wedge_planes(a, b))
                                   for a, b in zip(cuts[:-1], cuts[1:]))
        outlines.append(yz)
    return ScanElements(points, normals, areas, turning, arcs, tuple(outlines), used_h)
