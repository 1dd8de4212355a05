"""Large-deformation hyperelastic reference FE of the tissue under a rigid, bonded cuff.

The reference for the reduced nonlinear coupled model. The linear FE's mesh
(:func:`~phri_spring.physics.fe_mesh._mesh_lines`: triquadratic hexahedra between the bone
r = R - t and the skin r = R, seam closed) solved with felupe at finite strain:

* material: felupe ``NeoHooke(mu, bulk)``, psi = mu/2 (J^-2/3 tr C - 3) + K/2 (J - 1)^2,
  mu = E / (2 (1 + nu)), K = E / (3 (1 - 2 nu)): small-strain limit (E, nu);
  ``law="linear"``: felupe ``LinearElastic(E, nu)``, for cross-checks;
* bone and both end faces of the tube clamped (the linear FE's ``ends='fixed'``);
* every skin node under a plate (:func:`~phri_spring.physics.fe_mesh.patch_plates`) moves
  with the cuff: x = t + Rot(w) (X + d), u = (t, w) the cuff's translation [m] and
  rotation vector [rad] about its origin (``rotation="linear"``: x = X + t + w x X + d);
  d: the plate's preload offset, its rigid motion delta_e of the linear coupled model
  (local axes normal inward, axial, circumferential, rotations about p_e).

Forces: plate-node reactions r_i (cuff on skin); cuff resultant (sum r_i, sum (x_i - t) x
r_i) about the moved origin (linear rotation: sum X_i x r_i, the work conjugate of u).
Patch normal force as the coupled model's ``N_out``: reactions L2-projected to a traction
on the plate (reference configuration), along the local normal n(X), integrated. Newton
on the free nodes (and the cuff's 6 dofs under load control), GMRES preconditioned by a
reused sparse LU, load steps with cut-back. SI units; felupe imported lazily.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse.linalg as spla

from ..errors import ConvergenceError, UsageError
from .coupled import patch_frames
from .fe_mesh import (DEFAULT_LENGTH_FACTOR, DEFAULT_PATCH_GAP, _mesh_lines, check_material,
                      patch_plates, single_radius)
from .geometry import skew

__all__ = ["HYPER_EXTRA_HINT", "HyperCuff", "HyperSolution", "build_hyper_cuff",
           "patch_forces", "solve_wrench", "preload_offsets", "rotation_matrix"]

HYPER_EXTRA_HINT = "the hyperelastic reference FE needs felupe: pip install -e .[hyper]"
LAWS = ("neo_hookean", "linear")


def _felupe():
    """Import felupe lazily; a one-line :class:`UsageError` when the extra is missing."""
    try:
        import felupe
    except ImportError:
        raise UsageError(HYPER_EXTRA_HINT) from None
    return felupe


def rotation_matrix(w) -> np.ndarray:
    """Rot(w) of a rotation vector w (3,) [rad] (Rodrigues' formula), shape (3, 3)."""
    w = np.asarray(w, float)
    th = float(np.linalg.norm(w))
    K = skew(w)      # sin(th)/th and (1 - cos th)/th^2, finite at th = 0
    return np.eye(3) + np.sinc(th / np.pi) * K + 0.5 * np.sinc(th / (2 * np.pi)) ** 2 * K @ K


@dataclass(eq=False)
class HyperSolution:
    """The hyperelastic FE's equilibrium for one cuff pose.

    Attributes
    ----------
    u : ndarray, shape (6,)
        Cuff displacement (t [m], rotation vector w [rad]) about the cuff origin.
    normal_forces : ndarray, shape (n,)
        Patch normal forces on the skin as the coupled model reports them [N]; > 0 presses.
    patch_forces : ndarray, shape (n, 6)
        Per patch, its plate's summed nodal reactions (normal, axial, circumferential) [N]
        and their moment about the moved patch centre [N*m], patch reference axes.
    wrench : ndarray, shape (6,)
        Resultant of the plate reactions about the cuff origin [N, N*m] (= the load).
    iterations, steps : int
        Newton iterations (tangent assemblies) and load steps of this solve.
    """

    u: np.ndarray
    normal_forces: np.ndarray
    patch_forces: np.ndarray
    wrench: np.ndarray
    iterations: int = 0
    steps: int = 0


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
                     law="neo_hookean", rotation=None, delta=None) -> HyperCuff:
    """Mesh the tissue under a cuff and set up its felupe model.

    Parameters
    ----------
    geometry : CuffGeometry
        The patches (one radius R [m]); plates apart (``patch_gap`` > 0).
    thickness, young_modulus, poisson_ratio : float
        Tissue thickness t [m] over the bone; E [Pa], nu [-] (<= 0.45) at small strain.
    level, patch_gap, length_factor
        Mesh level, free skin between plates [m], tissue beyond each cuff edge [t]: the
        linear FE's (:func:`~phri_spring.physics.fe_tissue.condensed_surface_operators`).
    law : {'neo_hookean', 'linear'}
        felupe ``NeoHooke(mu, bulk)`` or small-strain ``LinearElastic(E, nu)``.
    rotation : {'finite', 'linear'}, optional
        The cuff's rotation: Rodrigues' Rot(w), or the linearised I + [w]x (the linear
        FE's). Default: finite for the neo-Hookean law, linear for the linear one (a
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
    if rotation is None:
        rotation = "finite" if law == "neo_hookean" else "linear"
    if rotation not in ("finite", "linear"):
        raise ValueError(f"rotation: expected 'finite' or 'linear', got {rotation!r}")
    R = single_radius(geometry)
    check_material(thickness=thickness, poisson_ratio=poisson_ratio,
                   young_modulus=young_modulus, radius=R)
    gap = float(patch_gap)
    if not gap > 0:
        raise ValueError(f"patch_gap: expected > 0 m (plates sharing nodes), got {patch_gap!r}")
    ax, ang, rad = _mesh_lines(geometry, thickness, int(level), length_factor, gap)
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
    umat = fem.NeoHooke(mu=mu, bulk=bulk) if law == "neo_hookean" else \
        fem.LinearElastic(E=E, nu=nu)
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
                      mu=mu, bulk=bulk, seconds=time.perf_counter() - t0)
    return model


def preload_offsets(coupled_model) -> np.ndarray:
    """The linear coupled model's preload offsets as plate motions (n, 6), local axes.

    ``delta`` of :func:`~phri_spring.physics.coupled.build_coupled_model` with a rigid
    cuff (delta = C_t P0: at zero wrench its patches sit at q = delta and report f0):
    normal (> 0: into the arm), axial, circumferential [m], rotations [rad].
    """
    d = np.asarray(coupled_model.delta, float).reshape(coupled_model.n, -1)
    out = np.zeros((coupled_model.n, 6))
    out[:, :d.shape[1]] = d
    return out


# --------------------------------------------------------------------- kinematics

def _plate_motion(model, q, pre):
    """Plate node displacements (m_all, 3) for cuff pose q and preload fraction ``pre``."""
    X = model.points[model._fe["s_nodes"]]
    Y = X + pre * model._fe["d"]
    if model.rotation == "finite":
        return q[:3] + Y @ rotation_matrix(q[3:]).T - X
    return q[:3] + np.cross(q[3:], X) + Y - X


def _wrench_of(model, q, pre, rs):
    """(resultant about the cuff origin (6,), current plate node positions) of reactions rs."""
    X = model.points[model._fe["s_nodes"]]
    x = X + _plate_motion(model, q, pre)
    arm = x - q[:3] if model.rotation == "finite" else X
    return np.concatenate([rs.sum(0), np.cross(arm, rs).sum(0)]), x


def _jacobians(model, q, pre, rs, h=1e-7):
    """G = d(plate displacements)/dq (3m, 6), H = d(wrench)/dq at fixed reactions (6, 6):
    central differences of the kinematics alone."""
    G, H = np.empty((rs.size, 6)), np.empty((6, 6))
    for k in range(6):
        dq = h * np.eye(6)[k]
        G[:, k] = (_plate_motion(model, q + dq, pre) - _plate_motion(model, q - dq, pre)
                   ).ravel() / (2 * h)
        H[:, k] = (_wrench_of(model, q + dq, pre, rs)[0]
                   - _wrench_of(model, q - dq, pre, rs)[0]) / (2 * h)
    return G, H


# --------------------------------------------------------------------------- solver

def _assemble(model, u, matrix=True):
    fe, fld = model._fe, model._fe["field"]
    fld[0].values[:] = u.reshape(-1, 3)
    r = np.asarray(fe["solid"].assemble.vector(fld).todense()).ravel()
    if not np.isfinite(r).all():
        return r, None
    return r, (fe["solid"].assemble.matrix(fld).tocsr() if matrix else None)


#: inner (GMRES) iterations after which the preconditioner's LU is refreshed
_KRYLOV_MAX = 40


class _Step:
    """Newton system J = K_ff, or bordered by the cuff's dofs (load control):
    J = [[K_ff, K_fs G], [A^T K_sf, A^T K_ss G + H]]; GMRES preconditioned by block
    elimination through a reused sparse LU of K_ff (refreshed when GMRES struggles)."""

    def __init__(self, model, K, cuff=None):
        fe = self.fe = model._fe
        s, f = fe["s"], fe["free"]
        self.Kff, nf, k = K[f][:, f], len(f), 0 if cuff is None else 6
        G, H, A = cuff if cuff is not None else (np.zeros((len(s), 0)), np.zeros((0, 0)),
                                                 np.zeros((len(s), 0)))
        self.KfsG = np.asarray(K[f][:, s] @ G)
        self.AKsf = np.asarray((K[s][:, f].T @ A).T)
        self.Sd = A.T @ np.asarray(K[s][:, s] @ G) + H
        self.nf, self.sc = nf, np.array([1.0] * 3 + [model.thickness] * 3)[:k]
        if fe.get("lu") is None:
            self.refactor()

    def refactor(self):
        self.fe["lu"] = spla.splu(self.Kff.tocsc(), permc_spec="MMD_AT_PLUS_A",
                                  options=dict(SymmetricMode=True))
        self.fe["stats"]["factorizations"] += 1
        self.fe["pc"] = None

    def solve(self, rf, rq=()):
        """The Newton step for residuals (r_f, h): J dx = -(r_f, h) (rotations and moments
        scaled by t); returns (dx_f, dq) or None."""
        nf, sc, fe = self.nf, self.sc, self.fe

        def mv(v):
            vq = v[nf:] / sc
            return np.concatenate([self.Kff @ v[:nf] + self.KfsG @ vq,
                                   (self.AKsf @ v[:nf] + self.Sd @ vq) / sc])
        b = -np.concatenate([rf, np.asarray(rq, float) / sc])
        for attempt in range(2):
            lu = fe["lu"]
            if fe.get("pc") is None or fe["pc"][0].shape[1] != len(sc):
                X = lu.solve(self.KfsG) if len(sc) else np.zeros((nf, 0))
                fe["pc"] = (X, np.linalg.inv(self.Sd - self.AKsf @ X))
            X, Sinv = fe["pc"]

            def pc(v):
                y = lu.solve(v[:nf])
                dq = Sinv @ (v[nf:] * sc - self.AKsf @ y)
                return np.concatenate([y - X @ dq, dq * sc])
            count = [0]
            op = spla.LinearOperator((len(b),) * 2, matvec=mv, dtype=float)
            M = spla.LinearOperator((len(b),) * 2, matvec=pc, dtype=float)
            x, info = spla.gmres(op, b, rtol=1e-10, atol=0.0, restart=_KRYLOV_MAX, maxiter=1,
                                 M=M, callback=lambda _: count.__setitem__(0, count[0] + 1),
                                 callback_type="pr_norm")
            fe["stats"]["krylov"] += count[0]
            if info == 0 and np.isfinite(x).all():
                if count[0] > _KRYLOV_MAX // 2:
                    fe["lu"] = None                      # refresh at the next step
                return x[:nf], x[nf:] / sc
            if attempt == 0:
                self.refactor()
        return None


def _newton(model, u, q, pre, W=None, maxiter=25):
    """Newton from (u, q): displacement control (W None: q fixed, plates already moved)
    or load control (q too, reactions' wrench = W). (u, q, iterations) or None: failed."""
    fe = model._fe
    s, f = fe["s"], fe["free"]
    tol_f = 1e-9 * model.young_modulus * model.thickness ** 2        # [N]
    tol_w = tol_f * np.array([1.0] * 3 + [model.thickness] * 3)
    u, q = u.copy(), q.copy()
    for it in range(maxiter + 1):
        r, _ = _assemble(model, u, matrix=False)
        if not np.isfinite(r).all():
            return None
        rs = r[s].reshape(-1, 3)
        h = () if W is None else _wrench_of(model, q, pre, rs)[0] - W
        if np.abs(r[f]).max(initial=0.0) <= tol_f and np.all(np.abs(h) <= tol_w[:len(h)]):
            return u, q, it
        if it == maxiter:
            return None
        _, K = _assemble(model, u)
        fe["stats"]["newton"] += 1
        cuff = None
        if W is not None:
            G, H = _jacobians(model, q, pre, rs)
            cuff = (G, H, G if model.rotation == "linear" else _arm_map(model, q, pre))
        dx = _Step(model, K, cuff).solve(r[f], h)
        if dx is None:
            return None
        u[f] += dx[0]
        if W is not None:
            q = q + dx[1]
            u[s] = _plate_motion(model, q, pre).ravel()
    return None  # pragma: no cover


def _arm_map(model, q, pre):
    """A (3m, 6): nodal forces -> resultant about the moved cuff origin (finite rotation)."""
    X = model.points[model._fe["s_nodes"]]
    arm = X + _plate_motion(model, q, pre) - q[:3]
    A = np.zeros((len(arm), 3, 6))
    A[:, :, :3] = np.eye(3)
    A[:, :, 3:] = -skew(arm)            # (arm x r) = -[r]x arm; A^T r = sum [r; arm x r]
    return A.reshape(-1, 6)


def _state(model, preload):
    return model._state.setdefault(bool(preload), dict(
        u=np.zeros(3 * len(model.points)), q=np.zeros(6), pre=0.0, W=np.zeros(6)))


def _path(model, st, q_to, pre_to, W_to, steps, max_cuts=8):
    """Walk the stored state to (q_to, pre_to) (W_to None) or to the wrench W_to, in
    ``steps`` equal steps, halving a step that fails. Returns (iterations, steps)."""
    fe = model._fe
    s, f = fe["s"], fe["free"]
    q0, pre0, W0 = st["q"].copy(), st["pre"], st["W"].copy()
    frac, step, its, nsteps, cuts = 0.0, 1.0 / max(1, steps), 0, 0, 0
    while frac < 1 - 1e-12:
        b = min(1.0, frac + step)
        pre, u, W = pre0 + b * (pre_to - pre0), st["u"].copy(), None
        if W_to is None:
            q = q0 + b * (q_to - q0)
            # predictor: the tangent's response of the free nodes to the plates' move
            dus = _plate_motion(model, q, pre).ravel() - u[s]
            r, K = _assemble(model, u)
            res = None
            if K is not None:
                dx = _Step(model, K).solve(r[f] + K[f][:, s] @ dus)
                if dx is not None:
                    u[f] += dx[0]
                    u[s] += dus
                    res = _newton(model, u, q, pre)
            its += 1
        else:                               # the preload is ramped first (solve_wrench)
            W = W0 + b * (W_to - W0)
            res = _newton(model, u, st["q"], pre, W)
        if res is None:
            cuts += 1
            if cuts > max_cuts:
                raise ConvergenceError(f"hyperelastic FE: no convergence after {max_cuts} "
                                       f"step cut-backs at {frac:.4g} of the step")
            step /= 2
            continue
        st["u"], st["q"], it = res
        st["pre"], st["W"] = pre, (st["W"] if W is None else W)
        its, nsteps, frac = its + it, nsteps + 1, b
    return its, nsteps


def _result(model, st, its, steps):
    fe, g, q, pre = model._fe, model.geometry, st["q"], st["pre"]
    rs = _assemble(model, st["u"], matrix=False)[0][fe["s"]].reshape(-1, 3)
    W, x = _wrench_of(model, q, pre, rs)
    frames, fn, P = patch_frames(g), np.empty(g.n), np.empty((g.n, 6))
    for e in range(g.n):
        sl = fe["s_slices"][e]
        L, c = fe["forms"][e]
        lam = np.linalg.solve(L.T, np.linalg.solve(L, rs[sl]))        # traction [Pa]
        fn[e] = float(np.sum(c * lam))
        P[e, :3] = frames[e] @ rs[sl].sum(0)
        P[e, 3:] = frames[e] @ np.cross(x[sl] - _centre(model, e, q, pre), rs[sl]).sum(0)
    return HyperSolution(u=q.copy(), normal_forces=fn, patch_forces=P, wrench=W,
                         iterations=int(its), steps=int(steps))


def _centre(model, e, q, pre):
    """Position of patch e's centre p_e moved with its plate [m]."""
    g = model.geometry
    Y = g.points[e] + pre * patch_frames(g)[e].T @ model.delta[e, :3]
    if model.rotation == "finite":
        return q[:3] + rotation_matrix(q[3:]) @ Y
    return Y + q[:3] + np.cross(q[3:], g.points[e])


def patch_forces(model: HyperCuff, u, *, preload=True, steps=None) -> HyperSolution:
    """Patch forces for an imposed cuff displacement (displacement control).

    Parameters
    ----------
    model : HyperCuff
    u : array_like, shape (6,)
        Cuff displacement: translation t [m] and rotation vector w [rad] about the origin.
    preload : bool
        Plates offset by ``model.delta`` (the strap's hoop preload) or not.
    steps : int, optional
        Load steps from the last converged state (default one per 1 mm of plate move).

    Returns
    -------
    HyperSolution
    """
    q = np.asarray(u, float).reshape(6)
    st = _state(model, preload)
    pre_to = 1.0 if preload else 0.0
    if steps is None:
        move = _plate_motion(model, q, pre_to) - _plate_motion(model, st["q"], st["pre"])
        steps = max(1, int(math.ceil(np.abs(move).max() / 1e-3 - 1e-9)))
    its, n = _path(model, st, q, pre_to, None, steps)
    res = _result(model, st, its, n)
    st["W"] = res.wrench.copy()
    return res


def solve_wrench(model: HyperCuff, W, *, W_pre=None, preload=True, u0=None,
                 steps=None) -> HyperSolution:
    """Load control: the cuff displacement u at which the skin's resultant is W + W_pre.

    Parameters
    ----------
    model : HyperCuff
    W : array_like, shape (6,)
        Wrench on the cuff about the cuff origin, cuff frame [N, N*m].
    W_pre : array_like, shape (6,), optional
        The strap's wrench (the linear coupled model's ``W_pre``); default zero.
    preload : bool
        Plates offset by ``model.delta`` or not.
    u0 : array_like, shape (6,), optional
        Move to this pose first (default: start from the last converged state).
    steps : int, optional
        Load steps (default one per 25 N / 1 N*m of change).

    Returns
    -------
    HyperSolution
        ``u``: the cuff displacement; cut-backs halve a failed step.
    """
    W = np.asarray(W, float).reshape(6) + (0.0 if W_pre is None else
                                           np.asarray(W_pre, float).reshape(6))
    st = _state(model, preload)
    pre_to = 1.0 if preload else 0.0
    its = n = 0
    if u0 is not None or st["pre"] != pre_to:
        q0 = st["q"] if u0 is None else np.asarray(u0, float).reshape(6)
        sol = patch_forces(model, q0, preload=preload)
        its, n = sol.iterations, sol.steps
    if steps is None:
        d = np.abs(W - st["W"])
        steps = max(1, int(math.ceil(max(d[:3].max() / 25.0, d[3:].max()) - 1e-9)))
    i2, n2 = _path(model, st, None, pre_to, W, steps)
    return _result(model, st, its + i2, n + n2)
