"""The coupled tissue model: the arm as a continuum condensed onto the sensor patches.

docs/model.md section 10. The spring model's tissue springs are independent:
pressing one element moves no other. Here the tissue is a linear elastic layer
bonded to the bone, condensed onto the n patches of the cuff: K_t (d n x d n,
d = 3 translations or 6 = translations and rotations per patch, SI units) maps
the patches' rigid motions q to the generalized forces the patches apply to
the skin, with its inverse, the surface compliance C_t = K_t^-1, coupling every
patch to every other. Each patch is joined to the rigid cuff through its cuff
spring (normal 1/k_c,e, tangential 1/(eta k_c,e), rotations rigid), in series
with the tissue; normal contact is compression-only (a patch can lift off),
tangential contact is bonded, as in the spring model.

With P the patch forces (local axes: normal, axial, circumferential, then
rotations), C = C_t + C_c the total compliance, T the map from the cuff
displacement u (6,) to the patches' rigid motions and delta the preload
offset, the equilibrium is the strictly convex quadratic program

    minimise  1/2 P^T C P - delta^T P   subject to  T^T P = W + W_pre,  P_n,e >= 0,

whose multiplier of the six equalities is u. For a contact set S (the patches
pressing), the tied dofs D (every dof but the normals of patches outside S)
satisfy C_DD P_D = T_D u + delta_D, so u solves the 6x6 system
H_S u = W + W_pre - T_D^T C_DD^-1 delta_D with H_S = T_D^T C_DD^-1 T_D, and
the indicator of the shared active-set kernel (docs/model.md section 9) is the
normal force f_e for e in S and the penetration (T u + delta)_n,e - (C_t P)_n,e
for e outside S. With a diagonal K_t (normal k_t,e, tangential eta k_t,e)
this is exactly the spring model. The safeguard solves the same program
reduced to the normal forces, a bound-constrained strictly convex quadratic
program, by the Lawson-Hanson non-negative least-squares method (finite).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from operator import attrgetter
from typing import NamedTuple

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from scipy.optimize import nnls

from ..contact.active_set import SET_RTOL, ContactSystem, FactorCache, key_groups, set_keys
from ...errors import ModelInputError
from ..cuff.geometry import CuffGeometry, patch_frames, rigid_body_map  # noqa: F401 - re-exported
from ..springs.model import OnGeometry, check_friction, field_unit
from ..cuff.preload import strap_preload
from .reading import PatchReading, parts_sum
from ..springs.stiffness import shear_ratio_from_poisson

__all__ = ["CoupledModel", "CoupledSystem", "SetFactors", "build_coupled_model", "patch_frames",
           "rigid_patch_map", "LIFT_OFF_MU"]

#: Coulomb coefficient of the coupled arm's interface without ``interface.friction_coefficient``
#: (docs/model.md section 10.2): a touching patch's tie holds while its tangential force is
#: within LIFT_OFF_MU times its normal force, so it is bonded except as it lets go, and a
#: patch out of contact carries nothing. Large against any skin-liner friction (at most
#: about 1 dry, section 12.1) so that pressing patches do not slide, small enough that the
#: sliding phase of a patch letting go spans more than round-off of its normal force.
LIFT_OFF_MU = 10.0


def rigid_patch_map(geometry: CuffGeometry, dofs: int) -> np.ndarray:
    """T (n*dofs, 6): patch e's rigid motion from the cuff displacement u = (t, w).

    Translation of the patch centre t + w x p_e, and (dofs = 6) its rotation w,
    in the cuff frame's axes (:func:`~phri_spring.physics.cuff.geometry.rigid_body_map`).
    """
    return rigid_body_map(geometry.points, rotations=dofs == 6).reshape(geometry.n * dofs, 6)


def _local_rotation(geometry: CuffGeometry, dofs: int) -> np.ndarray:
    """Block-diagonal R (n*dofs, n*dofs) turning cuff-frame patch dofs into local ones."""
    frames = patch_frames(geometry)
    n = geometry.n
    R = np.zeros((n * dofs, n * dofs))
    for e in range(n):
        s = e * dofs
        R[s:s + 3, s:s + 3] = frames[e]
        if dofs == 6:
            R[s + 3:s + 6, s + 3:s + 6] = frames[e]
    return R



@dataclass(frozen=True, eq=False)
class CoupledModel(OnGeometry):
    """A cuff on a continuum tissue layer, ready to solve (docs/model.md section 10).

    Attributes
    ----------
    geometry : CuffGeometry
    arm : str
        ``coupled``.
    K_t : ndarray, shape (n*d, n*d)
        Condensed tissue stiffness on the patches' rigid motions, cuff-frame axes,
        rotations about each patch centre [N/m, N/rad; N*m/m, N*m/rad].
    dofs : int
        d, 3 (translations) or 6 (and rotations) per patch.
    k_cuff : ndarray, shape (n,)
        Cuff stiffness k_c,e [N/m] (inf: a rigid cuff).
    shear_ratio : float
        eta, tangential over normal cuff stiffness [-].
    delta : ndarray, shape (n*d,)
        Preload offset of the tied dofs, local axes [m, rad].
    f0 : ndarray, shape (n,)
        Normal patch forces at zero wrench (hoop preload) [N].
    W_pre : ndarray, shape (6,)
        Constant wrench of the strap on the cuff [N, N*m].
    T : ndarray, shape (n*d, 6)
        Cuff displacement -> patch motions, local axes [-, m].
    C : ndarray, shape (n*d, n*d)
        Total compliance C_t + C_c, local axes [m/N, ...].
    C_t : ndarray, shape (n*d, n*d)
        Tissue compliance K_t^-1, local axes.
    N_out : ndarray, shape (n, n*d), or None
        Normal-force output, local axes: the normal force a patch reports is
        N_out q for the skin's patch motions q, the integral over the patch of the
        normal traction (from the built-in FE; None: the patch force along n_e).
    """

    geometry: CuffGeometry
    arm: str
    K_t: np.ndarray = field(metadata=field_unit("[[N/m, N/rad], [N*m/m, N*m/rad]]",
                                           "docs/model.md section 10"))
    dofs: int
    k_cuff: np.ndarray = field(metadata=field_unit("N/m", "docs/model.md section 2"))
    shear_ratio: float = field(metadata=field_unit("-", "docs/model.md section 2"))
    delta: np.ndarray = field(metadata=field_unit("[m, rad]", "docs/model.md section 10"))
    f0: np.ndarray = field(metadata=field_unit("N", "docs/model.md section 3"))
    W_pre: np.ndarray = field(metadata=field_unit("[N, N, N, N*m, N*m, N*m]",
                                                   "docs/model.md section 3"))
    T: np.ndarray = field(repr=False, metadata=field_unit("[-, m]", "docs/model.md section 10"))
    C: np.ndarray = field(repr=False, metadata=field_unit("[m/N, rad/N; m/(N*m), rad/(N*m)]",
                                                     "docs/model.md section 10"))
    C_t: np.ndarray = field(repr=False, metadata=field_unit("[m/N, rad/N; m/(N*m), rad/(N*m)]",
                                                       "docs/model.md section 10"))
    strap_model: str = "hoop"
    pain_threshold_kpa: float = field(default=120.0,
                                      metadata=field_unit("kPa", "docs/model.md section 4"))
    friction_coefficient: float | None = field(default=None, metadata=field_unit(
        "-", "docs/model.md section 12"))
    N_out: np.ndarray | None = field(default=None, repr=False,
                                     metadata=field_unit("[N/m, N/rad]",
                                                          "docs/model.md section 10"))
    #: what each patch's sensor reads (the compressive part of its normal traction,
    #: :mod:`~phri_spring.physics.continuum.reading`); None: ``N_out`` C_t P, clipped at 0
    reading: PatchReading | None = field(default=None, repr=False,
                                         metadata=field_unit("[-]", "docs/model.md section 10.6"))
    #: without ``friction_coefficient``: a patch out of contact is released (the default,
    #: :data:`LIFT_OFF_MU`); False: every patch's ties stay bonded (the program of 10.3)
    lift_off: bool = True
    inv_area_kpa: np.ndarray = field(init=False, repr=False,
                                     metadata=field_unit("1/(1000 N)", "derived"))
    normal_dofs: np.ndarray = field(init=False, repr=False, metadata=field_unit("-", "derived"))

    def __post_init__(self):
        object.__setattr__(self, "inv_area_kpa", 1.0 / (1000.0 * self.geometry.areas))
        object.__setattr__(self, "normal_dofs", np.arange(self.geometry.n) * self.dofs)

    @property
    def interface_mu(self) -> float | None:
        """The Coulomb coefficient the interface runs with: ``friction_coefficient``, else
        :data:`LIFT_OFF_MU` (bonded while touching, released when lifted; section 10.2);
        None with ``lift_off`` False (bonded ties everywhere, solved sample by sample)."""
        if self.friction_coefficient is not None:
            return self.friction_coefficient
        return LIFT_OFF_MU if self.lift_off else None

    def reported_normal(self, P, touching) -> np.ndarray:
        """The normal force each patch reports (m, n) [N] for patch forces P (m, n d), local
        axes, and ``touching`` (m, n) bool: with the built-in FE's ``reading``, the
        compressive part of the normal traction integrated over each touching patch (what an
        FSR reads; section 10.6); else ``N_out`` C_t P (never below 0) or, without an output
        map, P along n_e; 0 for a patch out of contact."""
        P = np.atleast_2d(P)
        if self.reading is not None:
            f = self.reading(P)
        elif self.N_out is None:
            f = np.maximum(P[:, self.normal_dofs], 0.0)
        else:
            f = np.maximum(P @ (self.N_out @ self.C_t).T, 0.0)
        f[~np.asarray(touching, dtype=bool)] = 0.0
        return f

    def contact_system(self, cache: FactorCache | None = None) -> "CoupledSystem":
        """The active-set kernel's system for this model (docs/model.md section 9)."""
        return CoupledSystem(self, cache)

    def tangent_stiffness(self, u, contact=None) -> np.ndarray:
        """H_S (6, 6) of the contact set ``contact`` (n,) bool, or of full contact if None."""
        S = np.ones(self.n, dtype=bool) if contact is None else np.asarray(contact, dtype=bool)
        system = self.contact_system(FactorCache(0))
        Mt = system.factors(set_keys(S[None])[0], S).solve_map
        H = np.linalg.inv(Mt.T)
        return 0.5 * (H + H.T)

    def patch_forces(self, u, contact) -> np.ndarray:
        """Patch forces P (m, n, d) in local axes [N, N*m]: normal, axial, circumferential, ...

        u (m, 6) solutions and ``contact`` (m, n) their contact sets.
        """
        u = np.atleast_2d(np.asarray(u, dtype=float))
        S = np.atleast_2d(np.asarray(contact, dtype=bool))
        out = self.contact_system(FactorCache(64)).tied_forces(u, S)
        return out.reshape(len(u), self.n, self.dofs)

    def shear_components(self, u, contact) -> np.ndarray:
        """Tangential patch forces on the arm, (m, n, 2) [N]: axial, circumferential."""
        return self.patch_forces(u, contact)[..., 1:3]


