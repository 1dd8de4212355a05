"""Quasi-linear viscoelastic (QLV) tissue fitted to indenter trials over time.

The model of a trial (Fung's QLV, :mod:`phri_spring.physics.history.relaxation`): the elastic
(instantaneous) response to the measured depth d(t_n),

    F^e(d) = k x                          (linear),   or
    F^e(d) = (k / beta) (exp(beta x) - 1) (exponential),   x = max(d - d_c, 0),

d_c the contact point of the trial, is filtered by the reduced relaxation function
G(t) = 1 - sum_i g_i (1 - exp(-t / tau_i)): F(t_n) = G_inf F^e_n + sum_i g_i h_i(t_n), with the
memory terms h_i updated sample by sample by the exact recursion of
:func:`~phri_spring.physics.history.relaxation.step_coefficients` (F^e linear between samples),
starting from a rested tissue (h_i = 0) at the first sample of the window
(:mod:`phri_spring.physics.indentation.qlv_window`).

**The fit** (one per location, its trials together, by least squares over every sample of
their windows). For given relaxation times, stiffening rate and contact points, the force is
linear in c_0 = k G_inf and c_i = k g_i, and g_i >= 0, sum g_i < 1 is exactly c >= 0; so the
c are solved by non-negative least squares (``scipy.optimize.nnls``) inside the residual
(variable projection), and the outer bounded least squares (``scipy.optimize.least_squares``)
moves only log tau_i, beta and the contact points. It starts from the best few points of a
log grid of relaxation times (and of beta), scanned first. Then k = sum c and g_i = c_i / k.

Everything here is pure numpy/scipy on arrays in SI units; no files, no printing.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..history.relaxation import Prony, step_coefficients

__all__ = ["ELASTIC_LAWS", "DEFAULT_TERMS", "MAX_TERMS", "QlvFit", "QlvLocationFit",
           "elastic_force", "memory_terms", "qlv_force", "fit_qlv"]

#: elastic (instantaneous) parts the QLV fit knows
ELASTIC_LAWS = ("linear", "exponential")
#: Prony terms fitted unless told otherwise
DEFAULT_TERMS = 2
#: most Prony terms the fit accepts
MAX_TERMS = 4
#: points per decade of the scanned log grid of relaxation times
_GRID_PER_DECADE = 3
#: beta x peak depth values scanned for the exponential part [-]
_BETA_GRID = (0.0, 0.5, 1.0, 2.0, 4.0)
#: upper bound of beta x peak depth [-]
_BETA_SPAN_MAX = 40.0
#: local fits started from the best grid points
_STARTS = 3
#: memory terms are summed in blocks over which t / tau grows by at most this [-]:
#: exp(_BLOCK_SPAN) stays far from overflow
_BLOCK_SPAN = 50.0
#: an optimum closer than this to a bound of log tau or beta counts as on the bound
_AT_BOUND = 1e-3


def elastic_force(depth, stiffness: float, stiffening: float = 0.0) -> np.ndarray:
    """F^e [N] of compression ``max(depth, 0)`` [m]: k x, or (k/beta)(exp(beta x) - 1)."""
    x = np.maximum(np.asarray(depth, dtype=float), 0.0)
    if stiffening > 0:
        return stiffness * np.expm1(stiffening * x) / stiffening
    return stiffness * x


def memory_terms(time, Fe, times_s) -> np.ndarray:
    """The memory terms h_i(t_n), shape (m, terms), of an elastic history F^e (m,).

    h_0 = 0 (rested tissue), then h_n = a_n h_{n-1} + b_n (F^e_n - F^e_{n-1}) with (a, b) of
    :func:`~phri_spring.physics.history.relaxation.step_coefficients`. Unrolled, h_n =
    sum_k (a_{k+1} ... a_n) u_k with u_k = b_k dF^e_k and a_j = exp(-dt_j / tau): so over a
    block of samples s..n after sample s-1, h_n = exp(-(t_n - t_{s-1})/tau) h_{s-1}
    + exp(-(t_n - t_s)/tau) sum_{s<=k<=n} exp((t_k - t_s)/tau) u_k, a cumulative sum: the same
    recursion, vectorised, in blocks short enough for exp not to overflow.
    """
    t = np.asarray(time, dtype=float)
    fe = np.asarray(Fe, dtype=float)
    tau = np.atleast_1d(np.asarray(times_s, dtype=float))
    m = t.size
    out = np.zeros((m, tau.size))
    if m < 2:
        return out
    dt = np.diff(t)
    # a valid series only to reuse the exact coefficients; the fractions do not enter them
    _, b = step_coefficients(Prony(np.zeros(tau.size), tau), dt)
    u = b * np.diff(fe)[:, None]                        # (m-1, terms)
    for i, ti in enumerate(tau):
        x = (t - t[0]) / ti                             # cumulative dt / tau
        h_prev, n0 = 0.0, 0                             # h at sample n0
        while n0 < m - 1:
            s = n0 + 1                                  # the block: samples s .. n1-1
            n1 = int(np.searchsorted(x, x[s] + _BLOCK_SPAN, side="right"))
            rel = x[s:n1] - x[s]
            acc = np.cumsum(np.exp(rel) * u[n0:n1 - 1, i])
            out[s:n1, i] = np.exp(-(x[s:n1] - x[n0])) * h_prev + np.exp(-rel) * acc
            h_prev, n0 = out[n1 - 1, i], n1 - 1
    return out


def qlv_force(time, depth, stiffness: float, prony: Prony, stiffening: float = 0.0,
              contact: float = 0.0) -> np.ndarray:
    """The QLV force [N] of a trial at every sample, tissue rested before the first one.

    Parameters
    ----------
    time : array_like, shape (m,)
        Increasing [s].
    depth : array_like, shape (m,)
        Measured depth [m]; compression is ``depth - contact`` where positive.
    stiffness : float
        k [N/m] of the elastic part (the slope at contact with ``stiffening``).
    prony : Prony
        The reduced relaxation function.
    stiffening : float
        beta [1/m]; 0 for the linear elastic part.
    contact : float
        Depth at which the indenter touches [m].
    """
    fe = elastic_force(np.asarray(depth, dtype=float) - contact, stiffness, stiffening)
    h = memory_terms(time, fe, prony.tau)
    return prony.relaxed * fe + h @ prony.g


@dataclass(frozen=True)
class QlvFit:
    """A QLV fit of one location's trials.

    Attributes
    ----------
    stiffness : float
        k [N/m], the instantaneous elastic stiffness (slope at contact if exponential).
    stiffening : float
        beta [1/m]; 0 for the linear elastic part.
    prony : Prony or None
        Relaxation, terms sorted by time; None if the fit failed.
    contacts : ndarray
        Contact point of each trial, depth from its onset sample [m].
    r2 : ndarray
        R^2 of the model force over each trial's window.
    rms : float
        Root-mean-square residual over all windows [N].
    status : str
        ``ok``, ``at_bound`` (a time or beta on its bound) or ``failed``.
    message : str
        Why, for ``at_bound`` and ``failed``.
    elastic : str
        ``linear`` or ``exponential``.
    """

    stiffness: float
    stiffening: float
    prony: Prony | None
    contacts: np.ndarray
    r2: np.ndarray
    rms: float
    status: str
    message: str = ""
    elastic: str = "linear"

    @property
    def fractions(self) -> np.ndarray:
        return self.prony.g if self.prony is not None else np.array([])

    @property
    def times_s(self) -> np.ndarray:
        return self.prony.tau if self.prony is not None else np.array([])

    @property
    def r2_min(self) -> float:
        return float(np.min(self.r2)) if self.r2.size else float("nan")

    def model(self, window, index: int) -> np.ndarray:
        """Model force [N] over ``window``, the ``index``-th of those fitted."""
        if self.prony is None:
            return np.full(window.time.shape, np.nan)
        return qlv_force(window.time, window.depth, self.stiffness, self.prony,
                         self.stiffening, float(self.contacts[index]))


@dataclass(frozen=True)
class QlvLocationFit:
    """The QLV fit of one location with the windows it was fitted to.

    ``stiffness`` is k [N/m]; ``std`` is NaN (one joint fit, no spread between trials).
    """

    location: str
    trial_ids: np.ndarray
    windows: tuple
    fit: QlvFit
    flags: tuple = ()

    @property
    def stiffness(self) -> float:
        return self.fit.stiffness

    @property
    def stiffening(self) -> float:
        return self.fit.stiffening

    @property
    def std(self) -> float:
        return float("nan")

    @property
    def n_trials(self) -> int:
        return len(self.windows)

    @property
    def r2_min(self) -> float:
        return self.fit.r2_min


def _design(windows, log_tau, beta_span, contacts):
    """Stacked columns [F^e/k, h_1/k, ...] and forces of all windows."""
    tau = np.exp(log_tau)
    cols, rhs = [], []
    for w, c in zip(windows, contacts):
        beta = beta_span / w.scale
        fe = elastic_force(w.depth - c * w.scale, 1.0, beta)
        cols.append(np.column_stack([fe, memory_terms(w.time, fe, tau)]))
        rhs.append(w.force)
    return np.vstack(cols), np.concatenate(rhs)


class _Scaled:
    """A window with its depth scale (the peak depth of the location's trials)."""

    def __init__(self, w, scale):
        self.time, self.depth, self.force, self.scale = w.time, w.depth, w.force, scale


def _solve(windows, p, terms, exponential):
    from scipy.optimize import nnls

    log_tau = p[:terms]
    beta_span = p[terms] if exponential else 0.0
    contacts = p[terms + int(exponential):]
    A, y = _design(windows, log_tau, beta_span, contacts)
    norms = np.linalg.norm(A, axis=0)
    norms[norms == 0] = 1.0
    c, _ = nnls(A / norms, y)
    c = c / norms
    return c, A @ c - y


def fit_qlv(windows, *, terms: int = DEFAULT_TERMS, elastic: str = "linear") -> QlvFit:
    """Fit k (and beta), the Prony fractions and times to a location's trials.

    Parameters
    ----------
    windows : sequence of QlvWindow
        The trials' windows (:func:`~phri_spring.physics.indentation.qlv_window.qlv_window`).
    terms : int
        Prony terms, 1 to :data:`MAX_TERMS`.
    elastic : {'linear', 'exponential'}
        The elastic part.

    Returns
    -------
    QlvFit
        ``status`` says whether the fit is trustworthy; it never raises on a bad fit.

    Raises
    ------
    ValueError
        Bad ``terms`` or ``elastic``.
    """
    from scipy.optimize import least_squares

    if elastic not in ELASTIC_LAWS:
        raise ValueError(f"elastic: expected one of {', '.join(ELASTIC_LAWS)}, got {elastic!r}")
    if not (isinstance(terms, (int, np.integer)) and 1 <= terms <= MAX_TERMS):
        raise ValueError(f"terms: expected an integer from 1 to {MAX_TERMS}, got {terms!r}")
    windows = list(windows)
    if not windows:
        raise ValueError("fit_qlv needs at least one window")
    exponential = elastic == "exponential"
    scale = max(w.peak_depth for w in windows)
    scaled = [_Scaled(w, scale) for w in windows]
    dts = np.concatenate([np.diff(w.time) for w in windows])
    span = max(float(w.time[-1] - w.time[0]) for w in windows)
    lo_tau, hi_tau = np.log(float(np.median(dts))), np.log(3.0 * span)
    # contact point between the window's first sample and a little past the onset
    c_lo = np.array([min(float(w.depth[:w.onset + 1].min()), 0.0) / scale for w in windows])
    c_hi = np.full(len(windows), 0.05)
    lower = np.concatenate([np.full(terms, lo_tau), [0.0] * exponential, c_lo])
    upper = np.concatenate([np.full(terms, hi_tau), [_BETA_SPAN_MAX] * exponential, c_hi])

    # scan: every combination of distinct grid times, every beta, contacts at the onset
    n_grid = max(int(np.ceil((hi_tau - lo_tau) / np.log(10) * _GRID_PER_DECADE)) + 1, terms)
    grid = np.linspace(lo_tau, hi_tau, n_grid + 2)[1:-1]
    betas = _BETA_GRID if exponential else (None,)
    scanned = []
    for combo in itertools.combinations(grid, terms):
        for b in betas:
            p = np.concatenate([combo, [b] * exponential, np.zeros(len(windows))])
            try:
                _, r = _solve(scaled, p, terms, exponential)
            except (ValueError, RuntimeError):          # a non-finite design: skip the point
                continue
            cost = float(r @ r)
            if np.isfinite(cost):
                scanned.append((cost, p))
    scanned.sort(key=lambda s: s[0])

    def residual(p):
        return _solve(scaled, p, terms, exponential)[1]

    best = None
    for _, p0 in scanned[:_STARTS]:
        p0 = np.clip(p0, lower, upper)
        try:
            sol = least_squares(residual, p0, bounds=(lower, upper), x_scale=1.0,
                                diff_step=1e-6, xtol=1e-10, ftol=1e-12, gtol=1e-10,
                                max_nfev=200 * (len(p0) + 1))
        except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:  # non-finite
            if best is None:
                best = (np.inf, None, str(exc))
            continue
        if best is None or best[1] is None or sol.cost < best[0]:
            best = (float(sol.cost), sol, "")
    cost, sol, why = best if best is not None else (np.inf, None, "no finite start")
    nan = float("nan")
    if sol is None:
        return QlvFit(nan, nan, None, np.full(len(windows), nan), np.full(len(windows), nan),
                      nan, "failed", why or "no start converged", elastic)
    p = sol.x
    c, _ = _solve(scaled, p, terms, exponential)
    k = float(c.sum())
    if not k > 0:
        return QlvFit(nan, nan, None, np.full(len(windows), nan), np.full(len(windows), nan),
                      nan, "failed", "no positive stiffness fits the trials", elastic)
    tau = np.exp(p[:terms])
    g = c[1:] / k
    order = np.argsort(tau)
    prony = Prony(g[order], tau[order])
    beta = float(p[terms] / scale) if exponential else 0.0
    contacts = p[terms + int(exponential):] * scale
    r2, res_all = [], []
    for w, dc in zip(windows, contacts):
        model = qlv_force(w.time, w.depth, k, prony, beta, dc)
        res = model - w.force
        ss = float(((w.force - w.force.mean()) ** 2).sum())
        r2.append(1.0 - float(res @ res) / ss if ss > 0 else nan)
        res_all.append(res)
    res_all = np.concatenate(res_all)
    status, message = "ok", ""
    on_bound = []
    for i in range(terms):
        if c[1 + i] > 0 and (p[i] - lo_tau < _AT_BOUND or hi_tau - p[i] < _AT_BOUND):
            on_bound.append(f"relaxation time {tau[i]:.3g} s on its bound "
                            f"[{np.exp(lo_tau):.3g}, {np.exp(hi_tau):.3g}] s")
    if exponential and _BETA_SPAN_MAX - p[terms] < _AT_BOUND:
        on_bound.append(f"stiffening {beta:.3g} 1/m on its bound")
    if on_bound:
        status, message = "at_bound", "; ".join(on_bound)
    return QlvFit(stiffness=k, stiffening=beta, prony=prony, contacts=contacts,
                  r2=np.asarray(r2), rms=float(np.sqrt(np.mean(res_all ** 2))), status=status,
                  message=message, elastic=elastic)

