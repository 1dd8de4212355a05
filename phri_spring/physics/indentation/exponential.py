"""Exponential (Fung-type) indenter law fitted to the unloading strokes (docs/fit-stiffness.md).

The linear analysis of :mod:`phri_spring.physics.indentation.linear` fits a straight line
to each unloading stroke. Tissue that stiffens as it is compressed bends that
line upwards; this module fits instead, per trial, the exponential law

    F(d) = (k0 / beta) (exp(beta (d - d0)) - 1)   for d > d0, 0 otherwise,

with k0 [N/m] the slope at contact, beta [1/m] >= 0 the stiffening rate (the
tangent grows by e every 1/beta of compression; beta = 0 is the linear law) and
d0 [m] the contact point of each stroke. Exponential force-compression laws of
this kind go back to Fung's exponential elasticity of soft tissue (Fung 1967,
Am. J. Physiol. 213(6):1532-1544; Fung, *Biomechanics*, 2nd ed., Springer 1993,
ch. 7) and describe whole human-device interfaces as well (Schiebl et al. 2025,
Sensors 25(15):4605). The force formula is
:class:`~phri_spring.physics.laws.ExponentialLaw`'s, so that a fitted
(k0, beta) means in a config exactly what it meant here.

Method, per trial (:func:`fit_trial_exponential`):

1. **Branch.** The samples of the linear fits' unloading strokes (each from the
   top of a push while the force stays above the contact threshold): the
   unloading branch, as in the paper; loading is softer (hysteresis) and left out.
2. **Parameters.** One k0 and one beta per trial, one d0 per stroke: the dent
   the push leaves moves the contact point from push to push, not the tissue.
3. **Start.** The law obeys F' = k0 + beta F, so along a stroke
   F = k0 d + beta G(d) + c with G the running integral of F dd: a linear least
   squares in (k0, beta, c per stroke) (:func:`start_estimate`). Integrating
   rather than differentiating keeps the encoder steps and the force noise from
   being amplified. If it gives beta < 0 or k0 <= 0 the start is the linear
   fit (beta = 0). Each d0 then follows from the law's inverse.
4. **Fit.** :func:`scipy.optimize.least_squares` (trust-region reflective,
   analytic Jacobian) on scaled parameters (k0 over its start value, beta times
   the branch's depth span, d0 over that span) with beta >= 0, first plain
   least squares, then a soft-L1 loss whose scale is three robust SDs
   (1.4826 x median absolute residual) of the first pass, so that a spike or a
   slip in the recording does not pull the curve.
5. **Report.** R^2 per stroke; a fit that ends on beta's bound (no stiffening
   found: the data are linear or softening) or that does not converge is
   reported as such in :attr:`ExponentialFit.status`, never raised.

Everything here is pure numpy/scipy on arrays in SI units; no files, no printing.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .linear import LocationFit, TrialFit, location_statistics, trial_spread
from ..laws import ExponentialLaw

__all__ = ["ExponentialFit", "ExponentialLocationFit", "BETA_SPAN_MAX", "start_estimate",
           "fit_branches", "fit_trial_exponential", "fit_location_exponential",
           "law_force"]

#: upper bound of beta times the branch's depth span [-]: beyond it the tangent would grow by
#: more than e^40 over the data, which no tissue does; a fit ending there is reported as such
BETA_SPAN_MAX = 40.0
#: the contact points may lie at most this many depth spans below a stroke's shallowest sample
_OFFSET_SPANS = 2.0
#: robust scale of the second pass: this many robust SDs of the first pass's residuals
_ROBUST_SDS = 3.0


# --------------------------------------------------------------------------- results


@dataclass(frozen=True)
class ExponentialFit:
    """The exponential law fitted to the unloading strokes of one trial.

    Attributes
    ----------
    trial : TrialFit
        The linear analysis the strokes come from (signal, strokes, fit ranges).
    k0 : float
        Slope at contact [N/m]; NaN when the fit failed.
    stiffening : float
        Stiffening rate beta [1/m]; NaN when the fit failed.
    offset : ndarray, shape (n,)
        Contact point d0 of each unloading stroke, depth from onset [m].
    r2 : ndarray, shape (n,)
        Coefficient of determination of each stroke [-].
    status : str
        ``ok``; ``at_bound`` when beta ended on a bound (0: no stiffening found;
        ``BETA_SPAN_MAX``); ``failed`` when the optimiser did not converge.
    message : str
        Why, for a status other than ``ok``.
    """

    trial: TrialFit
    k0: float
    stiffening: float
    offset: np.ndarray
    r2: np.ndarray
    status: str = "ok"
    message: str = ""

    @property
    def converged(self) -> bool:
        return self.status != "failed"

    @property
    def r2_min(self) -> float:
        """Worst R^2 over the strokes [-] (NaN when the fit failed)."""
        return float(np.min(self.r2)) if self.converged else float("nan")

    def curve(self, i: int, n: int = 60) -> tuple[np.ndarray, np.ndarray]:
        """Depth [m] and fitted force [N] over unloading stroke ``i``'s depth range."""
        s0, s1 = int(self.trial.unloading.start[i]), int(self.trial.unloading.stop[i])
        d = self.trial.depth[s0:s1]
        dd = np.linspace(max(float(d.min()), float(self.offset[i])), float(d.max()), n)
        return dd, law_force(dd - self.offset[i], self.k0, self.stiffening)


