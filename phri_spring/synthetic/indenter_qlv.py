"""Synthetic indenter trials of quasi-linear viscoelastic (QLV) tissue: ramp, hold, release.

The force is the QLV hereditary integral evaluated in **closed form** for a depth path that is
piecewise linear in time (independent of the sample-by-sample recursion the fit uses). On a
segment starting at time a with depth d_a and speed v, in contact, the elastic response
F^e = (k / beta)(exp(beta d) - 1) (or k d for beta = 0) has dF^e/ds = k v exp(beta d(s)), and

    int_a^u exp(-(t - s)/tau) k v exp(beta (d_a + v (s - a))) ds
        = k v exp(beta d_a) exp(-(t - a)/tau) (exp(lam (u - a)) - 1) / lam,   lam = beta v + 1/tau,

summed over the segments before t (u = min(t, segment end)). The tissue is at rest before
the ramp; the indenter touches it at the start of the ramp (depth 0).

After the release the indenter leaves the skin where the QLV force would turn negative (the
tissue recovers more slowly than it is unloaded): the recorded force is the QLV force clipped
at 0, which is exact up to the lift-off and a stand-in after it (the recovery out of contact is
not modelled; the QLV fit stops at the lift-off).

A trial: ``rest`` seconds at rest (the indenter just off the skin), a ramp of ``ramp_s`` to
``depth``, a hold of ``hold_s``, a release over ``ramp_s`` back to 0 and ``rest`` seconds more;
force offset and white noise (``noise`` x peak force), optional encoder steps. Everything is
synthetic and says so wherever it is written.
"""

from __future__ import annotations

import numpy as np

from .indenter import ENCODER_STEP, SynthTrial

__all__ = ["qlv_path_force", "ramp_hold_path", "synth_qlv_trial"]


def qlv_path_force(t, knots_t, knots_d, stiffness: float, fractions, times_s,
                   stiffening: float = 0.0) -> np.ndarray:
    """The QLV force [N] at times ``t`` of a piecewise-linear depth path, in closed form.

    Parameters
    ----------
    t : array_like
        Evaluation times [s].
    knots_t, knots_d : array_like
        The path's knots: increasing times [s] and depths [m] (>= 0, in contact, 0 before).
    stiffness : float
        k [N/m].
    fractions, times_s : sequence of float
        Prony g_i and tau_i [s].
    stiffening : float
        beta [1/m].
    """
    t = np.asarray(t, dtype=float)
    kt = np.asarray(knots_t, dtype=float)
    kd = np.asarray(knots_d, dtype=float)
    g = np.asarray(fractions, dtype=float)
    tau = np.asarray(times_s, dtype=float)
    beta = float(stiffening)
    d_now = np.interp(t, kt, kd, left=kd[0], right=kd[-1])
    if beta > 0:
        fe_now = stiffness * np.expm1(beta * d_now) / beta
    else:
        fe_now = stiffness * d_now
    out = (1.0 - g.sum()) * fe_now
    for gi, ti in zip(g, tau):
        h = np.zeros_like(t)
        for a, b, da, db in zip(kt[:-1], kt[1:], kd[:-1], kd[1:]):
            if b <= a or db == da:                    # a zero-length knot step, or a hold
                continue
            v = (db - da) / (b - a)
            started = t > a
            u = np.minimum(t, b)
            w = np.where(started, u - a, 0.0)
            lam = beta * v + 1.0 / ti
            lw = lam * w
            small = np.abs(lw) < 1.0
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                # exp(-(t - a)/tau) (exp(lam w) - 1) / lam, two ways to keep it finite
                direct = np.exp(-(t - a) / ti) * w * np.where(
                    small, np.expm1(lw) / np.where(lw == 0, 1.0, lw), 0.0)
                direct = np.where(small & (lw == 0), np.exp(-(t - a) / ti) * w, direct)
                far = (np.exp(-(t - u) / ti + beta * v * w) - np.exp(-(t - a) / ti)) / lam
            term = np.where(small, direct, far)
            h += np.where(started, stiffness * v * np.exp(beta * da) * term, 0.0)
        out = out + gi * h
    return out


def ramp_hold_path(depth: float, ramp_s: float, hold_s: float, rest: float,
                   release: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Knots (times [s], depths [m]) of rest, ramp, hold and (optionally) release, rest."""
    kt = [0.0, rest, rest + ramp_s, rest + ramp_s + hold_s]
    kd = [0.0, 0.0, depth, depth]
    if release:
        kt += [rest + 2 * ramp_s + hold_s, 2 * rest + 2 * ramp_s + hold_s]
        kd += [0.0, 0.0]
    return np.asarray(kt), np.asarray(kd)


def synth_qlv_trial(stiffness: float, fractions, times_s, *, stiffening: float = 0.0,
                    depth: float = 4e-3, ramp_s: float = 1.0, hold_s: float = 20.0,
                    rest: float = 3.5, rate: float = 100.0, noise: float = 0.0,
                    offset: float = 0.0, encoder: bool = False, release: bool = True,
                    seed=None, location: str = "A0", trial: int = 1) -> SynthTrial:
    """One synthetic ramp-hold-release trial of QLV tissue (module docstring).

    Parameters
    ----------
    stiffness : float
        k [N/m] of the elastic part.
    fractions, times_s : sequence of float
        Prony g_i and tau_i [s].
    stiffening : float
        beta [1/m]; 0 for the linear elastic part.
    depth, ramp_s, hold_s, rest : float
        Peak depth [m], ramp time, hold time, rest at each end [s].
    rate : float
        Sampling rate [Hz]; the knots fall on samples when their times are multiples of 1/rate.
    noise : float
        White force noise SD as a fraction of the peak force [-].
    offset : float
        Force sensor offset [N].
    encoder : bool
        Round the displacement to encoder steps (0.025 mm).
    release : bool
        End with the release and a rest (else the record ends in the hold).
    seed : int or numpy.random.Generator, optional
    location, trial : str, int
        Labels.
    """
    rng = np.random.default_rng(seed)
    kt, kd = ramp_hold_path(depth, ramp_s, hold_s, rest, release)
    n = int(round(kt[-1] * rate)) + 1
    t = np.arange(n) / rate
    f = qlv_path_force(t, kt, kd, stiffness, fractions, times_s, stiffening)
    f = np.maximum(f, 0.0)
    peak = float(f.max())
    f = f + offset + noise * peak * rng.standard_normal(n)
    d = np.interp(t, kt, kd)
    if encoder:
        d = np.round(d / ENCODER_STEP) * ENCODER_STEP
    return SynthTrial(location=location, trial=int(trial), time=t, displacement=d, force=f,
                      stiffness=float(stiffness), hysteresis=float("nan"), rate=float(rate),
                      n_pushes=1, stiffening=float(stiffening))
