"""Error metrics of a model-versus-measurement comparison (paper section IV-B).

Pure array functions, no I/O. Forces are in newtons.

- :func:`zero_on`        subtract a baseline (the "calibrate to zero" step)
- :func:`rmse`           root mean square error over the elements (paper Eq. 1)
- :func:`mean_and_se`    mean and standard error over trials
"""

from __future__ import annotations

import numpy as np

__all__ = ["zero_on", "rmse", "standard_error", "mean_and_se"]


def zero_on(values, baseline) -> np.ndarray:
    """Subtract a baseline: ``values - baseline`` (broadcasting).

    Measured loads are zeroed on the measured loads of the baseline condition,
    simulated loads on the simulated loads of the baseline condition, each on
    its own side (docs/model.md section 7).

    Parameters
    ----------
    values : array_like, shape (..., n)
        Loads of each element [N], e.g. one row per condition.
    baseline : array_like, shape (n,) or broadcastable to ``values``
        Loads of the baseline condition [N].

    Returns
    -------
    ndarray, shape (..., n)
        Zeroed loads [N].
    """
    return np.asarray(values, dtype=float) - np.asarray(baseline, dtype=float)


def rmse(measured, simulated, axis: int = -1) -> np.ndarray:
    """Root mean square error of paper Eq. 1.

    RMSE = sqrt( sum_e (F_expt,e - F_sim,e)^2 / N ), with N the number of
    elements along ``axis`` (21 for the Harmony cuff).

    Parameters
    ----------
    measured : array_like, shape (..., n)
        Measured (zeroed) load of each element F_expt [N].
    simulated : array_like, shape (..., n)
        Simulated (zeroed) load of each element F_sim [N]; broadcast against
        ``measured``.
    axis : int
        The element axis.

    Returns
    -------
    ndarray or float
        RMSE [N], one per remaining index (NaN where an input is NaN).

    Raises
    ------
    ValueError
        If there are no elements along ``axis``.
    """
    m = np.asarray(measured, dtype=float)
    s = np.asarray(simulated, dtype=float)
    d = m - s
    n = d.shape[axis]
    if n == 0:
        raise ValueError("rmse: expected at least one element")
    return np.sqrt(np.sum(d * d, axis=axis) / n)


def standard_error(values, axis: int = 0) -> np.ndarray:
    """Standard error of the mean, sample SD (ddof = 1) / sqrt(n).

    Parameters
    ----------
    values : array_like
        Samples, e.g. the RMSE of each trial [N].
    axis : int
        The sample axis.

    Returns
    -------
    ndarray or float
        Standard error [same unit as ``values``]; NaN where fewer than two
        samples are given (the sample SD is undefined).
    """
    v = np.atleast_1d(np.asarray(values, dtype=float))
    n = v.shape[axis]
    if n < 2:
        out = np.full(np.delete(np.array(v.shape), axis), np.nan)
    else:
        out = np.std(v, axis=axis, ddof=1) / np.sqrt(n)
    return float(out) if np.ndim(out) == 0 else out


def mean_and_se(values, axis: int = 0):
    """Mean and standard error (sample SD / sqrt(n)) of trial values.

    Parameters
    ----------
    values : array_like
        Samples, e.g. the RMSE of three trials [N].
    axis : int
        The sample axis.

    Returns
    -------
    mean : ndarray or float
        Mean [same unit as ``values``].
    se : ndarray or float
        Standard error [same unit]; NaN for a single sample.
    """
    v = np.atleast_1d(np.asarray(values, dtype=float))
    if v.shape[axis] == 0:
        raise ValueError("mean_and_se: expected at least one value")
    mean = np.mean(v, axis=axis)
    return (float(mean) if np.ndim(mean) == 0 else mean), standard_error(v, axis=axis)