@dataclass(frozen=True)
class ExponentialLocationFit:
    """Exponential law of one location from its trials.

    Mirrors :class:`~phri_spring.physics.indentation.linear.LocationFit` (same names for
    ``location``, ``trials``, ``stiffness``, ``std``, ``spread``, ``r2_min``,
    ``flags``), so that reports draw either.

    Attributes
    ----------
    linear : LocationFit
        The linear analysis of the same trials (loading slope, hysteresis, peaks).
    fits : tuple of ExponentialFit
        One per trial, in the order of ``linear.trials``.
    trial_stiffness, trial_stiffening : ndarray, shape (n_trials,)
        k0 [N/m] and beta [1/m] of the trials whose fit converged.
    stiffness : float
        Mean of k0 over those trials [N/m].
    std : float
        Sample SD (ddof = 1, NaN for one trial) of k0 over those trials [N/m].
    stiffening, stiffening_std : float
        The same for beta [1/m].
    spread : float
        ``(max - min) / mean`` of the trials' k0 [-].
    r2_min : float
        Lowest R^2 of the exponential fits [-].
    flags : tuple of str
        ``low_r2``, ``trial_spread``, ``single_trial`` as for the linear fit, and
        ``stiffening_bound`` (a trial's beta on its bound), ``fit_failed``.
    """

    linear: LocationFit
    fits: tuple
    trial_stiffness: np.ndarray
    trial_stiffening: np.ndarray
    stiffness: float
    std: float
    stiffening: float
    stiffening_std: float
    spread: float
    r2_min: float
    flags: tuple = field(default_factory=tuple)

    @property
    def location(self) -> str:
        return self.linear.location

    @property
    def trials(self) -> tuple:
        return self.linear.trials

    @property
    def trial_ids(self) -> np.ndarray:
        return self.linear.trial_ids

    @property
    def n_trials(self) -> int:
        """Trials whose fit converged (those in the means)."""
        return int(self.trial_stiffness.size)


# --------------------------------------------------------------------------- the law


def law_force(compression, k0: float, stiffening: float) -> np.ndarray:
    """F = (k0/beta)(exp(beta d) - 1) for d > 0, else 0 [N]: the tissue law's own formula."""
    return ExponentialLaw([k0], stiffening=stiffening).force(np.asarray(compression, float))


def _dforce_dbeta(dp: np.ndarray, beta: float) -> np.ndarray:
    """dF/dbeta / k0 = dp^2 ((x - 1) expm1(x) + x) / x^2, x = beta dp [m^2].

    The closed form cancels where x is small; its Taylor series is used there.
    """
    x = beta * dp
    small = x < 1e-3
    with np.errstate(over="ignore", invalid="ignore"):
        xs = np.where(small, 1.0, x)
        g = np.where(small, 0.5 + x / 3.0 + x * x / 8.0 + x ** 3 / 30.0,
                     ((xs - 1.0) * np.expm1(xs) + xs) / (xs * xs))
    return dp * dp * g


def _r2(res: np.ndarray, f: np.ndarray) -> float:
    dy = f - f.mean()
    ss_tot = float(dy @ dy)
    return 1.0 - float(res @ res) / ss_tot if ss_tot > 0 else float("nan")


# --------------------------------------------------------------------------- fitting


def _stack(depths, forces):
    d = [np.asarray(x, dtype=float).ravel() for x in depths]
    f = [np.asarray(y, dtype=float).ravel() for y in forces]
    if not d or len(d) != len(f) or any(a.size != b.size or a.size < 3 for a, b in zip(d, f)):
        raise ValueError("expected one (depth, force) pair of equal lengths >= 3 per stroke")
    idx = np.concatenate([np.full(a.size, i) for i, a in enumerate(d)])
    return d, f, np.concatenate(d), np.concatenate(f), idx