#: rows per chunk when per-row set maps are gathered (bounds the (rows, 6, n) temporary)
_GATHER_ROWS = 4096


class SetFactors(NamedTuple):
    """What :class:`CoupledSystem` caches per contact set S (m the dofs tied in S).

    Each ``*_map``, ``*_offset`` pair is an affine map of the cuff displacement u (6,)
    [m, rad], applied to rows of u as ``u @ map + offset``.

    Attributes
    ----------
    solve_map : ndarray, shape (6, 6)
        H_S^-1 transposed: u = (r + solve_offset) @ solve_map solves H_S u = r + c_S
        [m/N, m/(N*m); rad/N, rad/(N*m)].
    solve_offset : ndarray, shape (6,)
        c_S = -T_D^T C_DD^-1 delta_D [N, N*m].
    indicator_map : ndarray, shape (6, n)
    indicator_offset : ndarray, shape (n,)
        The indicator q = u @ indicator_map + indicator_offset: normal force of the
        patches in S [N], penetration of the others [m].
    tied : ndarray of int, shape (m,)
        D, the tied dofs: every dof but the normals of the patches outside S.
    force_map : ndarray, shape (m, 6)
        G T_D = C_DD^-1 T_D [N/m, N/rad; N*m/m, N*m/rad].
    force_offset : ndarray, shape (m,)
        G delta_D = C_DD^-1 delta_D [N, N*m]; the tied dofs' forces are
        u @ force_map.T + force_offset.
    abs_indicator_map : ndarray, shape (6, n)
    abs_indicator_offset : ndarray, shape (n,)
        ``|indicator_map|``, ``|indicator_offset|``: the round-off scale of the indicator.
    report_map : ndarray, shape (6, n)
    report_offset : ndarray, shape (n,)
        The reported normal patch forces u @ report_map + report_offset [N] (0 outside S).
    """

    solve_map: np.ndarray
    solve_offset: np.ndarray
    indicator_map: np.ndarray
    indicator_offset: np.ndarray
    tied: np.ndarray
    force_map: np.ndarray
    force_offset: np.ndarray
    abs_indicator_map: np.ndarray
    abs_indicator_offset: np.ndarray
    report_map: np.ndarray
    report_offset: np.ndarray


