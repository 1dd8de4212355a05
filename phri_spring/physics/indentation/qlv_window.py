"""The contact window of an indenter trial for the QLV fit, and whether relaxation is identifiable.

A quasi-linear viscoelastic (QLV) fit (:mod:`phri_spring.physics.indentation.qlv`) models the
force of the tissue over time from the measured depth, with the tissue at rest before the
indenter touches it. Per trial it uses the **first contact**: the force is zeroed over the
rest window and the onset found as in :mod:`phri_spring.physics.indentation.signal`; the
window then starts a little before the onset (so that the contact point can be fitted) and
ends at the first sample after it whose zeroed force is back at or below the onset threshold
(the indenter has left the skin; after that the tissue recovers out of contact, which the
measured depth no longer describes). A later push in the same trial is not used.

The relaxation function is identifiable from a location's trials only if they hold the depth
for a while (a **hold**: the depth within :data:`HOLD_TOLERANCE` of its peak for at least
:data:`HOLD_MIN_S`), or press at **several loading rates** (fastest over slowest at least
:data:`RATE_RATIO_MIN`). :func:`check_identifiable` refuses anything else.

Pure numpy on arrays, SI units (s, m, N); bad trials raise
:class:`~phri_spring.physics.indentation.signal.TrialError` naming the quantity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .signal import (TrialError, check_at_rest, default_onset_threshold,
                                 detect_onset, zero_level)

__all__ = ["QlvWindow", "qlv_window", "check_identifiable", "HOLD_MIN_S", "HOLD_TOLERANCE",
           "RATE_RATIO_MIN", "PRE_CONTACT_S"]

#: a hold keeps the depth within this fraction of its peak [-]
HOLD_TOLERANCE = 0.05
#: ... for at least this long [s]
HOLD_MIN_S = 1.0
#: without a hold, the loading rates of a location's trials must differ by this factor [-]
RATE_RATIO_MIN = 2.0
#: the window starts this long before the onset (at most back to the end of the rest window),
#: so that the contact point, between the last sample at rest and the onset, can be fitted [s]
PRE_CONTACT_S = 0.25
#: fewest samples in contact for a window
MIN_CONTACT_SAMPLES = 10


@dataclass(frozen=True)
class QlvWindow:
    """The samples of one trial the QLV fit uses (see the module docstring).

    Attributes
    ----------
    time : ndarray, shape (m,)
        [s], from the first sample of the trial.
    depth : ndarray, shape (m,)
        Depth from the onset sample, positive into the arm [m].
    force : ndarray, shape (m,)
        Zeroed force [N].
    onset : int
        Index of the onset sample in the window.
    noise_sd, threshold, zero_level : float
        Force noise SD in the rest window, onset threshold, zero level [N].
    sign : int
        -1 if the displacement was flipped (an encoder counting away from the arm).
    start : int
        Index of the window's first sample in the trial.
    """

    time: np.ndarray
    depth: np.ndarray
    force: np.ndarray
    onset: int
    noise_sd: float
    threshold: float
    zero_level: float
    sign: int
    start: int

    @property
    def peak_depth(self) -> float:
        """[m]"""
        return float(self.depth.max())

    @property
    def peak_force(self) -> float:
        """[N]"""
        return float(self.force.max())

    @property
    def hold_s(self) -> float:
        """Longest time the depth stays within :data:`HOLD_TOLERANCE` of its peak [s]."""
        near = self.depth >= (1.0 - HOLD_TOLERANCE) * self.peak_depth
        edges = np.diff(np.concatenate([[0], near.astype(np.int8), [0]]))
        first, last = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
        return float((self.time[last] - self.time[first]).max()) if first.size else 0.0

    @property
    def loading_rate(self) -> float:
        """Mean speed from 10 % to 90 % of the peak depth on the way in [m/s]."""
        d = self.depth[self.onset:]
        t = self.time[self.onset:]
        peak = self.peak_depth
        i10 = int(np.argmax(d >= 0.1 * peak))
        i90 = int(np.argmax(d >= 0.9 * peak))
        dt = float(t[i90] - t[i10])
        return 0.8 * peak / dt if dt > 0 else float("inf")


def qlv_window(time, displacement, force, *, zero_window: float = 3.0,
               onset_threshold: float | None = None) -> QlvWindow:
    """Zero a trial, find its onset and cut the window of its first contact.

    Parameters
    ----------
    time : array_like, shape (m,)
        Strictly increasing [s].
    displacement : array_like, shape (m,)
        Encoder displacement [m], any origin and direction.
    force : array_like, shape (m,)
        Raw force [N], any offset.
    zero_window : float
        Rest period at the start [s].
    onset_threshold : float, optional
        [N]; default :func:`~phri_spring.physics.indentation.signal.default_onset_threshold`.

    Returns
    -------
    QlvWindow

    Raises
    ------
    ~phri_spring.physics.indentation.signal.TrialError
        Time not increasing, no rest, no indentation, or too few samples in contact.
    """
    t = np.asarray(time, dtype=float)
    x = np.asarray(displacement, dtype=float)
    f_raw = np.asarray(force, dtype=float)
    if not (t.ndim == x.ndim == f_raw.ndim == 1 and t.size == x.size == f_raw.size):
        raise TrialError("time, displacement and force must be vectors of one length",
                         key="time")
    if not (np.isfinite(t).all() and np.isfinite(x).all() and np.isfinite(f_raw).all()):
        raise TrialError("expected finite samples", key="force")
    if t.size < 2 or (np.diff(t) <= 0).any():
        raise TrialError("expected strictly increasing time (a column of sample times [s])",
                         key="time")
    level, noise = zero_level(t, f_raw, zero_window)
    check_at_rest(t, f_raw, zero_window)
    f = f_raw - level
    threshold = default_onset_threshold(noise) if onset_threshold is None \
        else float(onset_threshold)
    onset = detect_onset(f, threshold)
    if t[onset] - t[0] < zero_window:
        raise TrialError(f"the force rises above its zero level at t = {t[onset] - t[0]:.3g} s, "
                         f"inside the zero window of {zero_window:g} s; expected the indenter "
                         "at rest there", key="force")
    after = np.flatnonzero(f[onset:] <= threshold)
    stop = onset + int(after[0]) if after.size else t.size
    if stop - onset < MIN_CONTACT_SAMPLES:
        raise TrialError(f"the force stays above {threshold:.3g} N for {stop - onset} samples "
                         f"only; expected a contact of {MIN_CONTACT_SAMPLES} samples or more",
                         key="force")
    rest_end = int(np.searchsorted(t, t[0] + zero_window))
    start = max(rest_end, int(np.searchsorted(t, t[onset] - PRE_CONTACT_S)), 0)
    start = min(start, onset - 1) if onset > 0 else 0
    d = x - x[onset]
    sign = 1
    if d[onset + int(np.argmax(f[onset:stop]))] < 0:
        sign, d = -1, -d
    win = slice(start, stop)
    w = QlvWindow(time=t[win] - t[0], depth=d[win], force=f[win], onset=onset - start,
                  noise_sd=float(noise), threshold=float(threshold), zero_level=float(level),
                  sign=sign, start=start)
    if not w.peak_depth > 0:
        raise TrialError("the depth does not increase while the force rises; expected the "
                         "indenter pressed into the arm", key="displacement")
    return w


def check_identifiable(windows) -> None:
    """Refuse trials from which the relaxation cannot be told apart from the elastic law.

    Parameters
    ----------
    windows : sequence of QlvWindow
        The trials of one location.

    Raises
    ------
    ~phri_spring.physics.indentation.signal.TrialError
        Neither a hold of :data:`HOLD_MIN_S` nor loading rates :data:`RATE_RATIO_MIN` apart.
    """
    windows = list(windows)
    hold = max(w.hold_s for w in windows)
    if hold >= HOLD_MIN_S:
        return
    rates = np.array([w.loading_rate for w in windows])
    finite = rates[np.isfinite(rates) & (rates > 0)]
    ratio = float(finite.max() / finite.min()) if finite.size else 1.0
    if ratio >= RATE_RATIO_MIN:
        return
    listed = ", ".join(f"{r * 1e3:.3g}" for r in rates)
    raise TrialError(f"relaxation not identifiable: no hold (the depth stays within "
                     f"{HOLD_TOLERANCE:.0%} of its peak for {hold:.2g} s at most) and one "
                     f"loading rate ({listed} mm/s); expected a hold of {HOLD_MIN_S:g} s or "
                     f"more after the ramp, or trials at loading rates {RATE_RATIO_MIN:g}x "
                     "apart", key="displacement")
