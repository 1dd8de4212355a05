"""Indenter force-displacement analysis (docs/model.md section 7; paper sections II-B and IV-A).

A flat cylindrical indenter is pushed by hand into the arm while a force sensor
and a linear encoder are logged. The tissue stiffness at that location is the
slope of the unloading part of the force-displacement curve:

1. **Zeroing.** The force is zeroed by its mean over the first ``zero_window``
   seconds, when the indenter is at rest (:func:`zero_level`).
2. **Onset.** Indentation begins at the first sample whose zeroed force exceeds
   a difference threshold (:func:`detect_onset`). The default threshold is
   ``max(ONSET_SIGMAS * s, ONSET_FLOOR)``, with s the sample standard deviation of
   the force in the zero window: 5 s makes a false onset from Gaussian noise
   practically impossible (p < 3e-7 per sample), and the floor of 0.05 N keeps
   a noiseless or coarsely quantised force signal from triggering on the
   smallest step (:func:`default_onset_threshold`).
3. **Depth.** The displacement is measured from its value at onset (positive
   into the arm; an encoder that counts the other way is detected from the sign
   of the displacement at peak force and flipped).
4. **Strokes.** The depth signal is split at its maxima and minima with a
   hysteresis (zig-zag) rule (:func:`turning_points`): a maximum is confirmed
   only once the depth has come back from it by at least ``reversal``, so that
   encoder steps (0.025 mm) and hand tremor do not split a stroke. A trial may
   hold one push or several. The loading stroke of a push runs from the
   preceding minimum to the first sample at the maximum; its unloading stroke
   from the last sample at the maximum to the next minimum.
5. **Fits.** A straight line ``F = k d + b`` is fitted by least squares to each
   unloading stroke while the indenter is in contact: from the start of the
   stroke up to (not including) the first sample whose zeroed force is at or
   below the onset threshold (:func:`fit_line`). The same is done on each
   loading stroke (backwards from its maximum) for the quality report.
6. **Trial stiffness** = mean of its unloading slopes; **location stiffness** =
   mean over its trials, with the sample standard deviation (ddof = 1; NaN for a
   single trial) (:func:`fit_location`).

Quality metrics: the coefficient of determination R^2 of every unloading fit,
the loading slope, the hysteresis ratio ``(W_load - W_unload) / W_load`` with
``W = integral F dd`` over a stroke in contact (the area between the loading
and the unloading curves over the loading work), the peak force and the peak
depth.

Everything here is pure numpy on arrays in SI units (s, m, N, N/m); no files,
no printing. Bad trials raise :class:`TrialError` (a ``ValueError``) naming the
offending quantity; the I/O layer adds the file. Steps 1 to 4 (zeroing, onset,
strokes) live in :mod:`phri_spring.physics.indentation.signal` (re-exported here).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .signal import (ONSET_FLOOR, ONSET_SIGMAS, REST_TREND_SIGMAS,
                                 REVERSAL_FLOOR, REVERSAL_FRACTION, TrialError, as_1d,
                                 check_at_rest, default_onset_threshold, detect_onset,
                                 split_strokes, turning_points, window_trend, zero_level)

__all__ = [
    "TrialError", "LinearFits", "TrialFit", "LocationFit",
    "ONSET_SIGMAS", "ONSET_FLOOR", "REST_TREND_SIGMAS", "REVERSAL_FLOOR", "REVERSAL_FRACTION",
    "MIN_FIT_POINTS", "DEFAULT_MIN_R2", "DEFAULT_MAX_SPREAD",
    "zero_level", "window_trend", "check_at_rest", "default_onset_threshold", "detect_onset",
    "turning_points",
    "split_strokes", "fit_line", "stroke_work", "fit_trial", "fit_location",
    "location_statistics", "trial_spread",
]

#: an unloading (or loading) fit needs at least this many samples in contact
MIN_FIT_POINTS = 5
#: unloading fits with R^2 below this are flagged ``low_r2``
DEFAULT_MIN_R2 = 0.98
#: locations whose trials differ by more than this fraction of their mean are flagged
DEFAULT_MAX_SPREAD = 0.10

_trapezoid = getattr(np, "trapezoid", None) or getattr(np, "trapz")


# --------------------------------------------------------------------------- dataclasses


@dataclass(frozen=True)
class LinearFits:
    """Straight-line fits ``F = slope * d + intercept``, one entry per stroke.

    Attributes
    ----------
    slope : ndarray of float, shape (n,)
        Slope [N/m]; NaN where the stroke had too few samples in contact.
    intercept : ndarray of float, shape (n,)
        Force at zero depth [N].
    r2 : ndarray of float, shape (n,)
        Coefficient of determination of the fit [-].
    start, stop : ndarray of int, shape (n,)
        Sample range of the fit, ``start:stop`` (stop exclusive) into the trial arrays.
    """

    slope: np.ndarray
    intercept: np.ndarray
    r2: np.ndarray
    start: np.ndarray
    stop: np.ndarray

    @property
    def n(self) -> int:
        return int(self.slope.size)


@dataclass(frozen=True)
class TrialFit:
    """Analysis of one indentation trial.

    The per-push arrays (:attr:`unloading`, :attr:`loading`, :attr:`hysteresis`,
    :attr:`peak_index`) have one entry per push with a valid unloading fit.

    Attributes
    ----------
    time : ndarray, shape (m,)
        Sample times [s].
    depth : ndarray, shape (m,)
        Displacement from its value at onset, positive into the arm [m].
    force : ndarray, shape (m,)
        Zeroed force [N].
    zero_level : float
        Mean raw force over the zero window [N].
    noise_sd : float
        Sample standard deviation of the force over the zero window [N].
    threshold : float
        Onset / contact threshold on the zeroed force [N].
    onset_index : int
        First sample whose zeroed force exceeds :attr:`threshold`.
    sign : int
        +1, or -1 when the encoder counts away from the arm (depth = -displacement).
    reversal : float
        Depth reversal that ends a stroke [m].
    peak_index : ndarray of int, shape (n,)
        First sample at each push's maximum depth.
    unloading : LinearFits
        Fits of the unloading strokes (these give the stiffness).
    loading : LinearFits
        Fits of the loading strokes (quality report only).
    hysteresis : ndarray, shape (n,)
        ``(W_load - W_unload) / W_load`` per push [-]; NaN where not defined.
    """

    time: np.ndarray
    depth: np.ndarray
    force: np.ndarray
    zero_level: float
    noise_sd: float
    threshold: float
    onset_index: int
    sign: int
    reversal: float
    peak_index: np.ndarray
    unloading: LinearFits
    loading: LinearFits
    hysteresis: np.ndarray

    @property
    def onset_time(self) -> float:
        """Time of the onset sample [s]."""
        return float(self.time[self.onset_index])

    @property
    def n_strokes(self) -> int:
        """Number of unloading strokes fitted."""
        return self.unloading.n

    @property
    def stiffness(self) -> float:
        """Trial stiffness = mean of the unloading slopes [N/m]."""
        return float(np.mean(self.unloading.slope))

    @property
    def loading_slope(self) -> float:
        """Mean slope of the loading strokes [N/m] (NaN if none could be fitted)."""
        return _nanmean(self.loading.slope)

    @property
    def r2_min(self) -> float:
        """Worst (lowest) R^2 of the unloading fits [-]."""
        return float(np.min(self.unloading.r2))

    @property
    def hysteresis_ratio(self) -> float:
        """Mean hysteresis ratio over the pushes [-] (NaN if none defined)."""
        return _nanmean(self.hysteresis)

    @property
    def peak_force(self) -> float:
        """Largest zeroed force [N]."""
        return float(np.max(self.force))

    @property
    def peak_depth(self) -> float:
        """Largest depth from onset [m]."""
        return float(np.max(self.depth))

    @property
    def sampling_rate(self) -> float:
        """Mean sampling rate [Hz]."""
        span = float(self.time[-1] - self.time[0])
        return (self.time.size - 1) / span if span > 0 else float("nan")


@dataclass(frozen=True)
class LocationFit:
    """Stiffness of one location from its trials.

    Attributes
    ----------
    location : str
        Element label (``B3``), or any name.
    trial_ids : ndarray of int, shape (n_trials,)
        Trial numbers, in the order of :attr:`trials`.
    trials : tuple of TrialFit
        The trial analyses.
    trial_stiffness : ndarray, shape (n_trials,)
        Stiffness of each trial [N/m].
    stiffness : float
        Mean of :attr:`trial_stiffness` [N/m].
    std : float
        Sample standard deviation (ddof = 1) of :attr:`trial_stiffness` [N/m];
        NaN for a single trial (no spread can be estimated from one value).
    spread : float
        ``(max - min) / mean`` of the trial stiffnesses [-]; 0 for one trial.
    r2_min : float
        Lowest R^2 of all unloading fits [-].
    loading_slope : float
        Mean of the trials' loading slopes [N/m].
    hysteresis_ratio : float
        Mean of the trials' hysteresis ratios [-].
    peak_force : float
        Largest force over the trials [N].
    peak_depth : float
        Largest depth over the trials [m].
    n_strokes : int
        Unloading strokes fitted, over all trials.
    flags : tuple of str
        ``low_r2`` (r2_min below the threshold), ``trial_spread`` (spread above the
        allowed fraction), ``single_trial`` (only one trial).
    """

    location: str
    trial_ids: np.ndarray
    trials: tuple
    trial_stiffness: np.ndarray
    stiffness: float
    std: float
    spread: float
    r2_min: float
    loading_slope: float
    hysteresis_ratio: float
    peak_force: float
    peak_depth: float
    n_strokes: int
    flags: tuple = field(default_factory=tuple)

    @property
    def n_trials(self) -> int:
        return int(self.trial_stiffness.size)


# --------------------------------------------------------------------------- helpers


def _nanmean(values) -> float:
    """Mean of the finite values, NaN (without a RuntimeWarning) when there are none."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else float("nan")