def start_estimate(depths, forces) -> tuple[float, float, np.ndarray]:
    """Start of the fit: (k0 [N/m], beta [1/m], d0 per stroke [m]) by linear least squares.

    Parameters
    ----------
    depths, forces : sequence of array_like
        One array per unloading stroke: depth [m] and force [N], in time order.

    Returns
    -------
    k0, beta, offsets
        From F = k0 d + beta G(d) + c_s (G the running trapezoid integral of F dd
        along the stroke, c_s one constant per stroke), which the law satisfies
        exactly; beta = 0 and the common slope of straight lines when that gives
        beta < 0 or k0 <= 0. The offsets invert the law at every sample (median).
    """
    d, f, d_all, f_all, idx = _stack(depths, forces)
    n = len(d)
    g_all = np.concatenate([np.concatenate([[0.0], np.cumsum(0.5 * (b[1:] + b[:-1])
                                                             * np.diff(a))])
                            for a, b in zip(d, f)])
    one_hot = (idx[:, None] == np.arange(n)[None, :]).astype(float)

    def lstsq(cols):
        a = np.column_stack(cols + [one_hot])
        norm = np.linalg.norm(a, axis=0)
        norm[norm == 0] = 1.0
        coef = np.linalg.lstsq(a / norm, f_all, rcond=None)[0] / norm
        return coef

    coef = lstsq([d_all, g_all])
    k0, beta = float(coef[0]), float(coef[1])
    if not (np.isfinite(k0) and np.isfinite(beta) and k0 > 0 and beta >= 0):
        k0, beta = float(lstsq([d_all])[0]), 0.0
    if not (np.isfinite(k0) and k0 > 0):
        span = float(np.ptp(d_all)) or 1.0
        k0 = max(float(np.ptp(f_all)) / span, 1e-9)
    law = ExponentialLaw([k0], stiffening=beta)
    offsets = np.array([float(np.median(a[b > 0] - law.compression_at(b[b > 0])))
                        if (b > 0).any() else float(a.min()) for a, b in zip(d, f)])
    return k0, beta, offsets


def fit_branches(depths, forces, *, noise_sd: float = 0.0, start=None) -> dict:
    """Fit the exponential law to unloading strokes: one k0 and beta, one d0 per stroke.

    Parameters
    ----------
    depths, forces : sequence of array_like
        One array per stroke: depth [m] and zeroed force [N], only samples in contact.
    noise_sd : float
        Force noise SD [N] (the zero window's); floor of the robust loss's scale.
    start : (float, float, array_like), optional
        (k0, beta, offsets) to start from; default :func:`start_estimate`.

    Returns
    -------
    dict
        ``k0`` [N/m], ``stiffening`` [1/m], ``offset`` (n,) [m], ``r2`` (n,) [-],
        ``status`` (``ok``, ``at_bound``, ``failed``) and ``message``.
    """
    from scipy.optimize import least_squares

    d, f, d_all, f_all, idx = _stack(depths, forces)
    n = len(d)
    k_ref, beta0, off0 = start_estimate(d, f) if start is None else start
    off0 = np.asarray(off0, dtype=float).copy()
    span = max(max(float(np.ptp(a)) for a in d), 1e-9)
    d_min = np.array([float(a.min()) for a in d])
    rows = np.arange(d_all.size)

    # scaled parameters p = (k0 / k_ref, beta * span, (d0 - off0) / span): all of order 1
    lower = np.concatenate([[1e-9, 0.0], (d_min - _OFFSET_SPANS * span - off0) / span])
    upper = np.concatenate([[np.inf, BETA_SPAN_MAX], (d_min - off0) / span])
    off0 = np.minimum(off0, d_min)          # a contact point below every sample of its stroke
    p0 = np.concatenate([[1.0, min(beta0 * span, 0.5 * BETA_SPAN_MAX)], np.zeros(n)])
    p0 = np.clip(p0, lower, upper)

    def unpack(p):
        return p[0] * k_ref, p[1] / span, off0 + p[2:] * span

    def residual(p):
        k0, beta, off = unpack(p)
        return law_force(d_all - off[idx], k0, beta) - f_all

    def jacobian(p):
        k0, beta, off = unpack(p)
        unit = ExponentialLaw([1.0], stiffening=beta)
        dp = np.maximum(d_all - off[idx], 0.0)
        jac = np.zeros((d_all.size, 2 + n))
        jac[:, 0] = unit.force(dp) * k_ref
        jac[:, 1] = k0 * _dforce_dbeta(dp, beta) / span
        jac[rows, 2 + idx] = -k0 * np.where(dp > 0, unit.tangent(dp), 0.0) * span
        return jac

    opts = dict(jac=jacobian, bounds=(lower, upper), method="trf", x_scale=1.0,
                ftol=1e-12, xtol=1e-12, gtol=1e-12, max_nfev=200 * (2 + n))
    fail = {"k0": float("nan"), "stiffening": float("nan"), "offset": np.full(n, np.nan),
            "r2": np.full(n, np.nan), "status": "failed"}
    try:
        first = least_squares(residual, p0, **opts)
        mad = float(np.median(np.abs(first.fun - np.median(first.fun))))
        scale = max(_ROBUST_SDS * 1.4826 * mad, _ROBUST_SDS * float(noise_sd),
                    1e-9 * max(float(np.abs(f_all).max()), 1.0))
        res = least_squares(residual, first.x, loss="soft_l1", f_scale=scale, **opts)
    except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
        return {**fail, "message": f"the optimiser stopped ({exc})"}
    if res.status <= 0 or not np.isfinite(res.x).all():
        return {**fail, "message": f"no convergence after {res.nfev} evaluations "
                                   f"({res.message})"}
    k0, beta, off = unpack(res.x)
    r = res.fun
    r2 = np.array([_r2(r[idx == i], f[i]) for i in range(n)])
    status, message = "ok", ""
    if beta <= 0.0 or res.active_mask[1] < 0:
        beta = 0.0           # the optimiser stays a hair inside its bounds: report the bound
        status, message = "at_bound", "stiffening on its bound 0 1/m: no stiffening found"
    elif res.active_mask[1] > 0:
        status = "at_bound"
        message = (f"stiffening on its bound {BETA_SPAN_MAX:g} / depth span "
                   f"({BETA_SPAN_MAX / span:.4g} 1/m)")
    return {"k0": float(k0), "stiffening": float(beta), "offset": off, "r2": r2,
            "status": status, "message": message}


