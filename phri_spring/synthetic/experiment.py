"""A synthetic sensorized-cuff experiment for ``phri compare`` (paper section III).

The "truth" is a spring network built directly with :mod:`phri_spring.physics`
from the config's geometry but with properties that are NOT those of either
model being compared:

- a tissue map drawn per element around 4242 +- 251.5 N/m (indenter basis,
  the paper's proxy-arm statistics, Fig. 6b),
- a strap tension a few newtons off the configured one,
- a cuff stiffness perturbed per element (log-normal),

always with soft tissue (the compliant structure). The measured loads then get
what a real FSR cuff adds: a gain error per sensor (a few percent), a
fraction of the load carried outside the sensors (x 0.9), a zero offset that
drifts between trials, 0.35 N noise, and no negative readings. The load cell
reads the true wrench (converted to its axes and units with
:func:`~phri_spring.physics.cuff.loadcell.cuff_to_loadcell` and the config's pose)
plus a little noise.

Experiments (three trials each by default, 100 Hz):

- ``I-Act``: the robot is fixed and the arm is loaded by hanging weights of
  11.1, 33.4 and 55.6 N (conditions ``no_load``, ``L1``, ``L2``, ``L3``);
  horizontal loading along the load cell's z axis, vertical along its y axis
  (paper section III and Fig. 8); the pulley is a couple of degrees off axis
  and the load acts a few millimetres along the arm from the cuff origin.
- ``II-Pass``: the arm is grounded and the robot drives the cuff through
  10 degrees (conditions ``start``, ``min``, ``mid``, ``max``), giving forces that
  grow through the motion with more misalignment, moments and trial-to-trial
  spread than the weights.

Between steady windows the wrench ramps smoothly and the ``condition`` cell is
empty.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from ..io.config import Config, load_config
from ..physics.cuff.loadcell import FORCE_UNITS, MOMENT_UNITS, cuff_to_loadcell
from ..physics.springs.model import SpringModel, build_model, tissue_element_stiffness
from ..physics.contact.solver import solve
from .indenter import PAPER_MEAN, PAPER_SD

__all__ = ["IACT_LOADS_N", "IPASS_LOADS_N", "LOADCELL_AXIS", "Truth", "truth_model",
           "trial_plan", "make_trial", "make_experiment"]

#: the I-Act hanging loads L1, L2, L3 [N] (paper section III-A)
IACT_LOADS_N = (11.1, 33.4, 55.6)
#: nominal II-Pass force at min, mid, max of the robot's motion [N] (assumption)
IPASS_LOADS_N = {"horizontal": (6.0, 13.0, 21.0), "vertical": (5.0, 11.0, 18.0)}
#: load-cell axis of each loading direction: horizontal = z, vertical = y (paper III, Fig. 8)
LOADCELL_AXIS = {"horizontal": 2, "vertical": 1}



@dataclass(eq=False)
class Truth:
    """The hidden spring network that generates the synthetic measurements.

    Attributes
    ----------
    model : SpringModel
        The truth network (compliant structure).
    tissue_indenter : ndarray, shape (n,)
        Indenter-basis tissue stiffness of each element [N/m].
    cuff_stiffness : ndarray, shape (n,)
        Cuff stiffness of each element [N/m].
    strap_tension : float
        Strap tension [N].
    fsr_gain : ndarray, shape (n,)
        Gain of each sensor [-] (before the fraction carried outside).
    carried_fraction : float
        Fraction of each element's load that reaches its sensor [-].
    """

    model: SpringModel
    tissue_indenter: np.ndarray
    cuff_stiffness: np.ndarray
    strap_tension: float
    fsr_gain: np.ndarray
    carried_fraction: float


def truth_model(cfg: Config, rng: np.random.Generator, *, strap_offset_n: float = 3.0,
                cuff_log_sd: float = 0.25, gain_sd: float = 0.04,
                carried_fraction: float = 0.9) -> Truth:
    """Draw a truth network from a config's geometry (see the module docstring).

    Parameters
    ----------
    cfg : Config
    rng : numpy.random.Generator
    strap_offset_n : float
        Truth strap tension minus the configured one [N].
    cuff_log_sd : float
        SD of the log of the per-element cuff-stiffness factor [-].
    gain_sd : float
        SD of the FSR gains around 1 [-].
    carried_fraction : float
        Fraction of the load that reaches the sensors [-].
    """
    from ..workflows.common import geometry_from_config

    geom = geometry_from_config(cfg)
    n = geom.n
    k_ind = rng.normal(PAPER_MEAN, PAPER_SD, n)  # proxy-arm map, paper Fig. 6b
    k_t = tissue_element_stiffness(k_ind, geom.areas, "indenter", cfg.indenter_diameter)
    k_c = np.asarray(cfg.cuff_stiffness, dtype=float)
    k_c = np.where(np.isfinite(k_c), k_c, 1e7) * np.exp(rng.normal(0.0, cuff_log_sd, n))
    tension = max(cfg.strap_tension + strap_offset_n, 0.0)
    model = build_model(geom, k_t, k_c, arm="compliant", shear_ratio=cfg.shear_ratio,
                        poisson_ratio=cfg.poisson_ratio, strap_tension=tension,
                        strap_model=cfg.strap_model, handle_angles_deg=cfg.handle_angles_deg,
                        handle_axial_position=cfg.strap_axial_position,
                        pain_threshold_kpa=cfg.pain_threshold_kpa)
    gain = rng.normal(1.0, gain_sd, n)
    return Truth(model=model, tissue_indenter=k_ind, cuff_stiffness=k_c, strap_tension=tension,
                 fsr_gain=gain, carried_fraction=float(carried_fraction))


def _normalized(v):
    return v / np.linalg.norm(v)


def _misaligned(d, rng, sd):
    """Unit vector near d, tilted by about ``sd`` radians."""
    return _normalized(d + rng.normal(0.0, sd, 3) * (1.0 - np.abs(d)))


def trial_plan(cfg: Config, experiment: str, direction: str, rng: np.random.Generator):
    """Conditions and true cuff wrenches of one trial.

    Returns
    -------
    baseline : str
    conditions : list of (str, ndarray (6,))
        Condition label and the wrench on the cuff (cuff frame, about its origin) [N, N*m].
    wobble : float
        Relative amplitude of the slow wrench oscillation within a window [-].
    """
    R = cfg.loadcell_rotation
    axis = LOADCELL_AXIS[direction]
    d = cfg.loadcell_sign * R[:, axis]           # cuff-frame direction of the load-cell axis
    if experiment == "I-Act":
        F0 = rng.normal(0.0, 0.4, 3)
        M0 = rng.normal(0.0, 0.01, 3)
        x_a = rng.normal(0.008, 0.003)           # m, where the load acts along the arm
        out = [("no_load", np.concatenate([F0, M0]))]
        for k, load in enumerate(IACT_LOADS_N):
            F = load * _misaligned(d, rng, 0.04)
            M = np.cross([x_a, 0.0, 0.0], F)
            out.append((f"L{k + 1}", np.concatenate([F0 + F, M0 + M])))
        return "no_load", out, 0.01
    if experiment == "II-Pass":
        F0 = rng.normal(0.0, 0.8, 3)
        M0 = rng.normal(0.0, 0.03, 3)
        x_a = rng.normal(0.015, 0.005)
        out = [("start", np.concatenate([F0, M0]))]
        levels = IPASS_LOADS_N[direction]
        for name, load in zip(("min", "mid", "max"), levels):
            mag = load * (1.0 + rng.normal(0.0, 0.06))
            F = mag * _misaligned(d, rng, 0.12)
            M = np.cross([x_a, 0.0, 0.0], F) + np.array([rng.normal(0.0, 0.02) * mag / levels[-1],
                                                         0.0, 0.0])
            out.append((name, np.concatenate([F0 + F, M0 + M])))
        return "start", out, 0.003
    raise ValueError(f"experiment: expected 'I-Act' or 'II-Pass', got {experiment!r}")


def make_trial(cfg: Config, truth: Truth, conditions, rng: np.random.Generator, *,
               rate_hz: float = 100.0, window_s: float = 2.0, transition_s: float = 1.0,
               wobble: float = 0.01, fsr_noise_n: float = 0.35,
               loadcell_noise=(0.08, 0.002)):
    """Samples of one trial: steady windows joined by smooth ramps.

    Parameters
    ----------
    cfg : Config
        For the load cell's pose, sign and units and the element labels.
    truth : Truth
    conditions : list of (str, ndarray (6,))
        From :func:`trial_plan`.
    rng : numpy.random.Generator
    rate_hz, window_s, transition_s : float
        Sample rate [Hz], window and ramp lengths [s].
    wobble : float
        Relative amplitude of a slow oscillation of the load in a window [-].
    fsr_noise_n : float
        SD of the FSR noise [N].
    loadcell_noise : (float, float)
        SD of the load-cell noise [N, N*m].

    Returns
    -------
    pandas.DataFrame
        ``time, Fx, Fy, Fz, Mx, My, Mz``, one column per element, ``condition``.
    """
    import pandas as pd

    n_win = max(int(round(window_s * rate_hz)), 1)
    n_tr = max(int(round(transition_s * rate_hz)), 0)
    W_parts, cond_parts = [], []
    for i, (name, W) in enumerate(conditions):
        if i > 0 and n_tr:
            prev = conditions[i - 1][1]
            s = (np.arange(1, n_tr + 1) / (n_tr + 1))
            s = s * s * (3.0 - 2.0 * s)                            # smoothstep ramp
            W_parts.append(prev + s[:, None] * (W - prev))
            cond_parts.append(np.full(n_tr, "", dtype=object))
        t = np.arange(n_win) / rate_hz
        phase = rng.uniform(0, 2 * np.pi)
        load = W - conditions[0][1]
        W_parts.append(W + wobble * np.sin(2 * np.pi * 0.7 * t + phase)[:, None] * load)
        cond_parts.append(np.full(n_win, name, dtype=object))
    W_true = np.vstack(W_parts)
    cond = np.concatenate(cond_parts)
    m = len(W_true)
    sol = solve(truth.model, W_true, max_iterations=max(cfg.max_iterations, 200))
    if not sol.converged.all():  # pragma: no cover - the solver converges on these loads
        raise RuntimeError("the truth model did not converge")
    n = truth.model.n
    offset = rng.uniform(0.2, 1.2, n)                               # FSR zero, drifts per trial
    measured = (truth.carried_fraction * truth.fsr_gain * sol.forces + offset
                + rng.normal(0.0, fsr_noise_n, (m, n)))
    measured = np.maximum(measured, 0.0)
    lc = cuff_to_loadcell(W_true, cfg.loadcell_rotation, cfg.loadcell_position,
                          cfg.loadcell_sign, FORCE_UNITS[cfg.force_unit],
                          MOMENT_UNITS[cfg.moment_unit])
    f_sd = loadcell_noise[0] / FORCE_UNITS[cfg.force_unit]
    m_sd = loadcell_noise[1] / MOMENT_UNITS[cfg.moment_unit]
    lc = lc + rng.normal(0.0, 1.0, lc.shape) * np.array([f_sd] * 3 + [m_sd] * 3)
    data = {"time": np.round(np.arange(m) / rate_hz, 4)}
    for j, c in enumerate(("Fx", "Fy", "Fz")):
        data[c] = np.round(lc[:, j], 3)
    for j, c in enumerate(("Mx", "My", "Mz")):
        data[c] = np.round(lc[:, 3 + j], 5)
    for j, lab in enumerate(truth.model.labels):
        data[lab] = np.round(measured[:, j], 2)
    data["condition"] = cond
    return pd.DataFrame(data)


_MANIFEST_HEADER = """\
# SYNTHETIC experiment for 'phri compare' (not measured data), made by
# {script} (seed {seed}) from a hidden "truth" network that is
# neither of the two models compared (see README.md in this folder).
# Trial files are relative to this manifest. Columns: time [s], Fx Fy Fz [N],
# Mx My Mz [N*m] (load-cell axes), A0..C6 measured load [N], condition.
baseline: no_load          # I-Act trials are zeroed on no_load; II-Pass trials on start
trials:
"""


def make_experiment(config, outdir, *, seed: int = 20230611, trials: int = 3,
                    experiments=(("I-Act", "horizontal"), ("I-Act", "vertical"),
                                 ("II-Pass", "horizontal"), ("II-Pass", "vertical")),
                    rate_hz: float = 100.0, window_s: float = 2.5, transition_s: float = 1.0,
                    script: str = "phri_spring.synthetic.experiment.make_experiment",
                    truth_csv: bool = True) -> Path:
    """Write a synthetic experiment: ``manifest.yaml`` and one CSV per trial.

    Parameters
    ----------
    config : Config or path
        The config whose geometry and load cell the experiment uses.
    outdir : path
        Folder to write (created; files of the same names are replaced).
    seed : int
        Seed of the random generator (the same seed gives the same files).
    trials : int
        Trials per experiment and direction.
    experiments : sequence of (experiment, direction)
        Among ``I-Act`` / ``II-Pass`` and ``horizontal`` / ``vertical``.
    rate_hz, window_s, transition_s : float
        Sample rate [Hz], steady-window and ramp lengths [s].
    truth_csv : bool
        Also write the truth's tissue map as ``truth_tissue_stiffness.csv``
        (the format of ``phri fit-stiffness``).

    Returns
    -------
    Path
        The manifest written.
    """
    from ..io.outputs.atomic import atomic_directory

    cfg = config if isinstance(config, Config) else load_config(config)
    rng = np.random.default_rng(seed)
    truth = truth_model(cfg, rng)
    outdir = Path(outdir)
    lines = [_MANIFEST_HEADER.format(script=script, seed=seed)]
    with atomic_directory(outdir) as tmp:
        for experiment, direction in experiments:
            stem = experiment.lower().replace("-", "")
            for k in range(1, trials + 1):
                baseline, conds, wobble = trial_plan(cfg, experiment, direction, rng)
                df = make_trial(cfg, truth, conds, rng, rate_hz=rate_hz, window_s=window_s,
                                transition_s=transition_s, wobble=wobble)
                name = f"{stem}_{direction}_{k}.csv"
                df.to_csv(tmp / name, index=False)
                extra = "" if baseline == "no_load" else f", baseline: {baseline}"
                lines.append(f"  - {{file: {name}, experiment: {experiment}, "
                             f"direction: {direction}, trial: {k}{extra}}}\n")
        (tmp / "manifest.yaml").write_text("".join(lines), encoding="utf-8")
        if truth_csv:
            _write_truth_csv(tmp / "truth_tissue_stiffness.csv", cfg, truth, seed)
    return outdir / "manifest.yaml"


def _write_truth_csv(path: Path, cfg: Config, truth: Truth, seed: int) -> None:
    n_ang = cfg.angle_count
    rows = ["# SYNTHETIC: the hidden truth's tissue map of this example experiment "
            f"(seed {seed}), indenter basis [N/m].",
            "location,row,angle_index,stiffness_N_per_m,std_N_per_m,n_trials"]
    for i, lab in enumerate(cfg.labels):
        rows.append(f"{lab},{cfg.row_labels[i // n_ang]},{i % n_ang},"
                    f"{truth.tissue_indenter[i]:.1f},0.0,1")
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")


def main(argv: Optional[list] = None) -> None:  # pragma: no cover - thin script entry
    import argparse

    ap = argparse.ArgumentParser(description="Write the synthetic compare experiment.")
    ap.add_argument("config")
    ap.add_argument("outdir")
    ap.add_argument("--seed", type=int, default=20230611)
    args = ap.parse_args(argv)
    print(make_experiment(args.config, args.outdir, seed=args.seed))