#: the (map, offset) pairs of :class:`SetFactors` that :meth:`CoupledSystem._affine` applies
_AFFINE_PAIRS = {name: attrgetter(f"{name}_map", f"{name}_offset")
                 for name in ("solve", "indicator", "abs_indicator", "report")}


class CoupledSystem(ContactSystem):
    """The coupled model as a :class:`~phri_spring.physics.contact.active_set.ContactSystem`.

    Per contact set S it caches a :class:`SetFactors`: the solve u = (r + c) @ Mt,
    the indicator q (normal force of the patches in S, penetration of the others),
    the tied dofs D and the maps from u to their forces and to the reported forces.
    """

    sets_follow_indicator = False

    def __init__(self, model: CoupledModel, cache: FactorCache | None = None):
        self.model = model
        self.n = model.n
        self.cache = FactorCache() if cache is None else cache
        self._reduced = None

    def factors(self, key, S_row: np.ndarray) -> SetFactors:
        """The cached :class:`SetFactors` of contact set ``S_row`` (n,) bool, keyed ``key``."""
        hk = key.item() if isinstance(key, np.generic) else key
        hit = self.cache.get(hk)
        if hit is None:
            hit = self._set_data(np.asarray(S_row, dtype=bool))
            self.cache.put(hk, hit)
        return hit

    def _set_data(self, S_row):
        m = self.model
        N = m.normal_dofs
        tied = np.ones(m.n * m.dofs, dtype=bool)
        tied[N[~S_row]] = False
        D = np.flatnonzero(tied)
        cf = cho_factor(m.C[np.ix_(D, D)])
        TD = m.T[D]
        GT = cho_solve(cf, TD)                          # C_DD^-1 T_D
        Gd = cho_solve(cf, m.delta[D])                  # C_DD^-1 delta_D
        H = TD.T @ GT
        H = 0.5 * (H + H.T)
        Mt = np.ascontiguousarray(np.linalg.inv(H).T)
        c = -(TD.T @ Gd)
        Q = np.empty((m.n, 6))
        q0 = np.empty(m.n)
        pos = np.searchsorted(D, N[S_row])             # where the pressing normals sit in D
        Q[S_row], q0[S_row] = GT[pos], Gd[pos]
        free = N[~S_row]
        CtND = m.C_t[np.ix_(free, D)]
        Q[~S_row] = m.T[free] - CtND @ GT
        q0[~S_row] = m.delta[free] - CtND @ Gd
        Qt = np.ascontiguousarray(Q.T)
        if m.N_out is None:  # reported normal force = the patch force along n_e
            Ft, f0 = Qt * S_row, q0 * S_row
        else:                # the normal traction integrated over each pressing patch
            NC = m.N_out @ m.C_t[:, D]
            Ft = np.ascontiguousarray((NC @ GT).T) * S_row
            f0 = (NC @ Gd) * S_row
        return SetFactors(solve_map=Mt, solve_offset=c, indicator_map=Qt, indicator_offset=q0,
                          tied=D, force_map=GT, force_offset=Gd, abs_indicator_map=np.abs(Qt),
                          abs_indicator_offset=np.abs(q0), report_map=Ft, report_offset=f0)

    def _affine(self, x, S, keys, pair: str, out=None, add_first: bool = False):
        """x @ A_S + b_S for every row, with (A_S, b_S) the :class:`SetFactors` pair ``pair``
        (``'solve'``, ``'indicator'``, ``'abs_indicator'`` or ``'report'``: its ``*_map``,
        ``*_offset``) of each row's contact set (``add_first``: (x + b_S) @ A_S instead).

        Rows sharing the block's one set take one product; otherwise the maps of the sets
        met are gathered per row and applied as a stack of small products, in chunks.
        """
        m = len(x)
        if m == 0:
            return np.empty((0, 0)) if out is None else out
        get = _AFFINE_PAIRS[pair]
        if m == 1 or np.all(keys == keys[0]):
            A, b = get(self.factors(keys[0], S[0]))
            if add_first:
                return np.matmul(x + b, A, out=out)
            res = np.matmul(x, A, out=out)
            res += b
            return res
        uniq, first, inv = np.unique(keys, return_index=True, return_inverse=True)
        data = [get(self.factors(k, S[f])) for k, f in zip(uniq, first)]
        A = np.stack([d[0] for d in data])
        b = np.stack([d[1] for d in data])
        res = np.empty((m, A.shape[2])) if out is None else out
        for s0 in range(0, m, _GATHER_ROWS):
            sl = slice(s0, min(m, s0 + _GATHER_ROWS))
            g = inv[sl]
            if add_first:
                res[sl] = np.matmul((x[sl] + b[g])[:, None, :], A[g])[:, 0, :]
            else:
                res[sl] = np.matmul(x[sl, None, :], A[g])[:, 0, :] + b[g]
        return res

    def solve_sets(self, keys, S, r):
        return self._affine(r, S, keys, "solve", add_first=True)

    def indicator(self, u, S, keys=None, out=None):
        if keys is None:
            keys = set_keys(S)
        return self._affine(u, S, keys, "indicator", out=out)

    def consistent(self, S, q, u):
        tol = self._affine(np.abs(np.atleast_2d(u)), S, set_keys(S), "abs_indicator")
        tol *= SET_RTOL
        wrong = (S & (q < -tol)) | (~S & (q > tol))
        return ~wrong.any(axis=-1)

    def forces(self, q, out=None, u=None):
        """Reported normal patch forces [N] (m, n) at the solution (u, its indicator q).

        Without an output map, the indicator's positive part (the patch force along
        n_e in S, <= 0 outside). With one (``N_out``), the normal traction integrated
        over each pressing patch, 0 for a patch that has lifted off, and never below 0.
        """
        if self.model.N_out is None:
            return np.maximum(q, 0.0, out=out)
        S = q > 0
        u = np.atleast_2d(u)
        if self.model.reading is None:
            f = np.maximum(self._affine(u, S, set_keys(S), "report"), 0.0)
        else:
            f = self.model.reported_normal(self.tied_forces(u, S), S)
        if out is None:
            return f
        out[...] = f
        return out

    def tied_forces(self, u, S) -> np.ndarray:
        """Patch forces P (m, n d), local axes [N, N*m], of solutions u (m, 6) with contact
        sets S (m, n): the tied dofs' forces, 0 on the normals of patches outside S."""
        P = np.zeros((len(u), self.model.n * self.model.dofs))
        for key, idx in key_groups(set_keys(S)):
            f = self.factors(key, S[idx[0]])
            P[np.ix_(idx, f.tied)] = u[idx] @ f.force_map.T + f.force_offset
        return P

    # ------------------------------------------------------------------ safeguard
    def _reduced_problem(self):
        """The program reduced to the normal forces f: gradient M f + m0 + Mr r (= -penetration)."""
        if self._reduced is None:
            mdl = self.model
            N = mdl.normal_dofs
            Tn = np.setdiff1d(np.arange(mdl.n * mdl.dofs), N)
            C, T, d = mdl.C, mdl.T, mdl.delta
            cf = cho_factor(C[np.ix_(Tn, Tn)])
            XT = cho_solve(cf, T[Tn])                               # C_TT^-1 T_T
            Xd = cho_solve(cf, d[Tn])
            XC = cho_solve(cf, C[np.ix_(Tn, N)])                    # C_TT^-1 C_TN
            H = T[Tn].T @ XT
            Hinv = np.linalg.inv(0.5 * (H + H.T))
            # u = Hinv (r - T_T^T Xd + (T_T^T XC - T_N^T) f)
            Au = Hinv @ (T[Tn].T @ XC - T[N].T)                     # (6, n)
            bu_r, bu_0 = Hinv, -Hinv @ (T[Tn].T @ Xd)
            # P_T = Xd + XT u - XC f
            # gradient g(f) = (C P - delta - T u)_N = C_NN f + C_NT P_T - d_N - T_N u
            CNT = C[np.ix_(N, Tn)]
            M = C[np.ix_(N, N)] - CNT @ XC + (CNT @ XT - T[N]) @ Au
            Mr = (CNT @ XT - T[N]) @ bu_r
            m0 = CNT @ Xd - d[N] + (CNT @ XT - T[N]) @ bu_0
            M = 0.5 * (M + M.T)
            L = np.linalg.cholesky(M)
            self._reduced = (L, m0, Mr)
        return self._reduced

    def safeguard(self, r, u, budget):
        """Solve one sample's reduced program by non-negative least squares, then polish.

        The reduced program min_{f >= 0} 1/2 f^T M f + m^T f is solved as
        min ||L^T f + L^-1 m|| (M = L L^T) by scipy's Lawson-Hanson NNLS (finite
        termination); its support is the contact set, solved exactly once more.
        """
        if budget < 1:
            return u, None, 0, False
        L, m0, Mr = self._reduced_problem()
        m = m0 + Mr @ r
        rhs = -solve_triangular(L, m, lower=True)
        f, _ = nnls(L.T, rhs, maxiter=50 * self.n)
        S = f > 0
        key = set_keys(S[None])
        u_new = self.solve_sets(key, S[None], r[None])[0]
        q = self.indicator(u_new[None], S[None], key)
        ok = bool(self.consistent(S[None], q, u_new[None])[0])
        return u_new, S, 1, ok


