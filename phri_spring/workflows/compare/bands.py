"""``phri compare --uncertainty N``: Monte Carlo bands of the arm models' zeroed loads.

:func:`compare_bands` solves every trial's condition-mean wrenches again for N
draws of the config's uncertain inputs (:mod:`.uncertain_draws`) and zeroes
each draw on its own baseline condition, as :func:`.compare.compare` zeroes the
prediction; :func:`write_compare_bands` writes ``bands.csv`` and one figure per
trial into the compare output folder.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np

from ...errors import UsageError
from ...physics.contact.solver import solve_segments
from ...reports.compare.report import bands_markdown
from ...reports.tissue_law_text import arm_law_text
from ..common import model_from_config
from ..uncertainty.draws import (PERCENTILES, check_fe_cache, draw_configs, parse_sd,
                              perturbed_text, reaches_model, uncertain_inputs)

__all__ = ["compare_bands", "write_compare_bands", "bands_report_section"]


def compare_bands(result, *, draws: int, seed: int = 0, sd: Optional[str] = None):
    """Monte Carlo bands of a ``phri compare`` result's simulated (zeroed) loads.

    The config's uncertain inputs (tissue stiffness, the exponential law's stiffening
    rate, strap tension; see :func:`parse_sd`) are drawn ``draws`` times, the same draws
    for every arm, each arm taking what its model uses (:mod:`.uncertain_draws`: the
    coupled arm the continuum's modulus, the rigid arm no tissue; every draw runs the
    config's tissue law), and every trial's condition-mean
    wrenches solved again; each draw's loads are zeroed on its own baseline
    condition, as :func:`phri_spring.workflows.compare.run.compare` does. Load-cell
    noise is left out: the wrenches are means over a steady window.

    Parameters
    ----------
    result : CompareResult
    draws, seed
    sd : str, optional
        ``tissue=from_csv|FRACTION,stiffening=from_csv|FRACTION,tension=N`` (force and
        moment are ignored).

    Returns
    -------
    bands : dict
        (trial index, arm) -> ndarray (3, c, n) of the 5/50/95th percentiles [N].
    table : pandas.DataFrame
        experiment, direction, trial, condition, arm, location, measured_N,
        simulated_N, sim_p5_N, sim_p50_N, sim_p95_N, perturbed (what scattered for
        the row's arm; ``none``: the band is the prediction itself), tissue_law (the
        arm's tissue: ``exponential tissue law (beta 150 1/m)``, ``linear continuum``,
        ...).
    """
    import pandas as pd

    if int(draws) < 2:
        raise UsageError(f"expected at least 2 draws, got {draws}", key="--uncertainty")
    cfg = result.config
    kw = parse_sd(sd)
    kw["force_sd_N"] = kw["moment_sd_Nm"] = 0.0
    inputs = uncertain_inputs(cfg, **kw)
    cfgs = draw_configs(cfg, inputs, int(draws), seed)
    check_fe_cache(cfg, inputs, result.arms)
    W = np.vstack([tc.cuff_wrench for tc in result.trials])
    bounds = np.cumsum([0] + [len(tc.conditions) for tc in result.trials])
    bands, rows = {}, []
    q = np.array(PERCENTILES)
    for arm in result.arms:
        perturbed = perturbed_text(cfg, inputs, arm, noise=False)
        law = arm_law_text(cfg, arm)
        F = np.empty((len(cfgs), len(W), cfg.n_elements))
        if reaches_model(cfg, inputs, arm):
            for d, c in enumerate(cfgs):
                F[d] = solve_segments(model_from_config(c, arm), W, bounds,
                                      max_iterations=cfg.max_iterations).forces
        else:       # nothing this arm uses scatters: every draw is the config itself
            F[:] = solve_segments(model_from_config(cfg, arm), W, bounds,
                                  max_iterations=cfg.max_iterations).forces
        for t, tc in enumerate(result.trials):
            Ft = F[:, bounds[t]:bounds[t + 1]]
            Z = Ft - Ft[:, tc.baseline_index][:, None, :]
            P = np.nanpercentile(Z, q, axis=0) if np.isnan(Z).any() else np.percentile(Z, q,
                                                                                       axis=0)
            bands[(t, arm)] = P
            for i, cond in enumerate(tc.conditions):
                for j, lab in enumerate(cfg.labels):
                    rows.append({"experiment": tc.spec.experiment,
                                 "direction": tc.spec.direction, "trial": tc.spec.trial,
                                 "condition": cond, "arm": arm, "location": lab,
                                 "measured_N": tc.measured[i, j],
                                 "simulated_N": tc.simulated[arm][i, j],
                                 "sim_p5_N": P[0, i, j], "sim_p50_N": P[1, i, j],
                                 "sim_p95_N": P[2, i, j], "perturbed": perturbed,
                                 "tissue_law": law})
    return bands, pd.DataFrame(rows)


def bands_report_section(result, table, *, draws: int, seed: int, figures: bool) -> str:
    """The compare report's section on the bands: per arm, its tissue law and what scattered."""
    return bands_markdown(table, draws=int(draws), seed=int(seed), figures=figures,
                          laws={a: arm_law_text(result.config, a) for a in result.arms})


def write_compare_bands(result, bands, table, outdir, *, figures: bool = True,
                        dpi: int = 150) -> list:
    """Write ``bands.csv`` and ``bands/<trial>.png`` into a compare output folder (atomically)."""
    from ...io.outputs.atomic import atomic_file
    from ...reports.compare.figures import save_figure
    from ...reports.uncertainty.figures import bands_figure

    outdir = Path(outdir)
    files = []
    with atomic_file(outdir / "bands.csv") as tmp:
        table.to_csv(tmp, index=False, float_format="%.6f")
    files.append(outdir / "bands.csv")
    if figures:
        (outdir / "bands").mkdir(exist_ok=True)
        for t, tc in enumerate(result.trials):
            fig = bands_figure(tc.measured, {arm: bands[(t, arm)] for arm in result.arms},
                               conditions=tc.conditions, labels=result.labels,
                               baseline_index=tc.baseline_index,
                               title=f"{tc.spec.experiment} {tc.spec.direction} trial "
                                     f"{tc.spec.trial}: zeroed loads, model 5-95 % band")
            name = f"{tc.spec.experiment}_{tc.spec.direction}_{tc.spec.trial}".replace(" ", "_")
            path = outdir / "bands" / f"{name}.png"
            with atomic_file(path) as tmp:
                save_figure(fig, tmp, dpi=dpi)
            files.append(path)
    return files
