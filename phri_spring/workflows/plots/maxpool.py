"""``phri simulate --plot``: a whole log at a glance, in bounded memory.

The forces of a long log (hours at 100 Hz: millions of samples) cannot be
drawn sample by sample, and must not be held in memory. :class:`MaxPool`
receives the chunks as :func:`~phri_spring.workflows.simulate.simulate_file`
solves them (its ``on_chunk`` hook) and keeps, for each of about ``bins``
consecutive groups of samples, the largest force of every element and the
largest peak pressure: downsampling by the maximum, so that no peak is lost
(a mean or a decimation would hide a short one). When the log turns out to be
longer than expected, neighbouring groups are merged two by two (the maximum
of maxima), so memory stays below ``2 * bins`` groups whatever the length.

:func:`write_simulate_plot` draws the result
(:func:`phri_spring.reports.simulate_figures.simulate_figure`) and writes it
atomically (PNG, SVG or PDF by the extension).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from ...errors import UsageError
from ...io.outputs.atomic import atomic_file

__all__ = ["MaxPool", "PooledLog", "PLOT_FORMATS", "check_plot_path", "write_simulate_plot"]

#: extensions ``--plot`` accepts
PLOT_FORMATS = (".png", ".svg", ".pdf")


@dataclass
class PooledLog:
    """A log max-pooled into k groups of consecutive samples (n elements).

    Attributes
    ----------
    time_start, time_end : ndarray, shape (k,)
        Time of the first and last sample of each group [s].
    forces : ndarray, shape (k, n)
        Largest force of each element in each group [N] (NaN where no sample
        of the group converged).
    peak_pressure : ndarray, shape (k,)
        Largest peak contact pressure in each group [kPa].
    samples_per_group : int
        Samples in each group (the last may hold fewer).
    samples : int
        Samples in the log.
    peak_kpa, peak_time, peak_element : float, float, int
        The largest peak pressure of the whole log [kPa], the time of its first
        sample [s] and the element it is on (column of ``forces``; -1 if none).
    peak_forces : ndarray, shape (n,), or None
        Every element's force [N] in that sample (the section figure's); None if none.
    """

    time_start: np.ndarray
    time_end: np.ndarray
    forces: np.ndarray
    peak_pressure: np.ndarray
    samples_per_group: int
    samples: int
    peak_kpa: float
    peak_time: float
    peak_element: int
    peak_forces: Optional[np.ndarray] = None


class MaxPool:
    """Max-pool a stream of (time, forces, peak pressure) chunks into about ``bins`` groups.

    Parameters
    ----------
    n : int
        Elements (columns of the forces).
    total : int, optional
        Samples expected (e.g. from :func:`phri_spring.io.logs.count_rows`);
        sets the group size ``ceil(total / bins)``. Wrong or missing is fine:
        groups are merged two by two whenever there are ``2 * bins`` of them.
    bins : int
        Target number of groups (the figure's columns).

    Notes
    -----
    Call the object (it is the ``on_chunk`` hook of ``simulate_file``) with
    ``time (m,) [s]``, ``forces (m, n) [N]`` and ``peak_pressure (m,) [kPa]``,
    chunk after chunk, in order; then :meth:`result`.
    """

    def __init__(self, n: int, total: Optional[int] = None, bins: int = 2000):
        if bins < 1:
            raise ValueError(f"bins: expected >= 1, got {bins}")
        self.n = int(n)
        self.bins = int(bins)
        self.width = max(1, math.ceil(total / self.bins)) if total else 1
        cap = 2 * self.bins + 1
        self._f = np.full((cap, self.n), np.nan)
        self._p = np.full(cap, np.nan)
        self._t0 = np.zeros(cap)
        self._t1 = np.zeros(cap)
        self._k = 0            # complete groups
        self._fill = 0         # samples in the open group (index self._k)
        self.samples = 0
        self._peak = (-math.inf, math.nan, -1)
        self._peak_forces = None

    def __call__(self, time, forces, peak_pressure) -> None:
        t = np.asarray(time, dtype=float)
        f = np.asarray(forces, dtype=float)
        p = np.asarray(peak_pressure, dtype=float)
        m = len(t)
        if f.shape != (m, self.n) or p.shape != (m,):
            raise ValueError(f"MaxPool: expected time (m,), forces (m, {self.n}), peak (m,); "
                             f"got {t.shape}, {f.shape}, {p.shape}")
        if m == 0:
            return
        if np.isfinite(p).any():
            j = int(np.nanargmax(p))
            if p[j] > self._peak[0]:
                fp = f[j]
                e = int(np.nanargmax(fp)) if np.isfinite(fp).any() else -1
                self._peak = (float(p[j]), float(t[j]), e)
                self._peak_forces = fp.copy()
        self.samples += m
        i = 0
        while i < m:
            take = min(m - i, self.width - self._fill)
            self._add(t[i:i + take], f[i:i + take], p[i:i + take])
            i += take

    def _add(self, t, f, p) -> None:
        """Samples that all fall into the open group (``width - fill`` at most)."""
        k = self._k
        if self._fill == 0:
            self._t0[k] = t[0]
        fmax = np.fmax.reduce(f, axis=0)
        self._f[k] = np.fmax(self._f[k], fmax)
        self._p[k] = np.fmax(self._p[k], np.fmax.reduce(p))
        self._t1[k] = t[-1]
        self._fill += len(t)
        if self._fill == self.width:
            self._k += 1
            self._fill = 0
            if self._k == 2 * self.bins:
                self._merge()

    def _merge(self) -> None:
        """Merge neighbouring groups two by two (the log is longer than expected)."""
        k = self._k                    # even, no open group
        h = k // 2
        self._f[:h] = np.fmax(self._f[0:k:2], self._f[1:k:2])
        self._p[:h] = np.fmax(self._p[0:k:2], self._p[1:k:2])
        self._t0[:h] = self._t0[0:k:2]
        self._t1[:h] = self._t1[1:k:2]
        self._f[h:] = np.nan
        self._p[h:] = np.nan
        self._k = h
        self.width *= 2

    def result(self) -> PooledLog:
        """The groups so far (the open one included)."""
        k = self._k + (1 if self._fill else 0)
        peak, t_peak, e = self._peak
        return PooledLog(time_start=self._t0[:k].copy(), time_end=self._t1[:k].copy(),
                         forces=self._f[:k].copy(), peak_pressure=self._p[:k].copy(),
                         samples_per_group=self.width, samples=self.samples,
                         peak_kpa=peak if math.isfinite(peak) else math.nan,
                         peak_time=t_peak, peak_element=e,
                         peak_forces=None if self._peak_forces is None
                         else self._peak_forces.copy())


def check_plot_path(path, inputs=(), option: str = "--plot") -> Path:
    """Refuse a ``--plot`` path of an unknown type, in a missing folder or equal to an input.

    Raises
    ------
    UsageError
        Naming the option.
    """
    from ...io.outputs.atomic import check_output_path

    path = Path(path)
    if path.suffix.lower() not in PLOT_FORMATS:
        raise UsageError(f"unknown figure type {path.suffix or '(none)'!r}; expected "
                         f"{', '.join(PLOT_FORMATS)}", file=path, key=option)
    check_output_path(path, inputs, option=option)
    return path


def write_simulate_plot(pooled: PooledLog, path, *, labels, pain_threshold_kpa: float,
                        title: str = "", dpi: int = 150, layout=None) -> Path:
    """Draw a :class:`PooledLog` and write it atomically (PNG, SVG or PDF by the extension).

    ``layout``: a free layout's :class:`~phri_spring.physics.cuff.patches.PatchLayout`
    (``cuff.patches``), drawn on the unrolled limb surface too; None for a grid."""
    from ...reports.compare.figures import save_figure
    from ...reports.simulate_figures import simulate_figure

    path = Path(path)
    arrays = None if layout is None else (layout.x, layout.theta, layout.width, layout.length)
    fig = simulate_figure(pooled, labels=labels, pain_threshold_kpa=pain_threshold_kpa,
                          title=title, layout=arrays)
    with atomic_file(path) as tmp:
        save_figure(fig, tmp, dpi)
    return path
