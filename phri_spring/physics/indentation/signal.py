"""Indenter signal conditioning: zeroing, onset and stroke detection (docs/model.md section 7).

Steps 1 to 4 of the analysis described in :mod:`phri_spring.physics.indentation.linear`
(which fits the strokes found here and re-exports every name of this module):
the force is zeroed over the rest window (:func:`zero_level`, with
:func:`window_trend` / :func:`check_at_rest` to reject a window that is not at
rest), the onset is the first sample above a threshold
(:func:`default_onset_threshold`, :func:`detect_onset`), and the depth signal is
split into pushes with a hysteresis rule (:func:`turning_points`,
:func:`split_strokes`).

Everything here is pure numpy on arrays in SI units (s, m, N); no files, no
printing. Bad trials raise :class:`TrialError` (a ``ValueError``) naming the
offending quantity; the I/O layer adds the file.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "TrialError", "ONSET_SIGMAS", "ONSET_FLOOR", "REST_TREND_SIGMAS", "REVERSAL_FLOOR",
    "REVERSAL_FRACTION", "zero_level", "window_trend", "check_at_rest",
    "default_onset_threshold", "detect_onset", "turning_points", "split_strokes",
]

#: default onset threshold = max(ONSET_SIGMAS * noise SD, ONSET_FLOOR)
ONSET_SIGMAS = 5.0
#: floor of the default onset threshold [N]
ONSET_FLOOR = 0.05
#: smallest depth reversal that ends a stroke [m] (4 encoder steps of 0.025 mm)
REVERSAL_FLOOR = 0.1e-3
#: a stroke also ends only on a reversal of at least this fraction of the peak depth [-]
REVERSAL_FRACTION = 0.1


class TrialError(ValueError):
    """A trial that cannot be analysed (too short, no indentation, NaN, ...).

    Attributes
    ----------
    key : str or None
        The quantity at fault (``time``, ``displacement`` or ``force``).
    """

    def __init__(self, message: str, key: str | None = None):
        self.key = key
        super().__init__(message)


def as_1d(values, name: str) -> np.ndarray:
    a = np.asarray(values, dtype=float)
    if a.ndim != 1:
        raise TrialError(f"expected a one-dimensional array, got shape {a.shape}", key=name)
    bad = ~np.isfinite(a)
    if bad.any():
        i = int(np.argmax(bad))
        raise TrialError(f"sample {i}: value {a[i]!r}; expected a finite number", key=name)
    return a


def zero_level(time, force, zero_window: float = 3.0) -> tuple[float, float]:
    """Zero level and noise of the force over the first ``zero_window`` seconds.

    Parameters
    ----------
    time : array_like, shape (m,)
        Sample times [s], increasing.
    force : array_like, shape (m,)
        Raw force [N].
    zero_window : float
        Length of the rest period at the start of the trial [s]. Samples with
        ``time - time[0] < zero_window`` are used.

    Returns
    -------
    level : float
        Mean force over the window [N].
    noise_sd : float
        Sample standard deviation (ddof = 1) of the force over the window [N].

    Raises
    ------
    TrialError
        If the trial does not last longer than the window or the window holds
        fewer than two samples.
    """
    t = np.asarray(time, dtype=float)
    f = np.asarray(force, dtype=float)
    if zero_window <= 0:
        raise ValueError(f"zero_window must be > 0 s, got {zero_window}")
    span = float(t[-1] - t[0]) if t.size else 0.0
    if span <= zero_window:
        raise TrialError(f"trial lasts {span:.3g} s, not longer than the zero window of "
                         f"{zero_window:g} s; expected a rest period followed by indentation",
                         key="time")
    window = (t - t[0]) < zero_window
    if np.count_nonzero(window) < 2:
        raise TrialError(f"fewer than 2 samples in the zero window of {zero_window:g} s",
                         key="time")
    fw = f[window]
    return float(fw.mean()), float(fw.std(ddof=1))


#: a zero window whose force trend changes it by more than this many noise SDs is not at rest
REST_TREND_SIGMAS = 10.0


def window_trend(time, force, zero_window: float = 3.0) -> tuple[float, float]:
    """Change of the force along the zero window's own trend, and the window's noise.

    A line is fitted to force against time over the window (as in
    :func:`zero_level`); the change is its slope times the window's span. The
    noise is estimated from successive differences, ``SD(diff(f)) / sqrt(2)``,
    which a slow push does not inflate (unlike the SD about the mean, which
    sets the default onset threshold).

    Parameters
    ----------
    time : array_like, shape (m,)
        Sample times [s], increasing, longer than the window.
    force : array_like, shape (m,)
        Raw force [N].
    zero_window : float
        [s]

    Returns
    -------
    change : float
        Force change along the fitted trend over the window [N] (signed).
    noise_sd : float
        Noise SD from successive differences [N].
    """
    t = np.asarray(time, dtype=float)
    f = np.asarray(force, dtype=float)
    window = (t - t[0]) < zero_window
    tw, fw = t[window], f[window]
    if tw.size < 3:
        return 0.0, 0.0
    tc = tw - tw.mean()
    denom = float(tc @ tc)
    slope = float(tc @ (fw - fw.mean())) / denom if denom > 0 else 0.0
    return slope * float(tw[-1] - tw[0]), float(np.std(np.diff(fw), ddof=1) / np.sqrt(2.0))


def check_at_rest(time, force, zero_window: float = 3.0,
                  sigmas: float = REST_TREND_SIGMAS, floor: float | None = None) -> None:
    """Refuse a trial whose indenter is already pushing (or releasing) in the zero window.

    A push that starts inside the window raises both the zero level and the
    noise SD, hence the default onset threshold, so the trial would otherwise be
    rejected as "no indentation" or mis-zeroed. Detected from the window's own
    trend (:func:`window_trend`), whatever onset threshold is in force: the
    trial is refused if the trend changes the force by more than
    ``max(sigmas * noise, floor)`` over the window.

    Raises
    ------
    TrialError
        Naming the change, the window's length and how to change it.
    """
    floor = ONSET_FLOOR if floor is None else float(floor)
    change, noise = window_trend(time, force, zero_window)
    if abs(change) > max(sigmas * noise, floor):
        how = "rises" if change > 0 else "falls"
        ratio = f", {abs(change) / noise:.0f} times its noise" if noise > 0 else ""
        raise TrialError(f"the indenter was not at rest inside the zero window of "
                         f"{zero_window:g} s: the force {how} {abs(change):.3g} N along its "
                         f"trend over the window{ratio}; expected the indenter at rest (force "
                         f"flat) for the first {zero_window:g} s: record a rest period first, "
                         "or set a shorter zero window (--zero-window SECONDS)", key="force")


def default_onset_threshold(noise_sd: float, sigmas: float = ONSET_SIGMAS,
                            floor: float = ONSET_FLOOR) -> float:
    """Default onset threshold ``max(sigmas * noise_sd, floor)`` [N].

    Parameters
    ----------
    noise_sd : float
        Standard deviation of the force at rest [N].
    sigmas : float
        Multiple of the noise [-].
    floor : float
        Smallest threshold [N].
    """
    return float(max(sigmas * float(noise_sd), floor))


def detect_onset(force_zeroed, threshold: float) -> int:
    """Index of the first sample whose zeroed force exceeds ``threshold``.

    Parameters
    ----------
    force_zeroed : array_like, shape (m,)
        Force minus the zero level [N].
    threshold : float
        Difference threshold [N], > 0.

    Returns
    -------
    int
        The onset index.

    Raises
    ------
    TrialError
        If the force never exceeds the threshold (no indentation).
    """
    f = np.asarray(force_zeroed, dtype=float)
    above = f > threshold
    if not above.any():
        peak = float(f.max()) if f.size else float("nan")
        hint = ""
        if f.size and f.min() < -10 * threshold:
            hint = (f"; it falls {-f.min():.3g} N below it: if the sensor reads compression "
                    "as negative, negate the force")
        raise TrialError(f"no indentation: the force never rises more than {threshold:.3g} N "
                         f"above its zero level (largest rise {peak:.3g} N){hint}", key="force")
    return int(np.argmax(above))


def turning_points(x, reversal: float) -> tuple[np.ndarray, np.ndarray]:
    """Maxima and minima of a signal, confirmed by a reversal of at least ``reversal``.

    A zig-zag (hysteresis) rule: while rising, the running maximum is tracked;
    it becomes a turning point once the signal has dropped ``reversal`` below it
    (and symmetrically for minima). Smaller wiggles, such as encoder steps or
    hand tremor, do not create turning points. A flat top (a plateau of equal
    values) is reported by its first and its last sample.

    Parameters
    ----------
    x : array_like, shape (m,)
        The signal (depth [m]).
    reversal : float
        Smallest reversal that confirms a turning point (same unit as x), > 0.

    Returns
    -------
    maxima : ndarray of int, shape (p, 2)
        First and last sample of each confirmed maximum.
    minima : ndarray of int, shape (q, 2)
        First and last sample of each confirmed minimum. Maxima and minima
        alternate; the ends of the signal are not reported.
    """
    if not reversal > 0:
        raise ValueError(f"reversal must be > 0, got {reversal}")
    xs = np.asarray(x, dtype=float).tolist()
    maxima: list[tuple[int, int]] = []
    minima: list[tuple[int, int]] = []
    if not xs:
        return np.zeros((0, 2), int), np.zeros((0, 2), int)
    hi_f = hi_l = lo_f = lo_l = 0
    hi = lo = xs[0]
    state = 0  # 0: undecided, +1: rising (tracking a maximum), -1: falling
    for i in range(1, len(xs)):
        v = xs[i]
        if state >= 0:
            if v > hi:
                hi, hi_f, hi_l = v, i, i
            elif v == hi:
                hi_l = i
            elif hi - v >= reversal:
                maxima.append((hi_f, hi_l))
                state = -1
                lo, lo_f, lo_l = v, i, i
                continue
        if state <= 0:
            if v < lo:
                lo, lo_f, lo_l = v, i, i
            elif v == lo:
                lo_l = i
            elif v - lo >= reversal:
                if state == -1:
                    minima.append((lo_f, lo_l))
                state = +1
                hi, hi_f, hi_l = v, i, i
    return (np.asarray(maxima, dtype=int).reshape(-1, 2),
            np.asarray(minima, dtype=int).reshape(-1, 2))


def split_strokes(depth, reversal: float) -> list[tuple[int, int, int, int]]:
    """Loading and unloading strokes of every push.

    Parameters
    ----------
    depth : array_like, shape (m,)
        Depth [m].
    reversal : float
        Smallest reversal that ends a stroke [m].

    Returns
    -------
    list of (load_start, peak_first, peak_last, unload_stop)
        One tuple per maximum: the loading stroke is ``load_start:peak_first + 1``
        (from the preceding minimum, or the first sample), the unloading stroke
        ``peak_last:unload_stop`` (to the next minimum inclusive, or the end).
    """
    d = np.asarray(depth, dtype=float)
    maxima, minima = turning_points(d, reversal)
    pushes = []
    for hi_f, hi_l in maxima:
        before = minima[minima[:, 1] < hi_f]
        after = minima[minima[:, 0] > hi_l]
        load_start = int(before[-1, 1]) if before.size else 0
        unload_stop = int(after[0, 0]) + 1 if after.size else d.size
        pushes.append((load_start, int(hi_f), int(hi_l), unload_stop))
    # a trial that ends at (or while pushing towards) its deepest point has an
    # unconfirmed last maximum: it holds a loading stroke but no unloading stroke,
    # and is left out.
    return pushes
