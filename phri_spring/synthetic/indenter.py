"""Synthetic indenter trials with a known stiffness (for examples and tests).

What a hand-held indenter session looks like, made up with a fixed seed:

- a rest of ``rest`` seconds (>= 3 s) at the start, the indenter a little off
  the arm, with small hand drift; the force sensor has an offset and white noise;
- one or several pushes per trial, each an approach, a press to a random depth
  at an irregular (time-warped) speed with hand tremor, an optional short hold,
  and a release back off the arm;
- a linear tissue with mild hysteresis of the Oliver-Pharr kind: loading is
  softer than unloading. With ``k`` the unloading (true) stiffness and ``h`` the
  hysteresis ratio, the force at depth d is ``k * max(0, d - h * dmax)``, dmax
  the deepest point so far in the push (the dent recovers between pushes).
  Loading therefore follows slope ``(1 - h) k``, every unloading or reloading
  below dmax follows slope ``k``, and the hysteresis ratio
  ``(W_load - W_unload) / W_load`` of a push is exactly ``h``;
- or, with ``stiffening`` beta > 0 [1/m], a tissue that stiffens: the same dent,
  with the exponential (Fung-type) law ``F(x) = (k / beta) (exp(beta x) - 1)`` of
  the compression ``x = max(0, d - h * dmax)`` in place of ``k x``. Every
  unloading stroke then follows that law exactly, with k the slope at contact and
  the contact point ``h * dmax`` (loading follows ``F((1 - h) d)``, softer; the
  hysteresis ratio is then close to, not exactly, ``h``);
- an encoder with 0.025 mm steps (1/500 inch) and an arbitrary zero;
- sampling rates of 100 to 500 Hz.

The truth map is a rows x angles grid drawn around the paper's
4242 +- 251.5 N/m and rescaled so that its mean and sample SD are exactly those.
Everything here is synthetic and labelled so wherever it is written.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["ENCODER_STEP", "PAPER_MEAN", "PAPER_SD", "SynthTrial", "truth_map",
           "synth_trial", "synth_dataset", "write_trials", "write_truth"]

#: encoder resolution [m] (US Digital EM1, 1/500 inch)
ENCODER_STEP = 0.025e-3
#: the paper's mean indenter stiffness over 21 locations [N/m]
PAPER_MEAN = 4242.0
#: the paper's SD over the 21 locations [N/m]
PAPER_SD = 251.5


@dataclass(frozen=True)
class SynthTrial:
    """One synthetic trial.

    Attributes
    ----------
    location : str
        Element label (``B3``).
    trial : int
        Trial number (1, 2, ...).
    time : ndarray
        [s]
    displacement : ndarray
        Encoder reading, multiples of :data:`ENCODER_STEP`, positive into the arm [m].
    force : ndarray
        Raw force with offset and noise [N].
    stiffness : float
        True unloading stiffness [N/m] (with stiffening: the slope at contact, k0).
    hysteresis : float
        True hysteresis ratio [-] (with stiffening: the dent fraction h).
    rate : float
        Sampling rate [Hz].
    n_pushes : int
    stiffening : float
        True stiffening rate beta [1/m]; 0 for the linear tissue.
    """

    location: str
    trial: int
    time: np.ndarray
    displacement: np.ndarray
    force: np.ndarray
    stiffness: float
    hysteresis: float
    rate: float
    n_pushes: int
    stiffening: float = 0.0


def truth_map(seed: int = 4242, rows: str = "ABC", n_angles: int = 7,
              mean: float = PAPER_MEAN, sd: float = PAPER_SD) -> dict[str, float]:
    """True stiffness per location, mean and sample SD exactly ``mean`` and ``sd``.

    Parameters
    ----------
    seed : int
        Random seed.
    rows : str or sequence of str
        Row labels.
    n_angles : int
        Angular locations per row.
    mean, sd : float
        Mean and sample standard deviation (ddof = 1) over the map [N/m].

    Returns
    -------
    dict
        Element label -> stiffness [N/m], in row-major order.
    """
    rng = np.random.default_rng(seed)
    n = len(rows) * n_angles
    z = rng.standard_normal(n)
    if n > 1:
        z = (z - z.mean()) / z.std(ddof=1)
        values = mean + sd * z
    else:
        values = np.array([mean])
    labels = [f"{r}{j}" for r in rows for j in range(n_angles)]
    return {lab: float(v) for lab, v in zip(labels, values)}


def _warp(rng, n: int) -> np.ndarray:
    """Monotone map [0, 1] -> [0, 1] with an irregular speed (a hand's)."""
    if n < 2:
        return np.ones(n)
    u = np.linspace(0.0, 1.0, n)
    speed = np.ones(n)
    for _ in range(3):
        speed += rng.uniform(0.1, 0.35) * np.sin(2 * np.pi * rng.uniform(0.5, 2.5) * u
                                                 + rng.uniform(0, 2 * np.pi))
    speed = np.clip(speed, 0.15, None)
    s = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]))])
    return s / s[-1]


