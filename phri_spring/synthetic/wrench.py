"""Synthetic wrench logs: the quick-start example and benchmark logs."""

from __future__ import annotations

import numpy as np

from ..physics.cuff.loadcell import cuff_to_loadcell

__all__ = ["step_profile", "iact_like_log", "smooth_random_log"]


def step_profile(time, levels, hold: float, ramp: float) -> np.ndarray:
    """Piecewise-constant levels held ``hold`` s each, joined by linear ramps of ``ramp`` s.

    Parameters
    ----------
    time : array_like
        Sample times [s] from 0.
    levels : sequence of float
        Successive plateau values.
    hold, ramp : float
        Plateau and ramp durations [s].
    """
    time = np.asarray(time, dtype=float)
    knots_t, knots_v = [0.0], [levels[0]]
    t = 0.0
    for i, lev in enumerate(levels):
        if i > 0:
            t += ramp
            knots_t.append(t)
            knots_v.append(lev)
        t += hold
        knots_t.append(t)
        knots_v.append(lev)
    return np.interp(time, knots_t, knots_v)


def iact_like_log(seed: int = 2024, rate_hz: float = 100.0,
                  loads_n=(0.0, 11.1, 33.4, 55.6), hold_s: float = 8.0, ramp_s: float = 1.5,
                  lever_m: float = 0.01, force_noise_n: float = 0.3,
                  moment_noise_nm: float = 0.01, loadcell_position=(0.0, -0.07, 0.0),
                  rotation=None):
    """An I-Act-like log: the arm loaded horizontally in steps, as the load cell reads it.

    The cuff is pushed along +z (horizontal loading, the paper's load-cell z) by
    hanging weights 0, 11.1, 33.4 and 55.6 N [paper, section III-A], applied a
    little off the cuff centre (``lever_m`` along x gives a moment My), then
    unloaded to zero. The cuff wrench is converted to load-cell readings with
    the load-cell pose, and Gaussian sensor noise is added.

    Returns
    -------
    time : ndarray, shape (m,)
        [s]
    wrench_lc : ndarray, shape (m, 6)
        (Fx, Fy, Fz [N], Mx, My, Mz [N*m]) in load-cell axes about its origin.
    """
    rng = np.random.default_rng(seed)
    levels = list(loads_n) + [0.0]
    duration = len(levels) * hold_s + (len(levels) - 1) * ramp_s
    time = np.arange(0.0, duration, 1.0 / rate_hz)
    fz = step_profile(time, levels, hold_s, ramp_s)
    W = np.zeros((len(time), 6))
    W[:, 2] = fz
    W[:, 4] = -lever_m * fz          # force at x = lever: M = p x F, My = -x Fz
    w_lc = cuff_to_loadcell(W, rotation, loadcell_position)
    w_lc[:, :3] += rng.normal(0.0, force_noise_n, (len(time), 3))
    w_lc[:, 3:] += rng.normal(0.0, moment_noise_nm, (len(time), 3))
    return np.round(time, 6), w_lc


def smooth_random_log(n_samples: int, seed: int = 0, rate_hz: float = 100.0,
                      force_amp_n: float = 40.0, moment_amp_nm: float = 1.5):
    """A long, smoothly varying wrench log (sums of slow sinusoids + noise) for benchmarks.

    Loads up to about ``2 * force_amp_n`` [N] lift some contacts part of the time,
    like real interaction logs. Returns ``(time [s], wrench (n, 6) [N, N*m])``.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n_samples) / rate_hz
    W = np.empty((n_samples, 6))
    amps = np.array([force_amp_n] * 3 + [moment_amp_nm] * 3)
    for j in range(6):
        f1, f2 = rng.uniform(0.02, 0.3, 2)
        p1, p2 = rng.uniform(0, 2 * np.pi, 2)
        W[:, j] = amps[j] * (np.sin(2 * np.pi * f1 * t + p1) + 0.5 * np.sin(2 * np.pi * f2 * t + p2))
    W += rng.normal(0.0, 1.0, W.shape) * amps * 0.005
    return t, W
