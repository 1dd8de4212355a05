"""Large-deformation flat punch on a one-term Ogden layer: stiffening rate and its inverse.

A rigid flat cylindrical punch pressed into a compressible one-term Ogden layer bonded
to a rigid base (the bone), axisymmetric, total Lagrangian, 9-node quadrilaterals. Its
force-depth curve, fitted with the tissue law's exponential formula
F = (k0/beta)(exp(beta d) - 1) (:func:`~phri_spring.physics.indentation.exponential.law_force`),
turns an Ogden exponent alpha into the stiffening rate beta [1/m] of an indenter test
(:func:`punch_stiffening`), and an indenter curve's beta (``phri fit-stiffness --law
exponential``) back into alpha (:func:`ogden_alpha_from_stiffening`), e.g. for a 3-D
Ogden model of the cuff's tissue.

The one-term Ogden law describes in-vivo indentation of limb soft tissue in large
deformation: Fougeron, Rohan, Haering, Rose, Bonnet and Pillet, "Combining Freehand
Ultrasound-Based Indentation and Inverse Finite Element Modeling for the Identification
of Hyperelastic Material Properties of Thigh Soft Tissues", J. Biomech. Eng. 142(9),
2020, doi:10.1115/1.4046444 (relaxed thigh: alpha = 10 +- 1). The energy is

    W = (2 mu / alpha^2) (l1^alpha + l2^alpha + l3^alpha - 3) + (K / 2) (J - 1)^2,

l_i = J^(-1/3) lambda_i the isochoric principal stretches; alpha = 2 is the compressible
neo-Hookean solid. mu = E / (2 (1 + nu)) and K = E / (3 (1 - 2 nu)) are the layer's
small-strain moduli. At fixed alpha and nu the force is proportional to E, so beta
depends on alpha, nu and the geometry only. ``examples/make_human_stiffening.py`` uses
this module for the human preset's ``tissue.stiffening``.

scikit-fem is an optional dependency (extra ``fe``), imported only inside the functions
that need it. SI units throughout.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq, least_squares

from ...errors import ConvergenceError
from ..continuum.mesh import graded, import_skfem, check_material
from ..indentation.exponential import law_force

__all__ = ["ogden_stress", "punch_curve", "slope_at_contact", "fit_stiffening",
           "punch_stiffening", "ogden_alpha_from_stiffening", "IDENTIFICATION_STEPS"]

#: Load steps per ``depth`` (10 mm) of :func:`punch_stiffening` and the inverse (its
#: docstring gives the measured effect of the step count on beta).
IDENTIFICATION_STEPS = 20
FIT_SAMPLES = 201          # depths at which punch_stiffening samples the curve's spline
_NEWTON_ITERATIONS = 25    # Newton iterations per load step before the step is cut
_STEP_CUTS = 5             # halvings of one load step before the curve stops


# --------------------------------------------------------------------------- material


def _stretches(g):
    """Principal stretches (in-plane pair, ascending, then hoop) and in-plane directions."""
    F11, F12, F21, F22 = 1 + g[0], g[1], g[2], 1 + g[3]
    C11, C12, C22 = F11 * F11 + F21 * F21, F11 * F12 + F21 * F22, F12 * F12 + F22 * F22
    ev, N = np.linalg.eigh(np.stack([np.stack([C11, C12], -1), np.stack([C12, C22], -1)], -2))
    return np.sqrt(ev[..., 0]), np.sqrt(ev[..., 1]), 1 + g[4], N


def ogden_stress(g, mu, alpha, kappa):
    """First Piola-Kirchhoff stress of the compressible one-term Ogden solid, axisymmetric.

    W = (2 mu / alpha^2) (sum_i (J^(-1/3) lambda_i)^alpha - 3) + (kappa / 2) (J - 1)^2,
    the form Fougeron et al. 2020 (J. Biomech. Eng. 142(9), doi:10.1115/1.4046444) fitted
    to in-vivo indentation of the thigh. The principal stretches of the in-plane (r, z)
    block come from its right Cauchy-Green tensor; the hoop stretch is principal.

    Parameters
    ----------
    g : ndarray, shape (5, ...)
        Displacement gradient at the quadrature points: F_rr - 1, F_rz, F_zr, F_zz - 1,
        F_tt - 1 [-].
    mu : float
        Small-strain shear modulus [Pa].
    alpha : float
        Ogden exponent [-] (2: neo-Hookean).
    kappa : float
        Bulk modulus [Pa].

    Returns
    -------
    P : ndarray, shape (5, ...)
        First Piola-Kirchhoff stress [Pa] in the layout of ``g`` (P_rr, P_rz, P_zr, P_zz,
        P_tt).
    J : ndarray, shape (...)
        Volume ratio det F [-].
    """
    F11, F12, F21, F22 = 1 + g[0], g[1], g[2], 1 + g[3]
    l1, l2, l3, N = _stretches(g)
    J = l1 * l2 * l3
    Jm = np.cbrt(1.0 / J)
    b = [(Jm * lam) ** alpha for lam in (l1, l2, l3)]
    mean = (b[0] + b[1] + b[2]) / 3.0
    vol = kappa * (J - 1.0) * J
    t = [2.0 * mu / alpha * (bi - mean) + vol for bi in b]      # lambda_i dW/dlambda_i
    s1, s2 = t[0] / l1 ** 2, t[1] / l2 ** 2
    n1, n2 = N[..., :, 0], N[..., :, 1]
    S = (s1[..., None, None] * n1[..., :, None] * n1[..., None, :]
         + s2[..., None, None] * n2[..., :, None] * n2[..., None, :])
    P = np.stack([F11 * S[..., 0, 0] + F12 * S[..., 1, 0], F11 * S[..., 0, 1] + F12 * S[..., 1, 1],
                  F21 * S[..., 0, 0] + F22 * S[..., 1, 0], F21 * S[..., 0, 1] + F22 * S[..., 1, 1],
                  t[2] / l3])
    return P, J


def _ogden_energy(g, mu, alpha, kappa):
    """Strain energy density W [J/m^3] of :func:`ogden_stress`'s solid."""
    l1, l2, l3, _ = _stretches(g)
    J = l1 * l2 * l3
    Jm = np.cbrt(1.0 / J)
    return (2.0 * mu / alpha ** 2 * ((Jm * l1) ** alpha + (Jm * l2) ** alpha
                                     + (Jm * l3) ** alpha - 3.0)
            + 0.5 * kappa * (J - 1.0) ** 2)


