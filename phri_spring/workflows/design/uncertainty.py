"""Uncertainty of a design study's objectives at one design: Monte Carlo and Sobol indices.

:func:`study_uncertainty` draws the study's uncertain inputs (tissue stiffness, the
exponential law's stiffening rate, strap tension, load-cell noise;
:mod:`.uncertain_draws`) N times and evaluates the objectives over the load set for
each draw (each draw runs the design's tissue law); with SALib,
:func:`sobol_indices` gives the first-order and total Sobol indices of each
objective to each scalar input the arm uses (per-location tissue stiffness or
the continuum's modulus, per-location stiffening rate, strap tension): which
measurement is worth repeating.
Load-cell noise is random per sample, not one scalar, so it is in the Monte
Carlo but not in the indices. The report section is
:func:`phri_spring.reports.uncertainty.report.study_uncertainty_markdown`.
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import UsageError
from ...io.config import Config
from ...reports.tissue_law_text import arm_law_text
from ...reports.uncertainty.report import study_uncertainty_markdown
from ..uncertainty.draws import (PERCENTILES, UncertainInputs, check_fe_cache, config_at,
                              draw_configs, perturbed_text, sobol_inputs, uncertain_inputs)

__all__ = ["study_uncertainty", "sobol_indices"]


def _objectives_at(cfg, loads, arm, objectives) -> tuple[np.ndarray, np.ndarray]:
    """(objective values (k,) in the order of ``objectives``, each element's peak pressure
    over the load set (n,) [kPa]) of one design."""
    from .objectives import evaluate_design

    r = evaluate_design(cfg, loads, arm)
    return np.array([r[o] for o in objectives], dtype=float), r["element_peak_pressure_kPa"]


def study_uncertainty(cfg: Config, loads, arm: str, spec, objectives) -> dict:
    """Monte Carlo (and optional Sobol indices) of a study's objectives at one design.

    Parameters
    ----------
    cfg : Config
        The design (usually the best).
    loads : LoadSet
    arm : str
    spec : UncertaintySpec
        The study's ``uncertainty:`` section.
    objectives : sequence of str

    Returns
    -------
    dict
        ``tables`` (file name -> DataFrame: the objectives' percentiles, mean and SD
        in their units; each element's peak pressure percentiles [kPa]; the Sobol
        indices [-]) and ``markdown`` (a report section).
    """
    import pandas as pd

    from .objectives import LoadSet

    inputs = uncertain_inputs(cfg, tissue_sd=spec.tissue_stiffness_sd,
                              tension_sd_N=spec.strap_tension_sd_N,
                              force_sd_N=spec.loadcell_force_sd_N,
                              moment_sd_Nm=spec.loadcell_moment_sd_Nm,
                              stiffening_sd=getattr(spec, "stiffening_sd", "from_csv"))
    cfgs = draw_configs(cfg, inputs, spec.draws, spec.seed)
    check_fe_cache(cfg, inputs, [arm])
    perturbed = perturbed_text(cfg, inputs, arm)
    noisy = bool(inputs.noise_sd.any())
    if noisy:   # noise is per sample: expand the merged rows back to every sample
        full = np.repeat(loads.wrench_lc, loads.weights.astype(np.int64), axis=0)
        # each sample keeps its share of its merged row's time (the dose objective)
        seconds = None if loads.seconds is None else \
            np.repeat(loads.seconds / loads.weights, loads.weights.astype(np.int64))
    vals, peaks = [], []
    for d, c in enumerate(cfgs):
        ls = loads
        if noisy:
            rng = np.random.default_rng([int(spec.seed), 1, d])
            w = full + rng.standard_normal(full.shape) * inputs.noise_sd
            ls = LoadSet(w, np.ones(len(w)), len(w), seconds=seconds)
        v, p = _objectives_at(c, ls, arm, objectives)
        vals.append(v)
        peaks.append(p)
    V = np.array(vals)
    P = np.array(peaks)
    q = np.array(PERCENTILES)
    obj = pd.DataFrame({"objective": list(objectives),
                        **{f"p{x:g}": np.nanpercentile(V, x, axis=0) for x in q},
                        "mean": np.nanmean(V, axis=0), "sd": np.nanstd(V, axis=0, ddof=1),
                        "draws_converged": np.isfinite(V).sum(axis=0),
                        "perturbed": perturbed})
    pat = pd.DataFrame({"location": list(cfg.labels),
                        **{f"peak_pressure_kPa_p{x:g}": np.nanpercentile(P, x, axis=0)
                           for x in q}})
    tables = {"uncertainty_objectives.csv": obj, "uncertainty_patches.csv": pat}
    sob = None
    if spec.sobol:
        sob = sobol_indices(cfg, loads, arm, inputs, objectives, spec.sobol, spec.seed)
        if sob is not None:
            tables["sobol.csv"] = sob
    md = study_uncertainty_markdown(obj, draws=spec.draws, seed=spec.seed, arm=arm,
                                    perturbed=perturbed, objectives=objectives,
                                    sobol_base=spec.sobol, sobol=sob,
                                    tissue_law=arm_law_text(cfg, arm))
    return {"tables": tables, "markdown": md}


def sobol_indices(cfg: Config, loads, arm: str, inputs: UncertainInputs, objectives,
                  n_base: int, seed: int = 0):
    """First-order and total Sobol indices of each objective to each scalar input (SALib).

    Inputs: those the arm uses with a non-zero SD (:func:`.uncertain_draws.sobol_inputs`:
    each location's tissue stiffness, or the continuum's Young's modulus, each location's
    stiffening rate, and the strap tension), each Gaussian. Costs n_base * (D + 2)
    evaluations over the load set (D inputs).

    Returns
    -------
    pandas.DataFrame or None
        objective, input, S1, S1_conf, ST, ST_conf [-], note; None when no input has an
        SD. An objective some evaluation gave no value for (not converged), or that
        never varies, has NaN indices and its reason in ``note`` (empty otherwise).
    """
    import pandas as pd

    try:
        from SALib.analyze import sobol as sobol_analyze
        from SALib.sample import sobol as sobol_sample
    except ImportError:
        raise UsageError("Sobol indices need SALib: pip install -e .[sensitivity]",
                         key="uncertainty.sobol") from None
    scalars = sobol_inputs(cfg, inputs, arm)
    if not scalars:
        return None
    names = [nm for nm, *_ in scalars]
    which = [w for *_, w in scalars]
    problem = {"num_vars": len(names), "names": names,
               "bounds": [[mean, sd] for _, mean, sd, _ in scalars],
               "dists": ["norm"] * len(names)}
    X = sobol_sample.sample(problem, int(n_base), calc_second_order=False, seed=int(seed))
    Y = np.empty((len(X), len(objectives)))
    for i, x in enumerate(X):
        Y[i] = _objectives_at(config_at(cfg, which, x), loads, arm, objectives)[0]
    rows = []
    for j, o in enumerate(objectives):
        y = Y[:, j]
        bad = int(np.count_nonzero(~np.isfinite(y)))
        note = (f"unavailable: {bad} of {len(y)} evaluations did not converge" if bad else
                f"unavailable: the objective is the same in all {len(y)} evaluations (no "
                "variance to apportion)" if np.ptp(y) == 0 else "")
        if note:
            rows += [{"objective": o, "input": nm, "S1": math.nan, "S1_conf": math.nan,
                      "ST": math.nan, "ST_conf": math.nan, "note": note} for nm in names]
            continue
        res = sobol_analyze.analyze(problem, y, calc_second_order=False, seed=int(seed))
        for i, nm in enumerate(names):
            rows.append({"objective": o, "input": nm, "S1": float(res["S1"][i]),
                         "S1_conf": float(res["S1_conf"][i]), "ST": float(res["ST"][i]),
                         "ST_conf": float(res["ST_conf"][i]), "note": ""})
    return pd.DataFrame(rows)