def fit_trial_exponential(trial: TrialFit) -> ExponentialFit:
    """Fit the exponential law to a trial's unloading strokes (the linear fits' ranges).

    Parameters
    ----------
    trial : TrialFit
        From :func:`~phri_spring.physics.indentation.linear.fit_trial`.

    Returns
    -------
    ExponentialFit
        Never raises for a fit that fails: its ``status`` says so.
    """
    u = trial.unloading
    depths = [trial.depth[s0:s1] for s0, s1 in zip(u.start, u.stop)]
    forces = [trial.force[s0:s1] for s0, s1 in zip(u.start, u.stop)]
    out = fit_branches(depths, forces, noise_sd=trial.noise_sd)
    return ExponentialFit(trial=trial, k0=out["k0"], stiffening=out["stiffening"],
                          offset=np.asarray(out["offset"], dtype=float),
                          r2=np.asarray(out["r2"], dtype=float), status=out["status"],
                          message=out["message"])


def fit_location_exponential(fits, linear: LocationFit, *, min_r2: float,
                             max_spread: float) -> ExponentialLocationFit:
    """Aggregate the exponential fits of one location's trials.

    Parameters
    ----------
    fits : sequence of ExponentialFit
        One per trial of ``linear``, same order.
    linear : LocationFit
        The location's linear analysis.
    min_r2 : float
        Flag ``low_r2`` when an exponential fit's R^2 is below this [-].
    max_spread : float
        Flag ``trial_spread`` when ``(max - min) / mean`` of k0 exceeds this [-].

    Returns
    -------
    ExponentialLocationFit
        Means and sample SDs (ddof = 1) over the converged trials: the SD is the
        trial-to-trial scatter (placement of the indenter, the hand), NaN for a
        single trial. With no converged trial the values are NaN.
    """
    fits = tuple(fits)
    ok = [ft for ft in fits if ft.converged]
    k0 = np.array([ft.k0 for ft in ok], dtype=float)
    beta = np.array([ft.stiffening for ft in ok], dtype=float)
    k_mean, k_std, n = location_statistics(k0)
    b_mean, b_std, _ = location_statistics(beta)
    spread = trial_spread(k0) if n else float("nan")
    r2_min = float(min(ft.r2_min for ft in ok)) if ok else float("nan")
    flags = []
    if n and not r2_min >= min_r2:
        flags.append("low_r2")
    if spread > max_spread:
        flags.append("trial_spread")
    if n == 1:
        flags.append("single_trial")
    if any(ft.status == "at_bound" for ft in fits):
        flags.append("stiffening_bound")
    if len(ok) < len(fits):
        flags.append("fit_failed")
    return ExponentialLocationFit(
        linear=linear, fits=fits, trial_stiffness=k0, trial_stiffening=beta,
        stiffness=k_mean, std=k_std, stiffening=b_mean, stiffening_std=b_std,
        spread=spread, r2_min=r2_min, flags=tuple(flags))
