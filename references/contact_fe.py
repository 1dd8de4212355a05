"""Reference FE of the cuff's contact: rigid plates touching the tissue node by node.

The coupled model (docs/model.md section 10) condenses the tissue onto whole patches
and decides contact per patch. This reference keeps the same tissue FE
(:func:`~phri_spring.physics.continuum.assembly.assemble_tissue_fe`: bone fixed, every other
node free) and makes every skin node under a patch's plate a contact of its own.
:func:`build_contact_fe` condenses the FE onto those nodes (:class:`ContactFE`, a Schur
complement in each node's axes: inward normal n, axial a, circumferential c = n x a);
:func:`solve_contact_path` / :func:`solve_contact` solve the cuff's contact along a
loading path (a :class:`ContactSolution` per row).

The cuff: plate e moves rigidly with zeta_e (translation of its centre, small rotation;
local patch axes of :func:`~phri_spring.physics.continuum.coupled.patch_frames`). Its rotation is
the cuff's, (T u + delta)_e; its translation is joined to (T u + delta)_e by the cuff
spring (normal k_c,e, tangential eta k_c,e; k_c,e = inf: rigid), as the coupled model's
C_c. T, delta and W_pre (the strap's preload) are the coupled model's; u is the cuff's
displacement.

Contact of node i with plate e (a node two plates share touches the deeper one): gap
x_n - (plate point)_n >= 0 along the node's normal, normal reaction lambda_n >= 0,
lambda_n gap = 0. Frictionless (mu = 0): tangentially free (condensed). Coulomb
(mu > 0): a touching node sticks (its tangential offset from the plate keeps its value
at the start of the load step) while ``|lambda_t| <= mu lambda_n``, else slides with
lambda_t = mu lambda_n e, e against its slip in the step (return mapping); the state is
carried from step to step. mu = inf: touching nodes never slide (bonded). A node that
touches a plate during a step grazes it (tangentially free) until the next step.

Each step is a semismooth Newton (active-set) iteration: contact (released when
pulling, touching when penetrating) and stick or slip by Alart and Curnier's augmented
test ``|lambda_t - rho slip| <= mu lambda_n``, the slip law linearised with its direction.
For a set, the prescribed skin displacements are eliminated; the free ones, the plates'
translations and u solve one linear system. The reported patch normal force is the
coupled model's for the built-in FE (its ``N_out``): the recovered traction of the nodal
reactions integrated over the plate with the local normal.

SI units; scikit-fem (extra ``fe``) is imported only inside the assembly.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from phri_spring.errors import ConvergenceError, ModelInputError
from phri_spring.physics.continuum.coupled import patch_frames
from phri_spring.physics.continuum.assembly import factor, assemble_tissue_fe
from phri_spring.physics.continuum.mesh import (DEFAULT_LENGTH_FACTOR, DEFAULT_LEVEL,
                                               check_material, single_radius)
from phri_spring.physics.cuff.geometry import rigid_body_map

__all__ = ["ContactFE", "ContactSolution", "build_contact_fe", "solve_contact",
           "solve_contact_path"]

#: relative tolerance of the contact, stick and slip decisions (of the largest reaction
#: [N] or displacement [m] of the iterate)
SET_TOL = 1e-9


@dataclass(eq=False)
class ContactFE:
    """The tissue FE condensed onto the m skin nodes under the cuff's plates.

    Attributes
    ----------
    geometry : CuffGeometry
    young_modulus : float
        E [Pa] (the matrices are for this E).
    points : ndarray, shape (m, 3)
        Node positions, cuff frame [m].
    frames : ndarray, shape (m, 3, 3)
        Per node, rows: inward normal n_i, axial a, circumferential c_i = n_i x a [-].
    K : ndarray, shape (3m, 3m)
        Stiffness of the nodes (node-major, local axes n, a, c), every other node free and
        the bone fixed [N/m]: their nodal forces are K x.
    K_normal : ndarray, shape (m, m)
        The normal block of K with the tangential components free [N/m].
    tangential_map : ndarray, shape (2m, m)
        Tangential displacements (a, c per node) of the normal ones with free tangents [-].
    incidence : ndarray of bool, shape (m, n)
        Node i lies on the plate of patch e.
    plate_map : ndarray, shape (m, n, 3, 6)
        Motion of plate e's point at node i (local axes of the node) per local plate dof
        zeta_e (0 where node and plate do not meet) [-, m].
    normal_output : ndarray, shape (n, 3m)
        Nodal reactions (local) -> patch normal force, the recovered traction integrated
        over the plate with the local normal [-].
    patch_output : ndarray, shape (6n, 3m)
        Nodal reactions (local) -> patch forces and moments about p_e, local patch axes,
        from the same traction [-, m].
    info : dict
        ``level``, ``n_dofs``, ``n_nodes`` (m), ``patch_gap`` [m], ``seconds``.
    """

    geometry: object
    young_modulus: float
    points: np.ndarray = field(repr=False)
    frames: np.ndarray = field(repr=False)
    K: np.ndarray = field(repr=False)
    K_normal: np.ndarray = field(repr=False)
    tangential_map: np.ndarray = field(repr=False)
    incidence: np.ndarray = field(repr=False)
    plate_map: np.ndarray = field(repr=False)
    normal_output: np.ndarray = field(repr=False)
    patch_output: np.ndarray = field(repr=False)
    info: dict = field(default_factory=dict)


@dataclass(eq=False)
class ContactSolution:
    """The contact FE's equilibrium at one row of a loading path.

    Attributes
    ----------
    u : ndarray, shape (6,)
        Cuff displacement (t [m], w [rad]) about the cuff origin, cuff frame.
    wrench : ndarray, shape (6,)
        W + W_pre, the wrench on the cuff [N, N*m].
    normal_forces : ndarray, shape (n,)
        Patch normal forces as the coupled model reports them [N] (compression > 0).
    patch_forces : ndarray, shape (n, 6)
        Patch forces and moments about p_e on the skin, local patch axes (normal, axial,
        circumferential), from the recovered traction [N, N*m].
    plate_forces : ndarray, shape (n, 6)
        The same as the sum of the reactions of the nodes touching each plate (the cuff
        springs' forces) [N, N*m].
    reactions : ndarray, shape (m, 3)
        Force of the plates on each node, local axes of the node [N].
    displacements : ndarray, shape (m, 3)
        Node displacements, local axes of the node [m].
    plates : ndarray, shape (n, 6)
        Plate motions zeta_e, local patch axes [m, rad].
    contact, slip : ndarray of bool, shape (m,)
        Nodes touching a plate; touching nodes that slide.
    plate : ndarray of int, shape (m,)
        The plate each node touches (-1: none).
    residual : ndarray, shape (6,)
        Wrench of the nodal reactions about the origin minus ``wrench`` [N, N*m].
    iterations : int
        Linear solves of the row.
    """

    u: np.ndarray
    wrench: np.ndarray
    normal_forces: np.ndarray
    patch_forces: np.ndarray
    plate_forces: np.ndarray
    reactions: np.ndarray = field(repr=False)
    displacements: np.ndarray = field(repr=False)
    plates: np.ndarray = field(repr=False)
    contact: np.ndarray = field(repr=False)
    slip: np.ndarray = field(repr=False)
    plate: np.ndarray = field(repr=False)
    residual: np.ndarray = field(repr=False)
    iterations: int = 0
    _law: np.ndarray = field(default=None, repr=False)


# ------------------------------------------------------------------------ condensation

def _skin_schur(K, s, free, block):
    """S = K_ss - K_sf K_ff^-1 K_fs (dense), K_ff^-1 by one sparse LU and column blocks."""
    K = K.tocsr()
    S = K[s][:, s].toarray()
    Kfs = K[free][:, s].tocsc()
    Ksf = K[s][:, free].tocsr()
    lu = factor(K[free][:, free])
    pr, pc = lu.perm_r, lu.perm_c
    L = lu.L.tocsr()
    U = lu.U.tocsr()
    del lu
    d = U.diagonal()
    U = (sp.diags(1.0 / d) @ U).tocsr()              # unit upper: U = diag(d) U'
    for j0 in range(0, len(s), block):
        j1 = min(len(s), j0 + block)
        y = np.empty((len(free), j1 - j0))
        y[pr] = Kfs[:, j0:j1].toarray()              # Pr b
        y = spla.spsolve_triangular(L, y, lower=True, unit_diagonal=True,
                                    overwrite_A=True, overwrite_b=True)
        y /= d[:, None]
        y = spla.spsolve_triangular(U, y, lower=False, unit_diagonal=True,
                                    overwrite_A=True, overwrite_b=True)
        S[:, j0:j1] -= Ksf @ y[pc]                   # K_ff^-1 b = Pc U^-1 L^-1 Pr b
    return 0.5 * (S + S.T)


def _node_frames(points):
    r = np.hypot(points[:, 1], points[:, 2])
    n = -np.column_stack([np.zeros(len(points)), points[:, 1] / r, points[:, 2] / r])
    a = np.broadcast_to([1.0, 0.0, 0.0], n.shape)
    return np.stack([n, a, np.cross(n, a)], axis=1)


def build_contact_fe(geometry, thickness, young_modulus, poisson_ratio, *,
                     level: int = DEFAULT_LEVEL, length_factor: float = DEFAULT_LENGTH_FACTOR,
                     ends: str = "fixed", patch_gap: float | None = None,
                     block: int = 256) -> ContactFE:
    """Condense the tissue FE onto the skin nodes under the cuff's plates.

    Parameters
    ----------
    geometry : CuffGeometry
        The patches (one radius R [m]).
    thickness : float
        Tissue thickness t [m], 0 < t < R.
    young_modulus : float
        E [Pa].
    poisson_ratio : float
        nu [-].
    level, length_factor, ends
        Mesh level, tissue beyond the cuff [thicknesses] and end faces, as
        :func:`~phri_spring.physics.continuum.tissue.condensed_surface_operators`.
    patch_gap : float, optional
        Free skin between neighbouring plates [m], passed to the assembly when given
        (otherwise the assembly's default: the built-in model's mesh).
    block : int, optional
        Right-hand sides per block of the condensation (memory: 8 block x dofs bytes).

    Returns
    -------
    ContactFE

    Raises
    ------
    ValueError
        Thickness, E, nu, level or geometry out of range.
    UsageError
        scikit-fem (extra ``fe``) not installed.
    """
    t0 = time.perf_counter()
    R = single_radius(geometry)
    check_material(thickness=thickness, poisson_ratio=poisson_ratio,
                   young_modulus=young_modulus, radius=R)
    kw = {} if patch_gap is None else {"patch_gap": float(patch_gap)}
    fe = assemble_tissue_fe(geometry, float(thickness), float(poisson_ratio), int(level),
                            float(length_factor), ends, patch_modes=True, **kw)
    s, g = fe.skin, fe.dof_map
    if len(s) % 3 or np.any(s.reshape(-1, 3) - s[::3, None] != np.arange(3)):
        raise RuntimeError("skin dofs are not whole nodes")  # pragma: no cover
    node_ids = s[::3] // 3
    m, n = len(node_ids), geometry.n
    doflocs = fe.mesh.mesh.doflocs
    xyz = np.zeros((fe.n_nodes, 3))
    xyz[g[::3] // 3] = doflocs.T
    points = xyz[node_ids]
    Q = _node_frames(points)
    E = float(young_modulus)
    Qb = sp.block_diag(list(Q), format="csr")        # cartesian -> local, per node
    S = _skin_schur(fe.K, s, fe.free, int(block)) * E
    S = np.asarray(Qb @ (Qb @ S.T).T)                # Q S Q^T
    S = 0.5 * (S + S.T)
    nrm, tan = np.arange(m) * 3, np.setdiff1d(np.arange(3 * m), np.arange(m) * 3)
    cf = sla.cho_factor(S[np.ix_(tan, tan)])
    tmap = -sla.cho_solve(cf, S[np.ix_(tan, nrm)])
    Kn = S[np.ix_(nrm, nrm)] + S[np.ix_(nrm, tan)] @ tmap
    # plates: the nodes on each patch's plate facets, and the rigid map of their points
    inc = np.zeros((m, n), bool)
    for e, facets in enumerate(fe.mesh.patch_facets):
        nodes = np.unique(g[fe.basis.get_dofs(facets=facets).all()] // 3)
        inc[np.searchsorted(node_ids, nodes), e] = True
    Re = np.zeros((n, 6, 6))
    Re[:, :3, :3] = Re[:, 3:, 3:] = patch_frames(geometry)
    pm = np.zeros((m, n, 3, 6))
    ii, ee = np.nonzero(inc)
    G = rigid_body_map(points[ii] - geometry.points[ee])            # (k, 3, 6)
    pm[ii, ee] = Q[ii] @ G @ np.transpose(Re[ee], (0, 2, 1))
    # outputs: recovered traction lambda = M^-1 r (cartesian), integrated over the plates
    mlu = fe.skin_mass_lu()
    Cw = mlu.solve(np.asarray(fe.C[s]))                              # (3m, n)
    Bw = mlu.solve(np.asarray(fe.B[s]))                              # (3m, 6n)
    N_out = np.asarray((Qb @ Cw).T)
    Rb = sp.block_diag(list(Re), format="csr")
    P_out = np.asarray(Rb @ (Qb @ Bw).T)
    info = dict(level=int(level), n_dofs=int(3 * fe.n_nodes), n_nodes=int(m),
                patch_gap=float(getattr(fe.mesh, "patch_gap", 0.0)),
                seconds=time.perf_counter() - t0)
    return ContactFE(geometry=geometry, young_modulus=E, points=points, frames=Q, K=S,
                     K_normal=0.5 * (Kn + Kn.T), tangential_map=tmap, incidence=inc,
                     plate_map=pm, normal_output=N_out, patch_output=P_out, info=info)


# ------------------------------------------------------------------------------ the cuff

class _Cuff(NamedTuple):
    """The coupled model's cuff for w = (u, translations of the plates with finite cuff
    springs): plate motions zeta = Z w + alpha z_pre (local axes), the springs' stiffness
    Ksp (nw, nw) and preload load k_pre (nw,) (both from the offset delta), W_pre (6,)."""

    Z: np.ndarray
    z_pre: np.ndarray
    Ksp: np.ndarray
    k_pre: np.ndarray
    W_pre: np.ndarray


def _cuff(model, n) -> _Cuff:
    T = np.asarray(model.T, float)
    if T.shape != (6 * n, 6) or getattr(model, "dofs", 6) != 6:
        raise ModelInputError("contact FE: expected a coupled model with 6 dofs per patch "
                              f"for {n} patches", "surface_stiffness")
    delta = np.asarray(model.delta, float)
    k = np.broadcast_to(np.asarray(model.k_cuff, float), (n,))
    eta = float(model.shear_ratio)
    fin = np.flatnonzero(np.isfinite(k))
    nw = 6 + 3 * len(fin)
    Z = np.zeros((6 * n, nw))
    z_pre = delta.copy()
    Jsp = np.zeros((3 * len(fin), nw))                 # spring stretch per w
    Kc = np.zeros(3 * len(fin))
    for j, e in enumerate(fin):
        t, c = slice(6 * e, 6 * e + 3), slice(6 + 3 * j, 9 + 3 * j)
        Z[6 * e + 3:6 * e + 6, :6] = T[6 * e + 3:6 * e + 6]
        Z[t, c] = np.eye(3)
        z_pre[t] = 0.0
        Jsp[3 * j:3 * j + 3, :6] = T[t]
        Jsp[3 * j:3 * j + 3, c] = -np.eye(3)
        Kc[3 * j:3 * j + 3] = k[e] * np.array([1.0, eta, eta])
    for e in np.flatnonzero(~np.isfinite(k)):
        Z[6 * e:6 * e + 6, :6] = T[6 * e:6 * e + 6]
    d_sp = delta.reshape(n, 6)[fin, :3].ravel()
    return _Cuff(Z=Z, z_pre=z_pre, Ksp=Jsp.T @ (Kc[:, None] * Jsp), k_pre=Jsp.T @ (Kc * d_sp),
                 W_pre=np.asarray(model.W_pre, float))


# ---------------------------------------------------------------------------- one step

def _linear_solve(Kb, P, Fr, slip, cuff, Gam, alpha, W, c_P, length):
    """Solve the system of one contact set; returns x (base components), w and whether
    the cuff's equations were solvable.

    Kb: base stiffness (normals only, or all components); P / Fr: prescribed / free base
    components; Gam (nb, 6n): the plate maps of the touching nodes; length [m] scales the
    rotations of the cuff. slip: (nodes, s, c, rho, mu, anchor) of the sliding nodes: their
    tangential force obeys the slip law linearised at the last iterate,
    (I - c P) lambda_t - mu s lambda_n + c rho P (x_t - plate_t - anchor) = 0,
    P = I - s s^T (Alart and Curnier's augmented form, sigma = lambda_t - rho slip).
    """
    GZ = Gam @ cuff.Z                                                # (nb, nw)
    nb, nw = Kb.shape[0], cuff.Z.shape[1]
    Psi = np.zeros((nb, nw))
    Psi[P] = GZ[P]
    psi0 = np.zeros(nb)
    psi0[P] = Gam[P] @ (alpha * cuff.z_pre) + c_P
    A1 = Kb[Fr]
    B1 = np.zeros((len(Fr), nw))
    b1 = np.zeros(len(Fr))
    nodes, s, c, rho, mu, anchor = slip
    if len(nodes):
        t = 3 * nodes[:, None] + np.array([1, 2])                    # (k, 2)
        rows = np.searchsorted(Fr, t)
        Pp = np.eye(2) - s[:, :, None] * s[:, None, :]
        Pi = (c * rho)[:, None, None] * Pp
        A1[rows] = (np.einsum("kab,kbj->kaj", np.eye(2) - c[:, None, None] * Pp, Kb[t])
                    - mu * s[:, :, None] * Kb[3 * nodes][:, None, :])
        for i in range(2):
            for j in range(2):
                A1[rows[:, i], t[:, j]] += Pi[:, i, j]
        B1[rows] = -np.einsum("kab,kbj->kaj", Pi, GZ[t])
        b1[rows] = np.einsum("kab,kb->ka", Pi, Gam[t] @ (alpha * cuff.z_pre) + anchor)
    A2 = GZ.T @ Kb
    A22 = A2 @ Psi + cuff.Ksp
    b2 = -A2 @ psi0 - alpha * cuff.k_pre
    b2[:6] += W + alpha * cuff.W_pre
    if len(Fr):
        lu = sla.lu_factor(A1[:, Fr])
        X1 = sla.lu_solve(lu, A1 @ Psi + B1)
        x1 = sla.lu_solve(lu, b1 - A1 @ psi0)
        H, h = A22 - A2[:, Fr] @ X1, b2 - A2[:, Fr] @ x1
    else:
        H, h = A22, b2
    # the cuff may have rigid motions no contact resists (frictionless: along and about
    # the arm): least squares with the rotations in units of the radius, checked
    dsc = np.ones(len(h))
    dsc[3:6] = 1.0 / length
    Hs = H * dsc[:, None] * dsc[None, :]
    ws, *_ = sla.lstsq(Hs, h * dsc, cond=1e-10)
    w = ws * dsc
    scale = max(np.linalg.norm(h * dsc), np.linalg.norm(Hs) * np.linalg.norm(ws),
                np.linalg.norm((A2 @ psi0) * dsc), 1e-300)
    ok = np.linalg.norm(Hs @ ws - h * dsc) <= 1e-8 * scale
    x = psi0 + Psi @ w
    if len(Fr):
        x[Fr] = x1 - X1 @ w
    return x, w, ok


def _step(fe, cuff, mu, W, alpha, prev, max_iterations):
    """Equilibrium of one load step from the state ``prev``; returns the new state."""
    m, n = len(fe.points), fe.geometry.n
    nc = 1 if mu == 0 else 3
    Kb = fe.K_normal if nc == 1 else fe.K
    pm = fe.plate_map
    contact, plate = prev.contact.copy(), prev.plate.copy()
    slip, law = prev.slip.copy(), prev._law.copy()
    x0, z0 = prev.displacements, prev.plates
    ar = np.arange(m)
    inc = fe.incidence
    length = float(np.max(np.linalg.norm(fe.points[:, 1:], axis=1)))
    dK = np.diag(fe.K)
    rho = 0.5 * (dK[1::3] + dK[2::3])        # augmentation: a node's tangential stiffness
    friction = nc == 3 and np.isfinite(mu)
    lost, singular = np.zeros(m, bool), 0
    for it in range(1, max_iterations + 1):
        # the set: prescribed normals of touching nodes, tangents of sticking ones
        Gam = np.zeros((m, nc, n, 6))
        Gam[contact, :, plate[contact]] = pm[contact, plate[contact], :nc]
        Gam = Gam.reshape(m * nc, 6 * n)
        pres = np.zeros((m, nc), bool)
        pres[:, 0] = contact
        # a node that touches its plate in this step (or lost it in an iterate of the step)
        # is free along it until the next: it grazes, with no normal force to rub with
        fresh = contact & (lost | ~(prev.contact & (plate == prev.plate)))
        if nc == 3:
            pres[:, 1:] = (contact & ~slip & ~fresh)[:, None]
        P, Fr = np.flatnonzero(pres.ravel()), np.flatnonzero(~pres.ravel())
        # stick anchors: the node's tangential offset from its plate at the step's start
        own_map = pm[ar, np.maximum(plate, 0), 1:]                   # (m, 2, 6)
        anchor = x0[:, 1:] - np.einsum("ijk,ik->ij", own_map, z0[np.maximum(plate, 0)])
        cP = np.zeros((m, nc))
        if nc == 3:
            cP[:, 1:] = anchor
        sl = np.flatnonzero(contact & slip)
        xb, w, ok = _linear_solve(Kb, P, Fr, (sl, law[sl, :2], law[sl, 2], rho[sl], mu,
                                              anchor[sl]),
                                  cuff, Gam, alpha, W, cP.ravel()[P], length)
        rb = Kb @ xb
        zeta = (cuff.Z @ w + alpha * cuff.z_pre).reshape(n, 6)
        if nc == 1:
            x = np.column_stack([xb, (fe.tangential_map @ xb).reshape(m, 2)])
            r = np.column_stack([rb, np.zeros((m, 2))])
        else:
            x, r = xb.reshape(m, 3), rb.reshape(m, 3)
        # plate points at the nodes; the deepest plate each node can touch
        pp = np.einsum("iejk,ek->iej", pm, zeta)                     # (m, n, 3)
        depth = np.where(inc, pp[:, :, 0], -np.inf)
        deep = np.argmax(depth, axis=1)
        tol_f = SET_TOL * max(np.abs(r).max(), 1e-300)
        tol_x = SET_TOL * max(np.abs(x).max(), np.abs(pp).max(), 1e-300)
        pen = depth[ar, deep] - x[:, 0]
        release = contact & (r[:, 0] < -tol_f)
        touch = ~contact & (pen > tol_x)
        move = contact & ~release & (depth[ar, deep] > depth[ar, np.maximum(plate, 0)] + tol_x)
        lost |= release
        new_contact = (contact & ~release) | touch
        new_plate = np.where(touch | move, deep, plate)
        new_plate[~new_contact] = -1
        new_slip = np.zeros(m, bool)
        new_law = law.copy()
        settled = True
        if friction:
            # sigma = lambda_t - rho (slip in the step): outside mu lambda_n the node slides
            keep = contact & ~release & ~move & ~fresh
            d = x[:, 1:] - np.einsum("ijk,ik->ij", own_map, zeta[np.maximum(plate, 0)]) - anchor
            sig = r[:, 1:] - rho[:, None] * d
            sn = np.linalg.norm(sig, axis=1)
            new_slip = keep & (sn > mu * r[:, 0] + tol_f)
            k = np.flatnonzero(new_slip)
            new_law[k, :2] = sig[k] / sn[k, None]
            new_law[k, 2] = mu * np.maximum(r[k, 0], 0.0) / sn[k]
            # the slip law itself at this iterate (the linear solve met its linearisation)
            if np.any(slip[k]):
                kk = k[slip[k]]
                err = r[kk, 1:] - mu * r[kk, :1] * new_law[kk, :2]
                settled = float(np.max(np.abs(err))) <= 10 * tol_f
        same = (np.array_equal(new_contact, contact) and np.array_equal(new_plate, plate)
                and np.array_equal(new_slip, slip))
        contact, plate, slip, law = new_contact, new_plate, new_slip, new_law
        singular += not ok
        if singular >= 5:
            break
        if same and settled:
            if not ok:
                break
            return _solution(fe, cuff, W, alpha, w, x, r, zeta, contact, plate, slip,
                             law, it)
    if singular:
        raise ConvergenceError("contact FE: no equilibrium: the touching nodes cannot hold "
                               "the wrench (gross slip, or a rigid motion of the cuff no "
                               "contact resists, e.g. along or about the arm without friction)")
    raise ConvergenceError(f"contact FE: the contact set did not settle in {max_iterations} "
                           "solves")


def _solution(fe, cuff, W, alpha, w, x, r, zeta, contact, plate, slip, law, it):
    m, n = len(fe.points), fe.geometry.n
    rl = r.ravel()
    Gam = np.zeros((m, n, 3, 6))
    Gam[contact, plate[contact]] = fe.plate_map[contact, plate[contact]]
    plate_f = np.einsum("iekl,ik->el", Gam, r)
    f_cart = np.einsum("ikj,ik->ij", fe.frames, r)
    wrench = np.asarray(W, float) + alpha * cuff.W_pre
    res = np.concatenate([f_cart.sum(0), np.cross(fe.points, f_cart).sum(0)]) - wrench
    return ContactSolution(u=w[:6].copy(), wrench=wrench, normal_forces=fe.normal_output @ rl,
                           patch_forces=(fe.patch_output @ rl).reshape(n, 6),
                           plate_forces=plate_f, reactions=r, displacements=x, plates=zeta,
                           contact=contact, slip=slip, plate=plate, residual=res,
                           iterations=it, _law=law)


def _initial_state(fe) -> ContactSolution:
    """The unloaded cuff: every node touching its first plate, nothing moved."""
    m, n, z = len(fe.points), fe.geometry.n, np.zeros
    return ContactSolution(z(6), z(6), z(n), z((n, 6)), z((n, 6)), z((m, 3)), z((m, 3)),
                           z((n, 6)), np.ones(m, bool), np.zeros(m, bool),
                           np.argmax(fe.incidence, axis=1), z(6), 0, z((m, 3)))


def _check_mu(mu) -> float:
    mu = float(mu)
    if not mu >= 0:
        raise ModelInputError(f"friction_coefficient: expected >= 0 (inf: bonded), got {mu!r}",
                              "friction_coefficient")
    return mu


def solve_contact_path(fe: ContactFE, model, wrenches, *, friction_coefficient: float = 0.0,
                       preload_steps: int = 4, state: ContactSolution | None = None,
                       max_iterations: int = 200) -> list:
    """Solve the contact FE along a loading path, the contact state carried row to row.

    Parameters
    ----------
    fe : ContactFE
    model : CoupledModel
        The coupled model whose cuff (T, k_cuff, shear_ratio) and strap preload (delta,
        W_pre) the reference takes (6 dofs per patch, same geometry).
    wrenches : array_like, shape (k, 6) or (6,)
        The wrench W on the cuff at each row, about the cuff origin, cuff frame [N, N*m].
    friction_coefficient : float, optional
        mu [-]: 0 frictionless (rows independent), > 0 Coulomb, inf bonded.
    preload_steps : int, optional
        Without ``state``: steps of the strap preload (delta, W_pre scaled 1/k .. 1) from
        the unloaded cuff, at zero wrench, before the first row (none for mu = 0).
    state : ContactSolution, optional
        The state to start from (the last row of an earlier path, same fe, model, mu).
    max_iterations : int, optional
        Linear solves allowed per row.

    Returns
    -------
    list of ContactSolution
        One per row.

    Raises
    ------
    ConvergenceError
        No equilibrium (gross slip, or a rigid motion of the cuff no contact resists) or
        a contact set that did not settle.
    ModelInputError
        A model that is not a 6-dof coupled model of this geometry, or mu < 0.
    """
    mu = _check_mu(friction_coefficient)
    cuff = _cuff(model, fe.geometry.n)
    W = np.atleast_2d(np.asarray(wrenches, float))
    if W.shape[1] != 6 or not np.isfinite(W).all():
        raise ValueError(f"wrenches: expected finite rows of 6, got shape {W.shape}")
    if state is None:
        state = _initial_state(fe)
        k = 0 if mu == 0 else max(1, int(preload_steps))
        for j in range(1, k + 1):
            state = _step(fe, cuff, mu, np.zeros(6), j / k, state, max_iterations)
    out = []
    for i, row in enumerate(W):
        try:
            state = _step(fe, cuff, mu, row, 1.0, state, max_iterations)
        except ConvergenceError as exc:
            raise ConvergenceError(f"{exc.message} (row {i} of the path)") from None
        out.append(state)
    return out


def solve_contact(fe: ContactFE, model, wrench, *, friction_coefficient: float = 0.0,
                  steps: int = 8, preload_steps: int = 4,
                  max_iterations: int = 200) -> ContactSolution:
    """The contact FE under one wrench, reached from the preloaded cuff in equal steps.

    Parameters
    ----------
    fe, model, friction_coefficient, preload_steps, max_iterations
        As :func:`solve_contact_path`.
    wrench : array_like, shape (6,)
        W on the cuff about the cuff origin, cuff frame [N, N*m].
    steps : int, optional
        Load increments from zero wrench to W (1 for mu = 0: no history).

    Returns
    -------
    ContactSolution
        The last row; errors as :func:`solve_contact_path`.
    """
    mu = _check_mu(friction_coefficient)
    k = 1 if mu == 0 else max(1, int(steps))
    path = np.outer(np.arange(1, k + 1) / k, np.asarray(wrench, float))
    return solve_contact_path(fe, model, path, friction_coefficient=mu,
                              preload_steps=preload_steps, max_iterations=max_iterations)[-1]
