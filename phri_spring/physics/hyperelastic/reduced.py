"""The reduced neo-Hookean coupled model: the hyperelastic FE condensed onto the cuff's pose.

docs/model.md section 10.8. The large-deformation FE of the tissue layer under a rigid
cuff bonded over its patches (:mod:`phri_spring.physics.hyperelastic.fe`) takes seconds to
minutes per load; a wrench log needs microseconds per sample. With the cuff rigid and
bonded, everything the FE reports is a function of the cuff's pose u = (t, w) alone
(translation [m], rotation vector [rad] about the cuff origin, the FE's finite rotation):
the resultant R(u) the skin applies to the cuff, the patch normal forces f(u) and the
patch forces P(u). The reduced model writes each as the linear coupled model's bonded
answer (rigid cuff, the same preload) plus a correction, a cubic polynomial in the scaled
pose x = u / s,

    R(u) = W_pre + H u + dR(x),    f(u) = f0 + N u + df(x),    P(u) = P0 + G u + dP(x),

with H = T^T C_t^-1 T, N = N_out T, G = C_t^-1 T (the linear model's own, so that its mesh
level sets the linear part). The corrections hold what the linear model lacks: the
neo-Hookean material's stiffening in compression and softening in tension, the normal
forces of finite shear (torsion), the finite rotation of the cuff and the initial stress
of the strap preload. They are fitted by least squares to the FE, solved under
displacement control at poses on rays from the preloaded state (the implicit-condensation
idea of Hollkamp and Gordon 2008, J. Sound Vib. 318:1139-1153,
doi:10.1016/j.jsv.2008.04.035, with the polynomial of Muravyov and Rizzi 2003, Comput.
Struct. 81:1513-1523, doi:10.1016/S0045-7949(03)00145-7). A wrench W is then the 6-unknown
equation H u + dR(u / s) = W, solved by Newton's method from the linear answer.

The rays reach the poses where the linear model carries a force of ``max_force`` or a
moment of ``max_moment`` (whichever comes first); a pose beyond that range
(``range_ratio`` > 1) is outside what was identified and is reported as not converged.
SI units; no files.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..springs.model import field_unit

__all__ = ["CV_FOLDS", "DEGREE", "EXPONENTS", "HyperReduction", "features", "fit_reduction",
           "held_out_error",
           "identification_poses", "identification_samples", "identify", "solve_poses"]

#: degree of the correction polynomials (cubic: the first odd and even nonlinear terms)
DEGREE = 3
# the monomials: 1, x_i, x_i x_j (i <= j), x_i x_j x_k (i <= j <= k); a cubic is a
# quadratic one times x_k, so both come from index arrays
_PAIRS = np.array([(i, j) for i in range(6) for j in range(i, 6)])
_TRIPLES = np.array([(p, k) for p, (i, j) in enumerate(_PAIRS) for k in range(j, 6)])


def _exponents() -> np.ndarray:
    rows = [np.zeros(6, int)] + list(np.eye(6, dtype=int))
    quad = [np.bincount(pq, minlength=6) for pq in _PAIRS]
    cub = [quad[p] + np.eye(6, dtype=int)[k] for p, k in _TRIPLES]
    return np.array(rows + quad + cub)


#: exponents (K, 6) of the monomials, in the order :func:`features` returns them
EXPONENTS = _exponents()
#: monomials of degree <= 2 (the derivatives of the cubic ones are in their span)
_LOW = 1 + 6 + len(_PAIRS)


def _derivative_maps() -> np.ndarray:
    """M (6, _LOW, K): d(monomial k)/dx_l = sum_i low-monomial_i(x) M[l, i, k]."""
    index = {tuple(e): i for i, e in enumerate(EXPONENTS[:_LOW])}
    M = np.zeros((6, _LOW, len(EXPONENTS)))
    for k, e in enumerate(EXPONENTS):
        for l_ in np.nonzero(e)[0]:
            lower = e.copy()
            lower[l_] -= 1
            M[l_, index[tuple(lower)], k] = e[l_]
    return M


_DMAPS = _derivative_maps()
#: Newton iterations of the 6-unknown equation before a sample counts as not converged
NEWTON_ITERATIONS = 30


def low_monomials(x: np.ndarray) -> np.ndarray:
    return np.concatenate([np.ones((len(x), 1)), x, x[:, _PAIRS[:, 0]] * x[:, _PAIRS[:, 1]]],
                          axis=1)


def _cubic(low: np.ndarray, x: np.ndarray) -> np.ndarray:
    return np.concatenate([low, low[:, 7 + _TRIPLES[:, 0]] * x[:, _TRIPLES[:, 1]]], axis=1)


def features(x, derivative: bool = False):
    """Monomials of the scaled poses x (m, 6): Phi (m, K) [and dPhi/dx (m, K, 6)]."""
    x = np.atleast_2d(np.asarray(x, float))
    low = low_monomials(x)
    phi = _cubic(low, x)
    if not derivative:
        return phi
    return phi, np.einsum("mi,lik->mkl", low, _DMAPS)


@dataclass(frozen=True, eq=False)
class HyperReduction:
    """The identified corrections of the reduced neo-Hookean model (module docstring).

    Attributes
    ----------
    scale : ndarray, shape (6,)
        s: x = u / s, the largest ``|u_k|`` the identification reached [m, rad].
    wrench : ndarray, shape (K, 6)
        Coefficients of dR [N, N*m].
    normal : ndarray, shape (K, n)
        Coefficients of df [N].
    patch : ndarray, shape (K, n*6)
        Coefficients of dP, local axes per patch [N, N*m].
    range_map : ndarray, shape (6, 6)
        D^-1 H, D = diag(max_force x 3, max_moment x 3) [1/m, 1/rad]: the scaled linear
        wrench of a pose (:meth:`range_ratio`).
    info : dict
        How it was identified: ``level``, ``max_force`` [N], ``max_moment`` [N*m],
        ``rays``, ``fractions``, ``samples``, the fit's RMS residuals (``fit_rms_*``), FE
        iterations and seconds.
    """

    scale: np.ndarray = field(metadata=field_unit("[m, rad]", "docs/model.md section 10.8"))
    wrench: np.ndarray = field(repr=False, metadata=field_unit("[N, N*m]", "docs/model.md section 10.8"))
    normal: np.ndarray = field(repr=False, metadata=field_unit("N", "docs/model.md section 10.8"))
    patch: np.ndarray = field(repr=False, metadata=field_unit("[N, N*m]", "docs/model.md section 10.8"))
    range_map: np.ndarray = field(repr=False, metadata=field_unit("[1/m, 1/rad]",
                                                                  "docs/model.md section 10.8"))
    info: dict = field(default_factory=dict)

    def range_ratio(self, u) -> np.ndarray:
        """``max(|F| / max_force, |M| / max_moment)`` (m,) of the linear wrench (F, M) = H u of
        poses u (m, 6): > 1 is outside the identified range."""
        return _box_norm(np.atleast_2d(u) @ self.range_map.T)

    @cached_property
    def jacobian_map(self) -> np.ndarray:
        """D (_LOW, 36): d(dR)/dx = (low-monomials(x) @ D).reshape(6, 6) (rows: dR's
        components, columns: x's), the derivative of the cubic as a quadratic."""
        return np.einsum("lik,kj->ijl", _DMAPS, self.wrench).reshape(_LOW, 36)

    def jacobian(self, H, low) -> np.ndarray:
        """d(H u + dR(u / s))/du (m, 6, 6) at the poses whose low monomials (:func:`low_monomials`
        of x = u / s) are ``low`` (m, _LOW): the reduced model's tangent stiffness."""
        return H + (low @ self.jacobian_map).reshape(-1, 6, 6) / self.scale

    def start_map(self, H) -> np.ndarray:
        """J0^-T (6, 6), J0 the tangent at u = 0: :meth:`start` with it precomputed."""
        return np.linalg.inv(self.jacobian(np.asarray(H, float), low_monomials(np.zeros((1, 6))))[0]).T

    def start(self, H, W, start_map=None) -> np.ndarray:
        """Newton's starting poses (m, 6) for wrenches W (m, 6): the reduced model's
        tangent at u = 0, J0 u = W - dR(0) (``start_map``: :meth:`start_map` of H)."""
        J0_T = self.start_map(H) if start_map is None else start_map
        return (np.atleast_2d(W) - self.wrench[0]) @ J0_T

    def arrays(self) -> dict:
        """Every array, for saving (``info`` separately)."""
        return dict(scale=self.scale, wrench=self.wrench, normal=self.normal,
                    patch=self.patch, range_map=self.range_map)


def _box_norm(s: np.ndarray) -> np.ndarray:
    """max(|s[:3]|, |s[3:]|) of rows s (m, 6) (the scaled force and moment)."""
    return np.maximum(np.linalg.norm(s[:, :3], axis=1), np.linalg.norm(s[:, 3:], axis=1))


def _range_scale(max_force: float, max_moment: float) -> np.ndarray:
    return np.array([max_force] * 3 + [max_moment] * 3, float)


def identification_poses(H, max_force: float, max_moment: float, rays: int,
                         seed: int = 0) -> np.ndarray:
    """Ray ends (rays, 6): u = H^-1 D d, d a random direction scaled to the range's edge,
    ``max(|d[:3]|, |d[3:]|) = 1``; half of them -d (antithetic).

    H (6, 6) is the linear bonded model's stiffness; D as in :class:`HyperReduction`.
    """
    rng = np.random.default_rng(seed)
    half = (int(rays) + 1) // 2
    d = rng.standard_normal((half, 6))
    d /= _box_norm(d)[:, None]
    d = np.concatenate([d, -d])[:int(rays)]
    return np.linalg.solve(H, (d * _range_scale(max_force, max_moment)).T).T


#: folds of the held-out check (:func:`fit_reduction`): rays are left out in turn
CV_FOLDS = 8


def _lstsq(phi, Y):
    # columns scaled to unit norm: the cubic monomials are small where the linear ones are not
    norms = np.linalg.norm(phi, axis=0)
    norms[norms == 0] = 1.0
    return np.linalg.lstsq(phi / norms, Y, rcond=None)[0] / norms[:, None]


def held_out_error(phi, Y, F, groups, folds: int = CV_FOLDS) -> float:
    """The normal-force correction's error on rays it was not fitted to [% of the peak].

    Rays (``groups`` >= 0; -1: always fitted) are split into ``folds`` sets; each set is
    predicted by the fit to the others. Per held-out pose, the RMSE over the patches in %
    of that pose's peak ``|F|``; returned: the 95th percentile. It estimates the reduced
    model's error between its rays, which a fit residual does not (a cubic can follow
    289 poses closely and still swing between them).
    """
    groups = np.asarray(groups)
    ids = np.unique(groups[groups >= 0])
    errs = []
    for k in range(folds):
        out = np.isin(groups, ids[k::folds])
        if not out.any():
            continue
        c = _lstsq(phi[~out], Y[~out])
        e = np.sqrt(np.mean((phi[out] @ c - Y[out]) ** 2, axis=1))
        errs.append(100 * e / np.maximum(np.abs(F[out]).max(axis=1), 1e-12))
    return float(np.percentile(np.concatenate(errs), 95)) if errs else float("nan")


def fit_reduction(U, R, F, P, linear, max_force: float, max_moment: float,
                  info: dict | None = None, groups=None) -> HyperReduction:
    """Least-squares corrections from FE samples.

    Parameters
    ----------
    U : ndarray, shape (m, 6)
        Poses [m, rad]; R (m, 6) resultants [N, N*m], F (m, n) normal forces [N], P (m, n*6)
        patch forces (local axes) [N, N*m] of the FE at them.
    linear : dict
        The linear bonded model at the FE's mesh level: ``W_pre`` (6,), ``H`` (6, 6),
        ``f0`` (n,), ``N`` (n, 6), ``P0`` (n*6,), ``G`` (n*6, 6).
    groups : array_like of int, shape (m,), optional
        The ray of each pose (-1: the preload): ``info["held_out_normal_pct"]`` then holds
        :func:`held_out_error` of the normal forces.
    """
    U = np.asarray(U, float)
    scale = np.max(np.abs(U), axis=0)
    if not np.all(scale > 0):
        raise ValueError("identification poses: every pose component must vary")
    phi = features(U / scale)
    targets = dict(
        wrench=R - linear["W_pre"] - U @ linear["H"].T,
        normal=F - linear["f0"] - U @ linear["N"].T,
        patch=P - linear["P0"] - U @ linear["G"].T)
    coef, out = {}, dict(info or {})
    for name, Y in targets.items():
        c = _lstsq(phi, Y)
        coef[name] = c
        out[f"fit_rms_{name}"] = float(np.sqrt(np.mean((phi @ c - Y) ** 2)))
    if groups is not None:
        out["held_out_normal_pct"] = held_out_error(phi, targets["normal"], np.asarray(F),
                                                    groups)
    out.update(samples=len(U), max_force=float(max_force), max_moment=float(max_moment))
    D = _range_scale(max_force, max_moment)
    return HyperReduction(scale=scale, range_map=linear["H"] / D[:, None], info=out, **coef)


def identify(cuff, linear, *, max_force: float, max_moment: float, rays: int,
             fractions=(1 / 3, 2 / 3, 1.0), seed: int = 0, progress=None) -> HyperReduction:
    """Identify the corrections with the hyperelastic FE (:mod:`.fe_hyper`): the samples of
    :func:`identification_samples`, fitted by :func:`fit_reduction`."""
    U, R, F, P, info = identification_samples(
        cuff, linear, max_force=max_force, max_moment=max_moment, rays=rays,
        fractions=fractions, seed=seed, progress=progress)
    groups = np.r_[-1, np.repeat(np.arange(int(rays)), len(fractions))]
    return fit_reduction(U, R, F, P, linear, max_force, max_moment, info, groups=groups)


def identification_samples(cuff, linear, *, max_force: float, max_moment: float,
                           rays: int, fractions=(1 / 3, 2 / 3, 1.0), seed: int = 0,
                           progress=None):
    """The FE's answers at the identification poses: U, R, F, P (as :func:`fit_reduction`
    takes them) and an info dict.

    Parameters
    ----------
    cuff : HyperCuff
        The FE, plates offset by the preload (``delta``) of ``linear``'s model.
    linear : dict
        As in :func:`fit_reduction`, at the FE's mesh level.
    max_force, max_moment : float
        The range [N, N*m] (module docstring).
    rays, fractions, seed
        Ray count, the fractions of each ray solved (in order, from the preloaded state), seed.
    progress : callable(done, total), optional
        Called after each ray.
    """
    from . import fe as fh

    ends = identification_poses(linear["H"], max_force, max_moment, rays, seed)
    rows, its = [fh.patch_forces(cuff, np.zeros(6), preload=True)], 0     # the preload
    start = cuff.checkpoint()
    for i, end in enumerate(ends):
        cuff.restore(start)
        for frac in fractions:
            sol = fh.patch_forces(cuff, frac * end, preload=True, steps=1)
            rows.append(sol)
            its += sol.iterations
        if progress is not None:
            progress(i + 1, len(ends))
    cuff.restore(start)
    U = np.array([s.u for s in rows])
    R = np.array([s.wrench for s in rows])
    F = np.array([s.normal_forces for s in rows])
    P = np.array([s.patch_forces.ravel() for s in rows])
    info = dict(level=int(cuff.info.get("level", 0)), rays=int(rays),
                fractions=[float(f) for f in fractions], seed=int(seed), fe_iterations=int(its))
    return U, R, F, P, info


def solve_poses(red: HyperReduction, H, W, u0, *, tol: float = 1e-9,
                max_iterations: int = NEWTON_ITERATIONS, arm: float = 0.05):
    """Newton's method for H u + dR(u / s) = W, every row at once.

    Parameters
    ----------
    red : HyperReduction
    H : ndarray, shape (6, 6)
        The linear bonded stiffness the reduction is added to [N/m, ...].
    W : ndarray, shape (m, 6)
        Wrenches [N, N*m].
    u0 : ndarray, shape (m, 6)
        Starting poses (e.g. :meth:`HyperReduction.start`).
    tol : float
        Converged when ``|(dF, dM / arm)| <= tol (1 + |(W_F, W_M / arm)|)``, ``arm`` [m].

    Returns
    -------
    u (m, 6), Phi (m, K) the monomials at u (for the forces), iterations (m,), converged
    (m,) bool: False where the iteration failed or u is outside the identified range.
    """
    W = np.atleast_2d(np.asarray(W, float))
    m = len(W)
    u = np.array(u0, float, copy=True).reshape(m, 6)
    if m == 1:
        return _solve_one(red, np.asarray(H, float), W[0], u[0], tol, int(max_iterations), arm)
    wscale = np.array([1.0] * 3 + [1.0 / arm] * 3)
    limit = tol * (1.0 + np.linalg.norm(W * wscale, axis=1))
    its = np.zeros(m, dtype=np.int64)
    conv = np.zeros(m, dtype=bool)
    phi_out = np.full((m, len(EXPONENTS)), np.nan)
    inv_s, HT = 1.0 / red.scale, np.asarray(H, float).T
    rows = np.arange(m)
    # a step that does not lower the residual is halved (from the pose it started at)
    # before the next Newton step is taken: Newton from the linear answer rarely needs it
    prev_u, prev_step = u.copy(), np.zeros((m, 6))
    prev_size, t = np.full(m, np.inf), np.ones(m)
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(int(max_iterations) + 1):
            ur = u[rows]
            x = ur * inv_s
            low = low_monomials(x)
            phi = _cubic(low, x)
            g = ur @ HT + phi @ red.wrench - W[rows]
            size = np.sqrt(np.einsum("mi,mi->m", g * wscale, g * wscale))
            done = size <= limit[rows]
            if done.any():
                conv[rows[done]] = True
                phi_out[rows[done]] = phi[done]
            worse = ~done & ~(size < prev_size[rows])
            if worse.any():                    # halve the last step of these rows
                wr = rows[worse]
                t[wr] *= 0.5
                u[wr] = prev_u[wr] - t[wr, None] * prev_step[wr]
            new = ~done & ~worse         # the residual fell (so it is finite)
            keep = ~done & (new | (t[rows] > 1e-6))
            if not new.any() and not keep.any():
                break
            if new.any():
                nr = rows[new]
                step = np.linalg.solve(red.jacobian(H, low[new]), g[new][:, :, None])[..., 0]
                prev_u[nr], prev_step[nr], prev_size[nr], t[nr] = ur[new], step, size[new], 1.0
                u[nr] = ur[new] - step
            its[rows[keep]] += 1
            rows = rows[keep]
            if not len(rows):
                break
    conv &= red.range_ratio(u) <= 1.0 + 1e-9
    return u, phi_out, its, conv


def _solve_one(red, H, w, u, tol, max_iterations, arm):
    """:func:`solve_poses` for one row: the same iteration without the row bookkeeping
    (a control loop's call)."""
    inv_s, C = 1.0 / red.scale, red.wrench
    wscale = np.array([1.0, 1.0, 1.0, 1.0 / arm, 1.0 / arm, 1.0 / arm])
    limit = tol * (1.0 + float(np.sqrt(((w * wscale) ** 2).sum())))
    prev_u, prev_step, prev_size, t = u, np.zeros(6), np.inf, 1.0
    its, ok, phi = 0, False, None
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(max_iterations + 1):
            x = (u * inv_s)[None]
            low = low_monomials(x)
            phi = _cubic(low, x)
            g = H @ u + phi[0] @ C - w
            size = float(np.sqrt(((g * wscale) ** 2).sum()))
            if size <= limit:
                ok = True
                break
            if not size < prev_size:       # halve the last step (also where size is NaN)
                t *= 0.5
                if t <= 1e-6:
                    break
                u = prev_u - t * prev_step
            else:
                step = np.linalg.solve(red.jacobian(H, low)[0], g)
                prev_u, prev_step, prev_size, t = u, step, size, 1.0
                u = u - step
            its += 1
    if ok:
        ok = bool(red.range_ratio(u[None])[0] <= 1.0 + 1e-9)
    if not ok:
        phi = np.full((1, len(EXPONENTS)), np.nan)
    return u[None], phi, np.array([its]), np.array([ok])


def linear_bonded(model) -> dict:
    """The linear bonded answer of a rigid-cuff :class:`~.coupled.CoupledModel` as
    :func:`fit_reduction` takes it: W_pre, H = T^T C_t^-1 T, f0, N = N_out T, P0 = C_t^-1 delta,
    G = C_t^-1 T (local axes, d = 6 dofs per patch)."""
    if model.dofs != 6 or model.N_out is None:
        raise ValueError("the reduced neo-Hookean model needs the built-in FE's coupled model "
                         "(6 dofs per patch and its normal-force output)")
    K = np.linalg.inv(model.C_t)
    K = 0.5 * (K + K.T)
    G = K @ model.T
    return dict(W_pre=np.asarray(model.W_pre, float), H=model.T.T @ G, f0=model.f0,
                N=model.N_out @ model.T, P0=K @ model.delta, G=G)
