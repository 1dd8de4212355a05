"""The large-deformation FE of the tissue under a rigid, bonded cuff: mesh, material, plates.

Builds the felupe model that :mod:`phri_spring.physics.hyperelastic.fe` solves (its docstring
has the model): the linear FE's mesh (:func:`~phri_spring.physics.continuum.mesh.mesh_lines`),
the material (:data:`LAWS`), the clamped nodes and every patch's plate with its skin
mass and normal loads for the traction projection. felupe imported lazily.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ...errors import UsageError
from ..continuum.coupled import patch_frames
from ..continuum.mesh import (DEFAULT_LENGTH_FACTOR, DEFAULT_PATCH_GAP, mesh_lines, check_material,
                      patch_plates, single_radius)

__all__ = ["HYPER_EXTRA_HINT", "LAWS", "HyperCuff", "build_hyper_cuff"]

HYPER_EXTRA_HINT = "the hyperelastic reference FE needs felupe: pip install -e .[hyper]"
LAWS = ("neo_hookean", "ogden", "linear")


def _material(fem, law, young_modulus, poisson_ratio, ogden_alpha):
    """The felupe material of a law at small-strain moduli (E, nu): mu = E / (2 (1 + nu)),
    K = E / (3 (1 - 2 nu)).

    ``ogden``: the compressible one-term Ogden solid of the punch FE
    (:mod:`~phri_spring.physics.hyperelastic.punch_ogden`), psi = (2 mu / alpha^2)(sum_i
    (J^-1/3 lambda_i)^alpha - 3) + K/2 (J - 1)^2, by felupe's automatic differentiation
    (tensortrax); alpha = 2 is the neo-Hookean solid.
    """
    E, nu = float(young_modulus), float(poisson_ratio)
    mu, bulk = E / (2 * (1 + nu)), E / (3 * (1 - 2 * nu))
    if law == "neo_hookean":
        return fem.NeoHooke(mu=mu, bulk=bulk)
    if law == "ogden":
        try:
            iso = fem.Hyperelastic(fem.ogden, mu=[mu], alpha=[float(ogden_alpha)])
        except (ImportError, AttributeError):
            raise UsageError("the Ogden law needs tensortrax: pip install -e .[hyper]") from None
        return iso & fem.Volumetric(bulk=bulk)
    return fem.LinearElastic(E=E, nu=nu)


def _felupe():
    """Import felupe lazily; a one-line :class:`UsageError` when the extra is missing."""
    try:
        import felupe
    except ImportError:
        raise UsageError(HYPER_EXTRA_HINT) from None
    return felupe


@dataclass(eq=False)
class HyperCuff:
    """The felupe model of the tissue under a rigid bonded cuff (module docstring).

    Attributes: ``thickness`` t [m], ``young_modulus`` E [Pa], ``poisson_ratio`` nu,
    ``law``, ``rotation``, ``points`` (N, 3) mesh nodes [m], ``plate_nodes`` per patch,
    ``delta`` (n, 6) plate preload offsets (local axes) [m, rad], ``info`` (``level``,
    ``n_dofs``, ``n_elements``, ``n_plate_nodes``, ``length`` [m], ``mu``, ``bulk`` [Pa]).
    The converged states (one per preload setting) are kept: each solve starts there.
    """

    geometry: object
    thickness: float
    young_modulus: float
    poisson_ratio: float
    law: str
    rotation: str
    points: np.ndarray = field(repr=False)
    plate_nodes: list = field(repr=False)
    delta: np.ndarray = field(repr=False)
    info: dict = field(default_factory=dict)
    _fe: dict = field(default_factory=dict, repr=False)
    _state: dict = field(default_factory=dict, repr=False)

    def set_preload(self, delta) -> None:
        """Set the plates' preload offsets: delta (n*d,) or (n, d), d = 3 or 6, local axes
        [m, rad], as the linear coupled model's ``delta``; resets the stored states."""
        d = np.asarray(delta, float).reshape(self.geometry.n, -1)
        if d.shape[1] not in (3, 6) or not np.isfinite(d).all():
            raise ValueError(f"delta: expected finite (n*3,) or (n*6,) offsets, got {d.shape}")
        self.delta = np.zeros((self.geometry.n, 6))
        self.delta[:, :d.shape[1]] = d
        self._fe["d"] = _plate_offsets(self)
        self._state.clear()

    def checkpoint(self) -> dict:
        """A copy of the converged states, for :meth:`restore`."""
        return {k: {n: np.copy(v) for n, v in st.items()} for k, st in self._state.items()}

    def restore(self, checkpoint: dict) -> None:
        """Continue from a :meth:`checkpoint` ({}: from the undeformed state)."""
        self._state = {k: {n: (float(v) if n == "pre" else np.copy(v)) for n, v in st.items()}
                       for k, st in checkpoint.items()}


def _mid(v):
    out = np.empty(2 * len(v) - 1)
    out[::2], out[1::2] = v, 0.5 * (v[:-1] + v[1:])
    return out


