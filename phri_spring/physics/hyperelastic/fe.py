"""Large-deformation hyperelastic reference FE of the tissue under a rigid, bonded cuff.

The reference for the reduced nonlinear coupled model. The linear FE's mesh
(:func:`~phri_spring.physics.continuum.mesh.mesh_lines`: triquadratic hexahedra between the bone
r = R - t and the skin r = R, seam closed) solved with felupe at finite strain:

* material: felupe ``NeoHooke(mu, bulk)``, psi = mu/2 (J^-2/3 tr C - 3) + K/2 (J - 1)^2,
  mu = E / (2 (1 + nu)), K = E / (3 (1 - 2 nu)): small-strain limit (E, nu);
  ``law="linear"``: felupe ``LinearElastic(E, nu)``, for cross-checks;
* bone and both end faces of the tube clamped (the linear FE's ``ends='fixed'``);
* every skin node under a plate (:func:`~phri_spring.physics.continuum.mesh.patch_plates`) moves
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
from dataclasses import dataclass

import numpy as np
import scipy.sparse.linalg as spla

from ...errors import ConvergenceError
from ..continuum.coupled import patch_frames
from .mesh import HYPER_EXTRA_HINT, LAWS, HyperCuff, build_hyper_cuff
from ..cuff.geometry import skew

__all__ = ["HYPER_EXTRA_HINT", "LAWS", "HyperCuff", "HyperSolution", "build_hyper_cuff",
           "patch_forces", "solve_wrench", "preload_offsets", "rotation_matrix"]

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


def preload_offsets(coupled_model) -> np.ndarray:
    """The linear coupled model's preload offsets as plate motions (n, 6), local axes.

    ``delta`` of :func:`~phri_spring.physics.continuum.coupled.build_coupled_model` with a rigid
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