def _ease(s: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 - np.cos(np.pi * s))


def synth_trial(stiffness: float, *, rate: float = 200.0, seed=None, location: str = "A0",
                trial: int = 1, n_pushes: int | None = None, hysteresis: float | None = None,
                rest: float | None = None, noise_sd: float | None = None,
                offset: float | None = None, depth_range=(2.5e-3, 5.0e-3),
                tremor: float = 0.012e-3, encoder_step: float = ENCODER_STEP,
                encoder_sign: int = 1, stiffening: float = 0.0) -> SynthTrial:
    """One synthetic hand-held indentation trial with a known unloading stiffness.

    Parameters
    ----------
    stiffness : float
        True unloading stiffness k [N/m].
    rate : float
        Sampling rate [Hz].
    seed : int or numpy.random.Generator, optional
        Randomness (fixed seed -> identical trial).
    location, trial : str, int
        Labels carried along.
    n_pushes : int, optional
        Pushes in the trial (default random 1 to 3).
    hysteresis : float, optional
        Hysteresis ratio h in [0, 1) (default random 0.04 to 0.12): loading slope (1 - h) k.
    rest : float, optional
        Rest period at the start [s] (default random 3.5 to 4.5).
    noise_sd : float, optional
        Force noise SD [N] (default random 0.01 to 0.04).
    offset : float, optional
        Force sensor offset [N] (default random -2 to 2).
    depth_range : (float, float)
        Range of the push depths [m].
    tremor : float
        Amplitude of the hand tremor (8 to 12 Hz) [m].
    encoder_step : float
        Encoder resolution [m]; 0 for none.
    encoder_sign : {1, -1}
        -1 for an encoder that counts away from the arm.
    stiffening : float
        Stiffening rate beta >= 0 [1/m] of the exponential tissue
        ``F = (k / beta) (exp(beta x) - 1)``; 0 (default) the linear tissue
        (the trial is then the same, draw for draw, as without this option).

    Returns
    -------
    SynthTrial
    """
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    k = float(stiffness)
    beta = float(stiffening)
    if not (np.isfinite(beta) and beta >= 0):
        raise ValueError(f"stiffening: expected a finite rate >= 0 [1/m], got {stiffening!r}")
    h = rng.uniform(0.04, 0.12) if hysteresis is None else float(hysteresis)
    n_pushes = int(rng.integers(1, 4)) if n_pushes is None else int(n_pushes)
    rest = rng.uniform(3.5, 4.5) if rest is None else float(rest)
    noise_sd = rng.uniform(0.01, 0.04) if noise_sd is None else float(noise_sd)
    offset = rng.uniform(-2.0, 2.0) if offset is None else float(offset)
    dt = 1.0 / float(rate)

    gap = rng.uniform(0.3e-3, 1.2e-3)           # indenter tip off the arm at rest [m]
    pieces = [np.full(int(round(rest / dt)), -gap)]
    push_id = [np.full(pieces[0].size, -1)]
    for p in range(n_pushes):
        depth = rng.uniform(*depth_range)
        t_in, t_out = rng.uniform(0.8, 1.8), rng.uniform(0.8, 1.8)
        t_hold, t_pause = rng.uniform(0.0, 0.4), rng.uniform(0.5, 1.2)
        back = -rng.uniform(0.3e-3, 1.2e-3)
        n_in, n_out = max(int(round(t_in / dt)), 2), max(int(round(t_out / dt)), 2)
        start = pieces[-1][-1]
        seg_in = start + (depth - start) * _ease(_warp(rng, n_in))
        seg_hold = np.full(int(round(t_hold / dt)), depth)
        seg_out = depth + (back - depth) * _ease(_warp(rng, n_out))
        seg_pause = np.full(int(round(t_pause / dt)), back)
        seg = np.concatenate([seg_in, seg_hold, seg_out, seg_pause])
        pieces.append(seg)
        push_id.append(np.full(seg.size, p))
    d_true = np.concatenate(pieces)
    pid = np.concatenate(push_id)
    n = d_true.size
    t = np.arange(n) * dt
    # hand tremor and slow drift (about a tenth of a millimetre at most)
    f_tr = rng.uniform(8.0, 12.0)
    d_true = (d_true + tremor * np.sin(2 * np.pi * f_tr * t + rng.uniform(0, 2 * np.pi))
              + 0.02e-3 * np.sin(2 * np.pi * t / rng.uniform(6.0, 12.0)))

    # force: Oliver-Pharr-like hysteresis, dent recovers between pushes
    dmax = np.zeros(n)
    for p in range(n_pushes):
        m = pid == p
        dmax[m] = np.maximum.accumulate(np.maximum(d_true[m], 0.0))
    x_true = np.maximum(0.0, d_true - h * dmax)
    # the exponential law written out here, not taken from tissue_laws, so that the tests
    # of the fit check the package's law against an independent formula
    f_true = k * x_true if beta == 0 else k * np.expm1(beta * x_true) / beta
    force = f_true + offset + noise_sd * rng.standard_normal(n)

    x0 = rng.uniform(5e-3, 25e-3)               # encoder zero somewhere on the rail
    x = encoder_sign * (x0 + d_true)
    if encoder_step > 0:
        x = np.round(x / encoder_step) * encoder_step
    return SynthTrial(location=location, trial=int(trial), time=t, displacement=x,
                      force=force, stiffness=k, hysteresis=float(h), rate=float(rate),
                      n_pushes=n_pushes, stiffening=beta)