def _plate_forms(P, nodes_grid):
    """Scalar skin mass m (k, k) and normal loads c (k, 3) of one plate's 9-node facets.

    ``nodes_grid``: (nfx, nft, 3, 3) global node ids of each facet (x, theta order);
    isoparametric facets, 3 x 3 Gauss points (as the linear FE's facet basis, order 5).
    """
    ids = np.unique(nodes_grid)
    loc = np.searchsorted(ids, nodes_grid).reshape(-1, 9)
    s, w = np.array([-math.sqrt(0.6), 0.0, math.sqrt(0.6)]), np.array([5, 8, 5]) / 9.0
    N = np.stack([s * (s - 1) / 2, 1 - s ** 2, s * (s + 1) / 2])   # (3 nodes, 3 qp)
    dN = np.stack([s - 0.5, -2 * s, s + 0.5])
    phi = np.einsum("aq,bp->abqp", N, N).reshape(9, 9)   # node (a,b), qp (q,p)
    dxi = np.einsum("aq,bp->abqp", dN, N).reshape(9, 9)
    deta = np.einsum("aq,bp->abqp", N, dN).reshape(9, 9)
    wq = np.outer(w, w).ravel()
    m = np.zeros((len(ids), len(ids)))
    c = np.zeros((len(ids), 3))
    for f in loc:
        X = P[ids[f]]                                    # (9, 3)
        x = phi.T @ X
        a, b = dxi.T @ X, deta.T @ X
        dA = np.linalg.norm(np.cross(a, b), axis=1) * wq
        r = np.hypot(x[:, 1], x[:, 2])
        nrm = -np.column_stack([np.zeros(9), x[:, 1] / r, x[:, 2] / r])
        m[np.ix_(f, f)] += (phi * dA) @ phi.T
        c[f] += (phi * dA) @ nrm
    return ids, m, c


def _plate_offsets(model):
    """Preload displacement d (m_all, 3) of every plate node, global axes [m]."""
    fe, g = model._fe, model.geometry
    frames, d = patch_frames(g), np.zeros((len(fe["s_nodes"]), 3))
    for e in range(g.n):
        sl = fe["s_slices"][e]
        d[sl] = frames[e].T @ model.delta[e, :3] + np.cross(
            frames[e].T @ model.delta[e, 3:], model.points[fe["s_nodes"][sl]] - g.points[e])
    return d