def fit_line(x, y) -> tuple[float, float, float]:
    """Least-squares line ``y = slope * x + intercept`` and its R^2.

    Parameters
    ----------
    x : array_like
        Abscissa (depth [m]).
    y : array_like
        Ordinate (force [N]).

    Returns
    -------
    slope, intercept, r2 : float
        Slope [N/m], intercept [N] and coefficient of determination [-]
        (``1 - SS_res / SS_tot``; NaN when y is constant).
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    xm, ym = x.mean(), y.mean()
    dx, dy = x - xm, y - ym
    sxx = float(dx @ dx)
    if sxx <= 0:
        return float("nan"), float("nan"), float("nan")
    slope = float(dx @ dy) / sxx
    intercept = float(ym - slope * xm)
    ss_tot = float(dy @ dy)
    res = dy - slope * dx
    r2 = 1.0 - float(res @ res) / ss_tot if ss_tot > 0 else float("nan")
    return slope, intercept, r2


def stroke_work(depth, force, in_contact) -> float:
    """Work ``integral F dd`` along a stroke, counting force only in contact [J].

    Parameters
    ----------
    depth : array_like
        Depth along the stroke [m].
    force : array_like
        Zeroed force [N].
    in_contact : array_like of bool
        Samples in contact; the force of the others counts as zero.

    Returns
    -------
    float
        Signed trapezoidal integral: positive along a loading stroke, negative
        along an unloading stroke.
    """
    f = np.where(np.asarray(in_contact, bool), np.asarray(force, float), 0.0)
    return float(_trapezoid(f, np.asarray(depth, float)))


def _contact_run(force, start: int, stop: int, threshold: float, backwards: bool):
    """Contiguous in-contact range next to ``start`` (forwards) or ``stop - 1`` (backwards)."""
    seg = np.asarray(force[start:stop]) > threshold
    if backwards:
        seg = seg[::-1]
    if seg.size == 0 or not seg[0]:
        return None
    off = np.flatnonzero(~seg)
    n = int(off[0]) if off.size else seg.size
    return (start, start + n) if not backwards else (stop - n, stop)


def fit_trial(time, displacement, force, *, zero_window: float = 3.0,
              onset_threshold: float | None = None, reversal: float | None = None,
              min_points: int = MIN_FIT_POINTS) -> TrialFit:
    """Analyse one indentation trial.

    Parameters
    ----------
    time : array_like, shape (m,)
        Sample times [s], strictly increasing.
    displacement : array_like, shape (m,)
        Encoder displacement [m], any origin; counting into the arm or away from it.
    force : array_like, shape (m,)
        Raw force [N], any offset.
    zero_window : float
        Rest period at the start used to zero the force [s].
    onset_threshold : float, optional
        Difference threshold on the zeroed force [N], also the contact threshold
        of the fits. Default :func:`default_onset_threshold` of the zero-window noise.
    reversal : float, optional
        Depth reversal that ends a stroke [m]. Default
        ``max(REVERSAL_FLOOR, REVERSAL_FRACTION * peak depth)``.
    min_points : int
        Fewest in-contact samples for a stroke to be fitted.

    Returns
    -------
    TrialFit

    Raises
    ------
    TrialError
        Non-finite samples, time not increasing, trial not longer than the zero
        window, indentation starting inside the zero window, no indentation, or
        no unloading stroke in contact.
    """
    t = as_1d(time, "time")
    x = as_1d(displacement, "displacement")
    f_raw = as_1d(force, "force")
    if not (t.size == x.size == f_raw.size):
        raise TrialError(f"time, displacement and force differ in length "
                         f"({t.size}, {x.size}, {f_raw.size})")
    if t.size < 2:
        raise TrialError("fewer than 2 samples", key="time")
    dt = np.diff(t)
    if (dt <= 0).any():
        i = int(np.argmax(dt <= 0)) + 1
        raise TrialError(f"sample {i}: time {t[i]:.6g} s does not increase (previous "
                         f"{t[i - 1]:.6g} s); expected strictly increasing time", key="time")

    level, noise = zero_level(t, f_raw, zero_window)
    check_at_rest(t, f_raw, zero_window)
    f = f_raw - level
    if onset_threshold is None:
        threshold = default_onset_threshold(noise)
    else:
        threshold = float(onset_threshold)
        if not threshold > 0:
            raise ValueError(f"onset_threshold must be > 0 N, got {onset_threshold}")
    onset = detect_onset(f, threshold)
    if t[onset] - t[0] < zero_window:
        raise TrialError(f"the force rises {threshold:.3g} N above its zero level at "
                         f"t = {t[onset] - t[0]:.3g} s, inside the zero window of "
                         f"{zero_window:g} s; expected the indenter at rest for the first "
                         f"{zero_window:g} s", key="force")

    d = x - x[onset]
    sign = 1
    if d[int(np.argmax(f))] < 0:
        sign = -1
        d = -d
    peak_depth = float(d.max())
    if reversal is None:
        reversal = max(REVERSAL_FLOOR, REVERSAL_FRACTION * peak_depth)

    peaks, unload, load, hyst = [], [], [], []
    nan = float("nan")
    for load_start, hi_f, hi_l, unload_stop in split_strokes(d, reversal):
        run = _contact_run(f, hi_l, unload_stop, threshold, backwards=False)
        if run is None or run[1] - run[0] < min_points:
            continue
        u = fit_line(d[run[0]:run[1]], f[run[0]:run[1]])
        if not np.isfinite(u[0]):
            continue
        peaks.append(hi_f)
        unload.append((*u, *run))
        lrun = _contact_run(f, load_start, hi_f + 1, threshold, backwards=True)
        if lrun is not None and lrun[1] - lrun[0] >= min_points:
            load.append((*fit_line(d[lrun[0]:lrun[1]], f[lrun[0]:lrun[1]]), *lrun))
        else:
            load.append((nan, nan, nan, load_start, load_start))
        contact = f > threshold
        w_load = stroke_work(d[load_start:hi_f + 1], f[load_start:hi_f + 1],
                             contact[load_start:hi_f + 1])
        w_unload = -stroke_work(d[hi_l:unload_stop], f[hi_l:unload_stop],
                                contact[hi_l:unload_stop])
        hyst.append((w_load - w_unload) / w_load if w_load > 0 else nan)

    if not unload:
        raise TrialError(f"no unloading stroke in contact: expected the depth to come back "
                         f"by at least {reversal * 1e3:.3g} mm from a maximum while the force "
                         f"stays above {threshold:.3g} N for {min_points} samples or more",
                         key="displacement")

    def _fits(rows) -> LinearFits:
        a = np.asarray(rows, dtype=float).reshape(-1, 5)
        return LinearFits(slope=a[:, 0], intercept=a[:, 1], r2=a[:, 2],
                          start=a[:, 3].astype(int), stop=a[:, 4].astype(int))

    return TrialFit(time=t, depth=d, force=f, zero_level=level, noise_sd=noise,
                    threshold=threshold, onset_index=onset, sign=sign, reversal=float(reversal),
                    peak_index=np.asarray(peaks, dtype=int), unloading=_fits(unload),
                    loading=_fits(load), hysteresis=np.asarray(hyst, dtype=float))


def location_statistics(values) -> tuple[float, float, int]:
    """Mean, sample standard deviation (ddof = 1) and count of stiffness values.

    Parameters
    ----------
    values : array_like
        Stiffnesses [N/m].

    Returns
    -------
    mean : float
        [N/m]; NaN for no values.
    std : float
        [N/m]; NaN for fewer than two values.
    n : int
    """
    v = np.asarray(values, dtype=float).ravel()
    n = int(v.size)
    mean = float(v.mean()) if n else float("nan")
    std = float(v.std(ddof=1)) if n > 1 else float("nan")
    return mean, std, n


def trial_spread(values) -> float:
    """``(max - min) / mean`` of the trial stiffnesses [-]; 0 for one value."""
    v = np.asarray(values, dtype=float).ravel()
    if v.size < 2:
        return 0.0
    return float((v.max() - v.min()) / v.mean())


def fit_location(trials, *, location: str = "", trial_ids=None,
                 min_r2: float = DEFAULT_MIN_R2,
                 max_spread: float = DEFAULT_MAX_SPREAD) -> LocationFit:
    """Aggregate the trials of one location.

    Parameters
    ----------
    trials : sequence of TrialFit
        At least one.
    location : str
        Label of the location.
    trial_ids : sequence of int, optional
        Trial numbers (default 1, 2, ...).
    min_r2 : float
        Flag ``low_r2`` when any unloading fit has R^2 below this [-].
    max_spread : float
        Flag ``trial_spread`` when ``(max - min) / mean`` of the trial
        stiffnesses exceeds this fraction [-].

    Returns
    -------
    LocationFit
    """
    trials = tuple(trials)
    if not trials:
        raise ValueError("fit_location needs at least one trial")
    ids = np.arange(1, len(trials) + 1) if trial_ids is None else np.asarray(trial_ids, int)
    ks = np.array([tr.stiffness for tr in trials], dtype=float)
    mean, std, n = location_statistics(ks)
    spread = trial_spread(ks)
    r2_min = float(min(tr.r2_min for tr in trials))
    flags = []
    if not r2_min >= min_r2:
        flags.append("low_r2")
    if spread > max_spread:
        flags.append("trial_spread")
    if n == 1:
        flags.append("single_trial")
    return LocationFit(
        location=str(location), trial_ids=ids, trials=trials, trial_stiffness=ks,
        stiffness=mean, std=std, spread=spread, r2_min=r2_min,
        loading_slope=_nanmean([tr.loading_slope for tr in trials]),
        hysteresis_ratio=_nanmean([tr.hysteresis_ratio for tr in trials]),
        peak_force=float(max(tr.peak_force for tr in trials)),
        peak_depth=float(max(tr.peak_depth for tr in trials)),
        n_strokes=int(sum(tr.n_strokes for tr in trials)),
        flags=tuple(flags))