def synth_dataset(truth: dict[str, float], *, seed: int = 0, trials_per_location: int = 2,
                  rates=(100.0, 200.0, 250.0, 500.0), trial_variation: float = 0.015,
                  stiffening=0.0, **kwargs) -> list[SynthTrial]:
    """Trials for every location of a truth map.

    Parameters
    ----------
    truth : dict
        Element label -> true stiffness [N/m]: the mean of the true stiffnesses
        of the location's trials, exactly.
    seed : int
        Random seed of the whole set.
    trials_per_location : int
    rates : sequence of float
        Sampling rates to draw from, one per trial [Hz].
    trial_variation : float
        Trial-to-trial variation of the true stiffness at a location (SD as a
        fraction, as when the indenter sits a little differently each time); the
        deviations are centred so that their mean over the trials is zero [-].
    stiffening : float or dict
        Stiffening rate beta [1/m] of the exponential tissue, one for all or
        element label -> beta (the same for every trial of a location); 0: linear.
    **kwargs
        Passed to :func:`synth_trial`.

    Returns
    -------
    list of SynthTrial
        ``SynthTrial.stiffness`` is the trial's own true stiffness.
    """
    rng = np.random.default_rng(seed)
    out = []
    for lab, k in truth.items():
        eps = trial_variation * rng.standard_normal(trials_per_location)
        if trials_per_location > 1:
            eps -= eps.mean()
        else:
            eps[:] = 0.0
        for tr in range(1, trials_per_location + 1):
            rate = float(rng.choice(np.asarray(rates, dtype=float)))
            beta = stiffening[lab] if isinstance(stiffening, dict) else stiffening
            out.append(synth_trial(k * (1.0 + eps[tr - 1]), rate=rate, seed=rng, location=lab,
                                   trial=tr, stiffening=beta, **kwargs))
    return out


def _frame(tr: SynthTrial, unit: str):
    import pandas as pd

    scale = 1e3 if unit == "mm" else 1.0
    return pd.DataFrame({"time": tr.time, "displacement": tr.displacement * scale,
                         "force": tr.force})


def write_trials(trials, path, *, layout: str = "folder", displacement_unit: str = "mm",
                 time_decimals: int = 4, displacement_decimals: int | None = None,
                 force_decimals: int = 4) -> list[Path]:
    """Write trials as a folder of ``<label>_<trial>.csv`` files or one long CSV.

    Parameters
    ----------
    trials : sequence of SynthTrial
    path : str or Path
        The folder (created if missing) or the long CSV file.
    layout : {'folder', 'long'}
    displacement_unit : {'mm', 'm'}
    time_decimals, displacement_decimals, force_decimals : int
        Decimals written (displacement default: 3 for mm, 6 for m, exact for
        0.025 mm steps).

    Returns
    -------
    list of Path
        The files written.
    """
    import pandas as pd

    if displacement_decimals is None:
        displacement_decimals = 3 if displacement_unit == "mm" else 6
    path = Path(path)
    fmt = {"time": time_decimals, "displacement": displacement_decimals,
           "force": force_decimals}

    def rounded(df):
        return df.round(fmt)

    if layout == "folder":
        path.mkdir(parents=True, exist_ok=True)
        files = []
        for tr in trials:
            f = path / f"{tr.location}_{tr.trial}.csv"
            rounded(_frame(tr, displacement_unit)).to_csv(f, index=False)
            files.append(f)
        return files
    if layout == "long":
        frames = []
        for tr in trials:
            df = rounded(_frame(tr, displacement_unit))
            df.insert(0, "trial", tr.trial)
            df.insert(0, "location", tr.location)
            frames.append(df)
        pd.concat(frames, ignore_index=True).to_csv(path, index=False)
        return [path]
    raise ValueError(f"layout: expected 'folder' or 'long', got {layout!r}")


def write_truth(truth: dict[str, float], path) -> Path:
    """Write the truth map as CSV ``location, true_stiffness_N_per_m``."""
    import pandas as pd

    path = Path(path)
    pd.DataFrame({"location": list(truth), "true_stiffness_N_per_m":
                  [round(v, 3) for v in truth.values()]}).to_csv(path, index=False)
    return path