def build_hyper_cuff(geometry, thickness, young_modulus, poisson_ratio, *, level=3,
                     patch_gap=DEFAULT_PATCH_GAP, length_factor=DEFAULT_LENGTH_FACTOR,
                     law="neo_hookean", ogden_alpha=None, rotation=None,
                     delta=None) -> HyperCuff:
    """Mesh the tissue under a cuff and set up its felupe model.

    Parameters
    ----------
    geometry : CuffGeometry
        The patches (one radius R [m]); plates apart (``patch_gap`` > 0).
    thickness, young_modulus, poisson_ratio : float
        Tissue thickness t [m] over the bone; E [Pa], nu [-] (<= 0.45) at small strain.
    level, patch_gap, length_factor
        Mesh level, free skin between plates [m], tissue beyond each cuff edge [t]: the
        linear FE's (:func:`~phri_spring.physics.continuum.tissue.condensed_surface_operators`).
    law : {'neo_hookean', 'ogden', 'linear'}
        felupe ``NeoHooke(mu, bulk)``, the one-term Ogden solid with exponent
        ``ogden_alpha`` (:func:`_material`), or small-strain ``LinearElastic(E, nu)``.
    ogden_alpha : float
        The Ogden exponent alpha [-] (law ``ogden`` only; 0 < alpha <= 40).
    rotation : {'finite', 'linear'}, optional
        The cuff's rotation: Rodrigues' Rot(w), or the linearised I + [w]x (the linear
        FE's). Default: finite for the hyperelastic laws, linear for the linear one (a
        small-strain law is not objective: a finite rotation strains it spuriously).
    delta : array_like, shape (n*d,), optional
        Plate preload offsets (:meth:`HyperCuff.set_preload`), e.g. :func:`preload_offsets`.

    Returns
    -------
    HyperCuff

    Raises
    ------
    UsageError
        felupe (extra ``hyper``) not installed (ValueError: inputs out of range).
    """
    fem = _felupe()
    t0 = time.perf_counter()
    if law not in LAWS:
        raise ValueError(f"law: expected one of {LAWS}, got {law!r}")
    if law == "ogden" and not (ogden_alpha is not None and 0 < float(ogden_alpha) <= 40):
        raise ValueError(f"ogden_alpha: expected 0 < alpha <= 40, got {ogden_alpha!r}")
    if rotation is None:
        rotation = "linear" if law == "linear" else "finite"
    if rotation not in ("finite", "linear"):
        raise ValueError(f"rotation: expected 'finite' or 'linear', got {rotation!r}")
    R = single_radius(geometry)
    check_material(thickness=thickness, poisson_ratio=poisson_ratio,
                   young_modulus=young_modulus, radius=R)
    gap = float(patch_gap)
    if not gap > 0:
        raise ValueError(f"patch_gap: expected > 0 m (plates sharing nodes), got {patch_gap!r}")
    ax, ang, rad = mesh_lines(geometry, thickness, int(level), length_factor, gap)
    xs, ths, rs = _mid(ax.nodes), _mid(ang.nodes)[:-1], _mid(rad)      # theta periodic
    nx, nt, nr = len(xs), len(ths), len(rs)
    I, J, K = np.meshgrid(np.arange(nx), np.arange(nt), np.arange(nr), indexing="ij")
    th, rr = ths[J].ravel(), rs[K].ravel()
    P = np.column_stack([xs[I].ravel(), rr * np.cos(th), rr * np.sin(th)])

    def node(i, j, k):
        return (i * nt + np.mod(j, nt)) * nr + k

    ref = fem.TriQuadraticHexahedron().points.astype(int) + 1          # (27, 3) in {0,1,2}
    ex, et, er = np.meshgrid(np.arange((nx - 1) // 2), np.arange(nt // 2),
                             np.arange((nr - 1) // 2), indexing="ij")
    ex, et, er = (a.ravel()[:, None] for a in (ex, et, er))
    # element axes (xi, eta, zeta) = (x, r, theta): a positive Jacobian
    cells = node(2 * ex + ref[:, 0], 2 * et + ref[:, 2], 2 * er + ref[:, 1])
    mesh = fem.Mesh(P, cells, "hexahedron27")
    region = fem.RegionTriQuadraticHexahedron(mesh)
    if np.any(region.dV <= 0):
        raise RuntimeError("tissue mesh: non-positive element volume")  # pragma: no cover
    fld = fem.FieldContainer([fem.Field(region, dim=3)])
    E, nu = float(young_modulus), float(poisson_ratio)
    mu, bulk = E / (2 * (1 + nu)), E / (3 * (1 - 2 * nu))
    umat = _material(fem, law, E, nu, ogden_alpha)
    solid = fem.SolidBody(umat, fld)
    # plates: skin nodes in each plate's box (theta on the plate's own branch)
    xl, xh, tl, th_ = patch_plates(geometry, gap)
    tol = 1e-9
    skin_i, skin_j = np.meshgrid(np.arange(nx), np.arange(nt), indexing="ij")
    skin = node(skin_i, skin_j, nr - 1)                                  # (nx, nt)
    plate_nodes, s_slices, forms, start = [], [], [], 0
    for e in range(geometry.n):
        inx = (xs >= xl[e] - tol * R) & (xs <= xh[e] + tol * R)
        inth = np.mod(ths - tl[e] + tol, 2 * np.pi) <= th_[e] - tl[e] + 2 * tol
        ia, ja = np.nonzero(inx)[0], np.nonzero(inth)[0]
        if len(ia) < 3 or len(ja) < 3 or len(ia) % 2 == 0 or len(ja) % 2 == 0:
            raise RuntimeError("plate not on mesh lines")  # pragma: no cover
        # facets: 3 x 3 node blocks starting at even offsets along the plate's lines
        jj = ja[np.argsort(np.mod(ths[ja] - tl[e] + tol, 2 * np.pi))]
        blocks = np.array([[skin[np.ix_(ia[a:a + 3], jj[b:b + 3])]
                            for b in range(0, len(jj) - 2, 2)]
                           for a in range(0, len(ia) - 2, 2)])
        ids, m, c = _plate_forms(P, blocks)
        plate_nodes.append(ids)
        s_slices.append(slice(start, start + len(ids)))
        forms.append((np.linalg.cholesky(m), c))
        start += len(ids)
    s_nodes = np.concatenate(plate_nodes)
    if len(np.unique(s_nodes)) != len(s_nodes):
        raise ValueError("plates share skin nodes; expected a patch_gap wide enough to "
                         "separate them")
    ii = np.arange(len(P)) // (nt * nr)
    fixed_nodes = np.nonzero((np.arange(len(P)) % nr == 0) | (ii == 0) | (ii == nx - 1))[0]
    dofs = lambda nodes: (3 * nodes[:, None] + np.arange(3)).ravel()  # noqa: E731
    s = dofs(s_nodes)
    fixed = np.setdiff1d(dofs(fixed_nodes), s)
    free = np.setdiff1d(np.arange(3 * len(P)), np.union1d(s, fixed))
    model = HyperCuff(geometry=geometry, thickness=float(thickness), young_modulus=E,
                      poisson_ratio=nu, law=law, rotation=rotation, points=P,
                      plate_nodes=plate_nodes, delta=np.zeros((geometry.n, 6)))
    model._fe.update(fem=fem, field=fld, solid=solid, s=s, free=free, s_nodes=s_nodes,
                     stats=dict(factorizations=0, newton=0, krylov=0),
                     s_slices=s_slices, forms=forms)
    model.set_preload(np.zeros(6 * geometry.n) if delta is None else delta)
    model.info = dict(level=int(level), n_dofs=3 * len(P), n_free=len(free),
                      n_elements=len(cells), n_plate_nodes=len(s_nodes), patch_gap=gap,
                      length=float(xs[-1] - xs[0]), length_factor=float(length_factor),
                      mu=mu, bulk=bulk, seconds=time.perf_counter() - t0,
                      ogden_alpha=None if law != "ogden" else float(ogden_alpha))
    return model