# --------------------------------------------------------------------------- punch FE


@lru_cache(maxsize=8)
def _operators(a, h, h0, bonded):
    """Mesh and the linear operators of the punch FE (shared by every call on one layer).

    Returns ``G`` (5 Q x N, sparse): the displacement gradient of :func:`ogden_stress` at
    the Q quadrature points from the dofs, component-major; ``w`` (Q): 2 pi r times the
    quadrature weight [m^2]; the punch's axial dofs and the free dofs.
    """
    sk = import_skfem()
    inner = a - graded(a, h0, 1.25)[::-1]
    rn = np.unique(np.concatenate([[0.0], inner[inner > 0], [a],
                                   a + graded(10.0 * max(h, a), h0, 1.25)]))
    zn = np.unique(np.concatenate([[0.0], -graded(h, h0, 1.25)]))
    zn[0] = -h
    ib = sk["Basis"](sk["MeshQuad"].init_tensor(rn, zn),
                     sk["ElementVector"](sk["ElementQuad2"]()), intorder=4)
    nel, nqp = ib.dx.shape
    Q = nel * nqp
    r = np.asarray(ib.global_coordinates())[0]
    rows, cols, vals = [], [], []
    qidx = np.arange(Q).reshape(nel, nqp)
    for j, (phi,) in enumerate(ib.basis):
        comps = (phi.grad[0][0], phi.grad[0][1], phi.grad[1][0], phi.grad[1][1],
                 np.asarray(phi)[0] / r)
        dof = np.broadcast_to(ib.element_dofs[j][:, None], (nel, nqp))
        for k, c in enumerate(comps):
            nz = c != 0
            rows.append(k * Q + qidx[nz])
            cols.append(dof[nz])
            vals.append(c[nz])
    G = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(5 * Q, ib.N))
    loc, comp = ib.doflocs, np.tile(np.arange(2), ib.N // 2)
    tol = 1e-12
    under = (np.abs(loc[1]) <= tol) & (loc[0] <= a + tol)
    punch = np.nonzero(under & (comp == 1))[0]
    fixed = [np.nonzero(np.abs(loc[1] + h) <= tol)[0],                # bonded to the bone
             np.nonzero((np.abs(loc[0]) <= tol) & (comp == 0))[0],   # axis
             punch]
    if bonded:                                                       # face bonded to the skin
        fixed.append(np.nonzero(under & (comp == 0))[0])
    free = np.setdiff1d(np.arange(ib.N), np.concatenate(fixed))
    Gc = G.tocsc()
    Gf, Gp = Gc[:, free].tocsr(), Gc[:, punch].tocsr()
    return dict(G=G, Gf=Gf, GfT=Gf.T.tocsr(), GpT=Gp.T.tocsr(), w=(2 * np.pi * r * ib.dx).ravel(),
                Q=Q, N=ib.N, punch=punch, free=free)


def _check(radius, thickness, young_modulus, poisson_ratio, alpha):
    check_material(thickness=thickness, poisson_ratio=poisson_ratio,
                   young_modulus=young_modulus)
    for name, v in (("radius", radius), ("alpha", alpha)):
        if not (math.isfinite(float(v)) and float(v) > 0):
            raise ValueError(f"{name}: expected a finite value > 0, got {v!r}")


def _march(radius, thickness, young_modulus, poisson_ratio, alpha, depths, edge_size, bonded,
           force_stop=None):
    """Equilibria at the punch depths ``depths`` (from 0): depths, forces, status."""
    _check(radius, thickness, young_modulus, poisson_ratio, alpha)
    a, h = float(radius), float(thickness)
    h0 = a / 8.0 if edge_size is None else float(edge_size)
    op = _operators(a, h, h0, bool(bonded))
    G, Gf, GfT, GpT, w, Q = op["G"], op["Gf"], op["GfT"], op["GpT"], op["w"], op["Q"]
    punch, free = op["punch"], op["free"]
    E, nu, alpha = float(young_modulus), float(poisson_ratio), float(alpha)
    mu, kappa = E / (2.0 * (1.0 + nu)), E / (3.0 * (1.0 - 2.0 * nu))
    diag = np.arange(Q)
    e_tol = 1e-12 * (mu + kappa) * float(w.sum())   # round-off of the total energy [J]
    hrow = np.concatenate([i * Q + diag for i in range(5) for j in range(5)])
    hcol = np.concatenate([j * Q + diag for i in range(5) for j in range(5)])

    def state(u):
        g = (G @ u).reshape(5, Q)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            P, J = ogden_stress(g, mu, alpha, kappa)
        return g, P, bool(np.all(J > 0) and np.all(np.isfinite(P)))

    def tangent(g, eps=1e-7):   # material tangent by central differences of P
        H = np.empty((5, 5, Q))
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            for j in range(5):
                gp, gm = g.copy(), g.copy()
                gp[j] += eps
                gm[j] -= eps
                H[:, j] = (ogden_stress(gp, mu, alpha, kappa)[0]
                           - ogden_stress(gm, mu, alpha, kappa)[0]) / (2 * eps)
        return sp.csr_matrix(((H * w).ravel(), (hrow, hcol)), shape=(5 * Q, 5 * Q))

    def energy(g):             # total strain energy [J]
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            return float(_ogden_energy(g, mu, alpha, kappa) @ w)

    def reaction(P):             # nodal forces of the stress: free dofs, punch total
        wp = (P * w).ravel()
        return GfT @ wp, float((GpT @ wp).sum())

    def step(u, g, P, d):        # Newton from the equilibrium (u, g, P) to punch depth d
        Hm = tangent(g)
        du = np.zeros(op["N"])
        du[punch] = -d - u[punch[0]]
        Rf, _ = reaction(P)
        du[free] = spla.spsolve((GfT @ (Hm @ Gf)).tocsc(), -(Rf + GfT @ (Hm @ (G @ du))))
        g, P, ok = state(u + du)     # predictor: the punch's increment carried into the layer
        if not ok:
            return None, "element inverted"
        u = u + du
        Rf, fp = reaction(P)
        for _ in range(_NEWTON_ITERATIONS):
            if np.linalg.norm(Rf) <= 1e-9 * max(abs(fp), 1e-12):
                return (u, g, P, -fp), ""
            du = np.zeros(op["N"])
            K = (GfT @ (tangent(g) @ Gf)).tocsc()
            du[free] = spla.spsolve(K, -Rf)
            slope, shift = float(Rf @ du[free]), 1e-4
            while slope >= 0 and shift < 1e4:   # indefinite tangent: shift to descend
                du[free] = spla.spsolve(K + shift * sp.diags(np.abs(K.diagonal())), -Rf)
                slope, shift = float(Rf @ du[free]), 10.0 * shift
            e0, s = energy(g), 1.0
            while True:              # halve against inverted elements and rising energy
                g1, P1, ok = state(u + s * du)
                if ok and energy(g1) <= e0 + 1e-4 * s * slope + e_tol:
                    break
                s *= 0.5
                if s < 1e-4:
                    return None, "no convergence" if ok else "element inverted"
            u, g, P = u + s * du, g1, P1
            Rf, fp = reaction(P)
        return None, "no convergence"

    depths = np.asarray(depths, float)
    forces = [0.0]
    u = np.zeros(op["N"])
    g, P, _ = state(u)
    done = 0.0
    for target in depths[1:]:
        inc, cuts = target - done, 0
        while done < target:
            d = min(done + inc, target)
            res, why = step(u, g, P, d)
            if res is None:
                cuts += 1
                if cuts > _STEP_CUTS:
                    return (depths[:len(forces)], np.array(forces),
                            f"{why} at {d * 1e3:.2f} mm")
                inc *= 0.5
                continue
            (u, g, P, f), done = res, d
        forces.append(f)
        if force_stop is not None and f >= force_stop:
            return depths[:len(forces)], np.array(forces), "ok"
    return depths, np.array(forces), "ok"


def punch_curve(radius, thickness, young_modulus, poisson_ratio, alpha, *, depth=0.010,
                steps=50, edge_size=None, bonded=True):
    """Force-depth curve of a rigid flat punch on an Ogden layer bonded to a rigid base.

    Axisymmetric, total Lagrangian, 9-node quadrilaterals graded toward the punch edge
    (``edge_size``, growing by a factor 1.25 per element), the layer 10 max(h, a) wide
    with a traction-free rim and top. Displacement-controlled load steps: a tangent
    predictor, then Newton iterations (the tangent shifted toward its diagonal where it is
    indefinite) with a backtracking line search on the strain energy and against inverted
    elements; a load step that does not converge is halved, up to 5 times. mu = E / (2 (1 +
    nu)) and K = E / (3 (1 - 2 nu)), the small-strain moduli of the linear layer. Human
    preset (a = 4.5 mm, h = 25 mm, alpha = 10, 50 steps to 10 mm): about 5 s.

    Parameters
    ----------
    radius : float
        Punch radius a [m].
    thickness : float
        Layer thickness h [m] over the rigid base.
    young_modulus : float
        Small-strain Young's modulus E [Pa] (the force is proportional to it).
    poisson_ratio : float
        Small-strain Poisson ratio nu [-], at most 0.45.
    alpha : float
        Ogden exponent [-] (> 0; 2 is neo-Hookean).
    depth : float, optional
        Deepest punch depth [m].
    steps : int, optional
        Equal load steps to ``depth``.
    edge_size : float, optional
        Element size at the punch edge [m] (default a / 8).
    bonded : bool, optional
        Punch face bonded to the skin (True) or frictionless (False).

    Returns
    -------
    depth : ndarray
        Punch depths [m] from 0, stopping early if a step fails.
    force : ndarray
        Punch force [N] at those depths (positive in compression).
    status : str
        ``"ok"``, or why the curve stopped (``"element inverted at 6.20 mm"``).
    """
    return _march(radius, thickness, young_modulus, poisson_ratio, alpha,
                  np.linspace(0.0, float(depth), int(steps) + 1), edge_size, bonded)


def slope_at_contact(radius, thickness, young_modulus, poisson_ratio, alpha, *, bonded=True,
                     edge_size=None):
    """Slope of the punch curve at contact [N/m]: one 10 um step of :func:`punch_curve`.

    Parameters are those of :func:`punch_curve`. At contact the slope does not depend on
    alpha (every alpha has the small-strain moduli E and nu).

    Returns
    -------
    float
        k0 = F / d at d = 10 um [N/m].
    """
    d, f, _ = _march(radius, thickness, young_modulus, poisson_ratio, alpha, [0.0, 1e-5],
                     edge_size, bonded)
    return float(f[1] / d[1])


# --------------------------------------------------------------------------- fit


def fit_stiffening(depth, force, k0, depth_max, *, samples=None):
    """Stiffening rate of F = (k0/beta)(exp(beta d) - 1) fitted to a force-depth curve.

    Least squares over 0 <= d <= ``depth_max``, k0 held, the contact point at d = 0.

    Parameters
    ----------
    depth : ndarray
        Depths [m] from 0 (contact), increasing.
    force : ndarray
        Forces [N] at those depths.
    k0 : float
        Slope at contact [N/m].
    depth_max : float
        End of the fit range [m].
    samples : int, optional
        None (default): fit the given samples with d <= ``depth_max``, so the range
        really ends at the last sample before it. An integer n: fit the curve's cubic
        spline at n equally spaced depths from 0 to ``depth_max`` (which the samples must
        reach), so that beta varies continuously with ``depth_max`` and hardly depends on
        the sample spacing.

    Returns
    -------
    beta : float
        Stiffening rate [1/m] (>= 0).
    r2 : float
        Coefficient of determination of the fit [-].
    worst : float
        Largest relative force error of the fit over the range, contact excluded [-].
    """
    depth, force = np.asarray(depth, float), np.asarray(force, float)
    if samples is None:
        m = depth <= depth_max * (1 + 1e-9)
        d, f = depth[m], force[m]
    else:
        if depth[-1] < depth_max * (1 - 1e-9):
            raise ValueError(f"depth_max: the curve ends at {depth[-1]:.4g} m, before "
                             f"{depth_max:.4g} m")
        d = np.linspace(0.0, float(depth_max), int(samples))
        f = CubicSpline(depth, force)(d)
    res = least_squares(lambda b: law_force(d, k0, b[0]) - f, [50.0], bounds=([0.0], [np.inf]),
                        x_scale=[100.0])
    beta = float(res.x[0])
    fit = law_force(d, k0, beta)
    r2 = 1.0 - float(np.sum((fit - f) ** 2) / np.sum((f - f.mean()) ** 2))
    worst = float(np.max(np.abs(fit[1:] - f[1:]) / f[1:]))
    return beta, r2, worst


def punch_stiffening(alpha, radius, thickness, young_modulus, poisson_ratio, force_max, *,
                     steps=IDENTIFICATION_STEPS, depth=0.010, max_depth=None, edge_size=None,
                     bonded=True):
    """Stiffening rate beta [1/m] an indenter test would measure on an Ogden layer.

    The recipe of ``examples/make_human_stiffening.py`` in one call: the punch curve of
    :func:`punch_curve` in increments ``depth / steps``, stopped at the first depth whose
    force reaches ``force_max`` (e.g. the pressure pain threshold times the punch area: as
    far as an indenter test on a person would go); k0 the curve's own slope at contact
    (:func:`slope_at_contact`); beta by :func:`fit_stiffening` from contact to the depth
    at which the curve's cubic spline reaches ``force_max``, on 201 equally spaced depths
    (so that beta varies continuously with alpha; the example fits its 0.2 mm samples up
    to that depth instead: 115.25 against 115.26 1/m here for its alpha = 10).

    Load steps. The layer is hyperelastic: the force at a depth does not depend on the
    steps taken to it, except where the curve passes an instability at the punch edge
    (below). Human preset (a = 4.5 mm, h = 25 mm, E = 30 kPa, nu = 0.45, force_max =
    7.63 N), beta [1/m] with 50 / 20 / 10 steps per 10 mm: alpha = 4: 33.50 / 33.53 /
    33.45; alpha = 6: 66.15 / 66.00 / 66.53; alpha = 10: 115.256 / 115.256 / 115.251;
    alpha = 15: 170.83 / 170.83 / 170.83; alpha = 30: 341.73 / 341.73 / 341.76 (alpha = 3:
    9.03 / 9.11 / 9.16). The default, 20 steps per 10 mm, is within 0.25 % of 50 steps for
    alpha >= 4, with fewer Newton solves (the time is in benchmarks/STIFFENING.md).

    Accuracy. At the sharp edge of the bonded punch the corner elements are crushed (J
    down to 0.1) and, beyond a few mm, the discrete layer has unstable equilibria there;
    the solver keeps to states of decreasing energy. beta with edge elements a/4, a/8
    (default), a/12, a/16, a/20: alpha = 10: 113.1, 115.3, 115.8, 115.8, 114.7; alpha = 6:
    67.7, 66.0, 65.7, 64.8, 64.6 1/m. Small alpha is less certain: alpha = 2 (neo-Hookean)
    softens (secant 0.8 k0 at 9.3 mm, force 2.1 N at 5 mm with a/8, 1.9 N with a/16) and
    reaches 6.5 N at 20 mm, so it has no beta up to 7.63 N on the human preset.

    Parameters
    ----------
    alpha : float
        Ogden exponent [-].
    radius, thickness, young_modulus, poisson_ratio
        Punch radius a [m], layer thickness h [m], small-strain E [Pa] and nu [-] (see
        :func:`punch_curve`). beta does not depend on E.
    force_max : float
        Force [N] at which the fit range ends.
    steps : int, optional
        Load steps per ``depth``.
    depth : float, optional
        Depth [m] that sets the load increment, depth / steps.
    max_depth : float, optional
        Deepest depth tried [m] (default 0.8 h).
    edge_size : float, optional
        Element size at the punch edge [m] (default a / 8).
    bonded : bool, optional
        Punch face bonded to the skin (default) or frictionless.

    Returns
    -------
    float
        beta [1/m].

    Raises
    ------
    ConvergenceError
        The curve stops (element inversion, no convergence) or reaches ``max_depth``
        before the force reaches ``force_max``.
    """
    _check(radius, thickness, young_modulus, poisson_ratio, alpha)
    fmax = float(force_max)
    if not (math.isfinite(fmax) and fmax > 0):
        raise ValueError(f"force_max: expected a finite value > 0 N, got {force_max!r}")
    if int(steps) < 1 or not float(depth) > 0:
        raise ValueError(f"steps, depth: expected >= 1 and > 0 m, got {steps!r}, {depth!r}")
    dmax = 0.8 * float(thickness) if max_depth is None else float(max_depth)
    beta, why = _stiffening(float(alpha), float(radius), float(thickness),
                            float(young_modulus), float(poisson_ratio), fmax, int(steps),
                            float(depth), dmax, None if edge_size is None else float(edge_size),
                            bool(bonded))
    if beta is None:
        raise ConvergenceError(why)
    return beta


@lru_cache(maxsize=256)
def _stiffening(alpha, a, h, E, nu, fmax, steps, depth, dmax, edge_size, bonded):
    """:func:`punch_stiffening`, cached (failures too): beta or None, and why it failed."""
    inc = depth / steps
    grid = inc * np.arange(int(np.floor(dmax / inc * (1 + 1e-9))) + 1)
    d, f, status = _march(a, h, E, nu, alpha, grid, edge_size, bonded, force_stop=fmax)
    if f[-1] < fmax:
        why = status if status != "ok" else f"the deepest depth tried, {d[-1] * 1e3:.1f} mm"
        return None, (f"the Ogden punch (alpha = {alpha:g}) stops at {f[-1]:.3g} N, below "
                      f"force_max = {fmax:.3g} N: {why}")
    k0 = slope_at_contact(a, h, E, nu, alpha, bonded=bonded, edge_size=edge_size)
    spline = CubicSpline(d, f)
    k = int(np.argmax(f >= fmax))                      # first sample at or above force_max
    d_max = brentq(lambda x: float(spline(x)) - fmax, d[k - 1], d[k], xtol=1e-12)
    return fit_stiffening(d, f, k0, d_max, samples=FIT_SAMPLES)[0], ""


def ogden_alpha_from_stiffening(beta, radius, thickness, young_modulus, poisson_ratio,
                                force_max, *, bracket=(1.0, 30.0), rtol=1e-3, **kwargs):
    """Ogden exponent alpha whose punch curve has the stiffening rate ``beta``.

    The inverse of :func:`punch_stiffening` (same layer, punch and ``force_max``): Brent's
    method on alpha within ``bracket``, after checking that beta increases from one end of
    the bracket to the other (and, at the end, over every alpha tried, to 1 %: the load-path
    noise of :func:`punch_stiffening`). If the punch FE stops before ``force_max`` at the
    lower end (small alpha on a thick layer, see :func:`punch_stiffening`), the lower end
    is raised by bisection, failures counting as below the root. Each alpha tried is one
    punch FE (cached). Human preset, default bracket: beta = 115.26 1/m, 7 FE runs (alpha =
    1 stops below force_max), about 30 s; beta = 66 1/m: 10 runs, about 45 s.

    Parameters
    ----------
    beta : float
        Stiffening rate of the indenter curve [1/m] (``phri fit-stiffness --law
        exponential``), fitted the same way: k0 at contact, up to ``force_max``.
    radius, thickness, young_modulus, poisson_ratio, force_max
        The indenter test, as in :func:`punch_stiffening`: punch radius [m], layer
        thickness [m], small-strain E [Pa] and nu [-], end of the fit range [N].
    bracket : tuple of float, optional
        Range of alpha searched [-].
    rtol : float, optional
        Relative tolerance on alpha.
    **kwargs
        Passed to :func:`punch_stiffening` (``steps``, ``depth``, ``edge_size``, ...).

    Returns
    -------
    float
        alpha [-].

    Raises
    ------
    ValueError
        ``beta`` is outside the range the Ogden law reaches over ``bracket`` for this
        layer and punch (the one-line message gives that range), or an invalid input.
    ConvergenceError
        The punch FE fails at the upper end of the bracket, or beta does not increase
        with alpha.
    """
    b = float(beta)
    lo, hi = (float(x) for x in bracket)
    if not (math.isfinite(b) and b >= 0):
        raise ValueError(f"beta: expected a finite value >= 0 1/m, got {beta!r}")
    if not (0 < lo < hi and math.isfinite(hi)):
        raise ValueError(f"bracket: expected 0 < low < high, got {bracket!r}")
    memo, why = {}, [""]

    def beta_of(al):                     # beta, or None where the FE stops before force_max
        if al not in memo:
            try:
                memo[al] = punch_stiffening(al, radius, thickness, young_modulus,
                                            poisson_ratio, force_max, **kwargs)
            except ConvergenceError as e:
                memo[al], why[0] = None, str(e)
        return memo[al]

    where = (f"on this layer and punch (a = {float(radius) * 1e3:.3g} mm, h = "
             f"{float(thickness) * 1e3:.3g} mm, nu = {float(poisson_ratio):g}, fit up to "
             f"{float(force_max):.3g} N)")
    b_hi = beta_of(hi)
    if b_hi is None:
        raise ConvergenceError(f"alpha = {hi:g}, the bracket's upper end: {why[0]}")
    b_lo = beta_of(lo)
    if b_lo is None:
        if b > b_hi:
            raise ValueError(f"beta = {b:.4g} 1/m is above the {b_hi:.4g} 1/m the one-term "
                             f"Ogden law reaches at alpha = {hi:g} {where}")
        fail, ok, b_ok = lo, hi, b_hi
        while b_lo is None:              # raise the lower end out of the failing alphas
            if ok - fail <= max(rtol, 0.01) * ok:
                raise ValueError(f"beta = {b:.4g} 1/m is outside the {b_ok:.4g}-{b_hi:.4g} "
                                 f"1/m the one-term Ogden law reaches for alpha in "
                                 f"{ok:.3g}-{hi:g} {where}; below alpha = {ok:.3g} the "
                                 f"punch FE stops before force_max ({why[0]})")
            mid = 0.5 * (fail + ok)
            bm = beta_of(mid)
            if bm is None:
                fail = mid
            elif bm > b:
                ok, b_ok, hi, b_hi = mid, bm, mid, bm
            else:
                lo, b_lo = mid, bm
    if not b_hi > b_lo:
        raise ConvergenceError(f"beta does not increase with alpha over {lo:g}-{hi:g} "
                               f"({b_lo:.4g} to {b_hi:.4g} 1/m): no unique alpha")
    if not b_lo <= b <= b_hi:
        raise ValueError(f"beta = {b:.4g} 1/m is outside the {b_lo:.4g}-{b_hi:.4g} 1/m the "
                         f"one-term Ogden law reaches for alpha in {lo:.3g}-{hi:.3g} {where}")
    if b in (b_lo, b_hi):
        root = lo if b == b_lo else hi
    else:
        def f(al):
            v = beta_of(al)
            if v is None:
                raise ConvergenceError(f"alpha = {al:.4g}: {why[0]}")
            return v - b
        root = float(brentq(f, lo, hi, rtol=rtol, xtol=1e-9))
    tried = sorted((al, v) for al, v in memo.items() if v is not None)
    vals = np.array([v for _, v in tried])
    if np.any(vals < 0.99 * np.maximum.accumulate(vals)):
        raise ConvergenceError("beta does not increase with alpha over the alphas tried ("
                               + ", ".join(f"{al:.3g}: {v:.4g}" for al, v in tried)
                               + " 1/m): no unique alpha")
    return root