def build_coupled_model(geometry: CuffGeometry, K_surface, k_cuff, *, poisson_ratio: float = 0.45,
                        shear_ratio: float | None = None, strap_tension: float = 15.0,
                        strap_model: str = "hoop", handle_angles_deg=None,
                        handle_axial_position: float | None = None,
                        pain_threshold_kpa: float = 120.0, normal_output=None,
                        friction_coefficient: float | None = None,
                        lift_off: bool = True, normal_parts=None) -> CoupledModel:
    """Assemble the coupled model of docs/model.md section 10.

    Parameters
    ----------
    geometry : CuffGeometry
    K_surface : array_like, shape (3n, 3n) or (6n, 6n)
        Condensed tissue stiffness on the patches (patch-major, per patch
        t_x, t_y, t_z [, w_x, w_y, w_z] in the cuff frame's axes, rotations about
        the patch centre) [N/m, N/rad; N*m/m, N*m/rad]; symmetric positive definite.
    k_cuff : array_like, shape (n,)
        Cuff stiffness k_c,e [N/m]; inf for a rigid cuff.
    poisson_ratio, shear_ratio : float
        eta = k_s / k for the cuff's tangential springs; default 1 / (2 (1 + nu)).
    strap_tension, strap_model, handle_angles_deg, handle_axial_position
        As :func:`phri_spring.physics.springs.model.build_model`. With the hoop strap the
        patches carry, at zero wrench, the normal forces f0 of the spring model.
    pain_threshold_kpa : float
    normal_output : array_like, shape (n, 3n) or (n, 6n), optional
        N: the normal force a patch reports, N q [N], for the skin's patch motions q
        (same dof layout as K_surface), e.g. the integral of the normal traction over
        the patch (the built-in FE's). Default: the patch force along n_e.
    normal_parts : (ndarray (k, 3n) or (k, 6n), ndarray of int (k,)), optional
        ``normal_output`` split into parts (the built-in FE's skin nodes), same dof layout,
        with the patch of each part, ascending: a patch then reports the sum of its parts'
        positive values, the compressive part of its normal traction (what an FSR reads;
        :mod:`~phri_spring.physics.continuum.reading`). ``normal_output`` defaults to
        their sum per patch.
    friction_coefficient : float, optional
        Coulomb coefficient mu >= 0 [-] (docs/model.md section 12); None: a touching patch
        bonded, one out of contact released (``lift_off``, :data:`LIFT_OFF_MU`).
    lift_off : bool
        False (without ``friction_coefficient``): every patch's tangential and rotational
        ties stay bonded, lifted or not (the program of docs/model.md 10.3, solved sample by
        sample; the coupled arm's default before lift-off released).

    Raises
    ------
    ValueError
        For a K_surface of the wrong shape, not symmetric positive definite or
        not finite, a cuff stiffness that is not positive, or a geometry whose
        tangential ties cannot hold the cuff.
    """
    n = geometry.n
    K = np.asarray(K_surface, dtype=float)
    if K.ndim != 2 or K.shape[0] != K.shape[1] or K.shape[0] not in (3 * n, 6 * n):
        raise ModelInputError(f"surface stiffness: expected shape ({3 * n}, {3 * n}) or "
                              f"({6 * n}, {6 * n}) for {n} patches, got {K.shape}",
                              "surface_stiffness")
    if not np.isfinite(K).all():
        raise ModelInputError("surface stiffness: expected finite numbers", "surface_stiffness")
    scale = np.abs(K).max()
    if not np.allclose(K, K.T, rtol=0, atol=1e-8 * scale):
        raise ModelInputError("surface stiffness: expected a symmetric matrix",
                              "surface_stiffness")
    K = 0.5 * (K + K.T)
    try:
        cK = cho_factor(K)
    except np.linalg.LinAlgError:
        raise ModelInputError("surface stiffness: expected a positive definite matrix",
                              "surface_stiffness") from None
    dofs = K.shape[0] // n
    k_c = np.broadcast_to(np.asarray(k_cuff, dtype=float), (n,)).copy()
    if not np.all(k_c > 0):
        raise ModelInputError("cuff stiffness: expected > 0 (inf for a rigid cuff)", "stiffness")
    eta = shear_ratio_from_poisson(poisson_ratio) if shear_ratio is None else float(shear_ratio)
    if not eta > 0:
        raise ModelInputError(f"shear_ratio: expected > 0, got {eta}", "shear_ratio")

    R = _local_rotation(geometry, dofs)
    C_t_global = cho_solve(cK, np.eye(K.shape[0]))
    C_t = R @ C_t_global @ R.T
    C_t = 0.5 * (C_t + C_t.T)
    cc = np.zeros((n, dofs))
    with np.errstate(divide="ignore"):
        cc[:, 0] = 1.0 / k_c
        cc[:, 1] = cc[:, 2] = 1.0 / (eta * k_c)
    C = C_t + np.diag(cc.ravel())
    T = R @ rigid_patch_map(geometry, dofs)

    N_out = None
    if normal_parts is not None and normal_output is None:
        rows, owner = normal_parts
        normal_output = parts_sum(np.asarray(rows, dtype=float), np.asarray(owner), n)
    if normal_output is not None:
        N_g = np.asarray(normal_output, dtype=float)
        if N_g.shape != (n, n * dofs) or not np.isfinite(N_g).all():
            raise ModelInputError(f"normal output: expected finite numbers of shape "
                                  f"({n}, {n * dofs}), got {N_g.shape}", "normal_output")
        N_out = N_g @ R.T
    reading = None
    if normal_parts is not None:
        rows = np.asarray(normal_parts[0], dtype=float)
        if rows.ndim != 2 or rows.shape[1] != n * dofs or not np.isfinite(rows).all():
            raise ModelInputError(f"normal output parts: expected finite numbers of shape "
                                  f"(k, {n * dofs})", "normal_output")
        try:
            reading = PatchReading.build(rows @ R.T, normal_parts[1], C_t, n)
        except ValueError as exc:
            raise ModelInputError(str(exc), "normal_output") from None

    f0, W_handles = strap_preload(geometry, strap_tension, strap_model, handle_angles_deg,
                                  handle_axial_position)
    if W_handles is None:  # hoop
        P0 = np.zeros(n * dofs)
        normals = np.arange(n) * dofs
        P0[normals] = f0
        if N_out is not None and strap_tension > 0:
            # normal patch forces p such that the patches *report* f0 at zero wrench; a
            # pulling p would mean an output map that does not fit its stiffness (a patch
            # pressed alone reporting a pull), and the preload could not be the hoop's
            try:
                p = np.linalg.solve((N_out @ C_t)[:, normals], f0)
            except np.linalg.LinAlgError:
                p = np.full(n, np.nan)
            if not np.all(p > 0):
                bad = int(np.argmax(~(p > 0)))
                raise ModelInputError(f"normal output: with this map the strap's hoop preload "
                                      f"cannot be carried by pressing patches (patch "
                                      f"{geometry.labels[bad]} would have to pull to report "
                                      f"its {f0[bad]:.3g} N); check that the output map "
                                      f"belongs to the surface stiffness", "normal_output")
            P0[normals] = p
        delta = C @ P0
        W_pre = T.T @ P0
    else:
        delta = np.zeros(n * dofs)
        W_pre = W_handles

    model = CoupledModel(geometry=geometry, arm="coupled", K_t=K, dofs=dofs, k_cuff=k_c,
                         shear_ratio=eta, delta=delta, f0=f0, W_pre=W_pre, T=T, C=C, C_t=C_t,
                         strap_model=strap_model, pain_threshold_kpa=float(pain_threshold_kpa),
                         N_out=N_out, friction_coefficient=check_friction(friction_coefficient),
                         lift_off=bool(lift_off), reading=reading)
    # every patch lifted off: the tangential ties alone must hold the cuff
    try:
        model.contact_system(FactorCache(0))._reduced_problem()
    except np.linalg.LinAlgError:
        raise ModelInputError("the tangential ties cannot hold the cuff in every direction for "
                              "this geometry (e.g. a single angular location)",
                              "geometry") from None
    return model
