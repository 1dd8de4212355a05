"""report.md of ``phri compare``: the inputs, the method, the RMSE tables, the figure index.

The markdown only, from plain data (the config, the manifest, the summary
table, one row per trial and loaded condition);
:func:`phri_spring.workflows.compare.run.write_compare` gathers them and writes it.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..tissue_law_text import arms_law_text

__all__ = ["compare_report", "summary_markdown", "rmse_markdown", "bands_markdown"]


def _fmt(x, digits=2) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


def summary_markdown(summary, arms: Sequence[str]) -> str:
    """The summary as a Markdown table: one line per experiment, direction and condition.

    Parameters
    ----------
    summary : pandas.DataFrame
        The ``summary.csv`` table: experiment, direction, condition, arm,
        mean_rmse_N and se_rmse_N [N], n_trials, load_N [N].
    arms : sequence of str
        The arm models, in the order of their columns.

    Returns
    -------
    str
        Columns: experiment, direction, condition, load [N], then per arm model
        ``<arm> RMSE [N]`` as mean +- standard error, and the number of trials.
    """
    s = summary
    head = ["experiment", "direction", "condition", "load [N]"] + \
        [f"{a} RMSE [N], mean ± SE" for a in arms] + ["trials"]
    lines = ["| " + " | ".join(head) + " |",
             "|" + "|".join(["---"] * 3 + ["---:"] * (len(arms) + 2)) + "|"]
    keys = list(dict.fromkeys(zip(s["experiment"], s["direction"], s["condition"])))
    for exp, direc, cond in keys:
        g = s[(s["experiment"] == exp) & (s["direction"] == direc) & (s["condition"] == cond)]
        cells = [str(exp), str(direc), str(cond), _fmt(float(g["load_N"].iloc[0]), 1)]
        n = 0
        for arm in arms:
            a = g[g["arm"] == arm]
            if len(a):
                cells.append(f"{_fmt(float(a['mean_rmse_N'].iloc[0]), 3)} ± "
                             f"{_fmt(float(a['se_rmse_N'].iloc[0]), 3)}")
                n = max(n, int(a["n_trials"].iloc[0]))
            else:
                cells.append("")
        cells.append(str(n))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def rmse_markdown(rows, arms: Sequence[str]) -> str:
    """The RMSE of every trial and loaded condition as a Markdown table.

    Parameters
    ----------
    rows : iterable of tuple
        ``(experiment, direction, trial, condition, load [N], {arm: RMSE [N]})``
        per trial and condition, the baseline left out.
    arms : sequence of str
    """
    head = ["experiment", "direction", "trial", "condition", "load [N]"] + \
        [f"{a} RMSE [N]" for a in arms]
    lines = ["| " + " | ".join(head) + " |",
             "|" + "|".join(["---"] * 4 + ["---:"] * (len(arms) + 1)) + "|"]
    for experiment, direction, trial, condition, load, rmse in rows:
        cells = [experiment, direction, str(trial), condition, _fmt(load, 1)] + \
            [_fmt(float(rmse[a]), 3) for a in arms]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def compare_report(cfg, manifest, *, arms: Sequence[str], n_trials: int, baselines,
                   tissue_stiffness_file, summary, rmse_rows, figures: bool,
                   fig_index=(), bands_markdown: str = "") -> str:
    """report.md of a comparison.

    Parameters
    ----------
    cfg : Config
    manifest : Manifest
    arms : sequence of str
    n_trials : int
    baselines : sequence of str
        The trials' baseline conditions, each once.
    tissue_stiffness_file : path or None
        A ``phri fit-stiffness`` CSV that replaced the config's map.
    summary : pandas.DataFrame
        The ``summary.csv`` table (see :func:`summary_markdown`).
    rmse_rows : iterable of tuple
        See :func:`rmse_markdown`.
    figures : bool
        Whether the figures were drawn (and are linked).
    fig_index : sequence of (TrialSpec, str, list of (str, str))
        Per trial: its spec, its wrench figure's path and (condition, heat-map
        path) pairs, paths relative to the output folder.
    bands_markdown : str
        The section on ``--uncertainty``'s bands (:func:`bands_markdown`), or ''.
    """
    man = manifest
    tissue = (f"`{tissue_stiffness_file}` (replacing the config's map)"
              if tissue_stiffness_file else "from the config")
    lines = [
        "# phri compare: rigid- vs compliant-arm predictions against the sensorized cuff",
        "",
        f"- config: `{cfg.path}`" + (f" ({cfg.name})" if cfg.name else ""),
        f"- experiment manifest: `{man.path}`" +
        (f": {man.description.strip()}" if man.description.strip() else ""),
        f"- trials: {n_trials}; elements: {len(cfg.labels)} "
        f"({cfg.labels[0]}..{cfg.labels[-1]}); arm models: {', '.join(arms)}",
        f"- tissue stiffness: {tissue}",
        f"- tissue law: {arms_law_text(cfg, arms)}",
        "- interface: " + ("bonded shear springs (the paper's)" if cfg.friction_coefficient is None
                           else f"Coulomb friction, mu = {cfg.friction_coefficient:g}, each "
                           f"trial's conditions solved in order as one loading path "
                           f"(docs/model.md section 12)"),
        f"- baseline condition(s): {', '.join(baselines)}",
        "",
        "Method: each condition's measured loads and wrench are the means over its rows; the "
        "simulated loads are the model's output at that mean wrench. Both sides are zeroed on "
        "their own baseline condition (measured minus measured at the baseline, simulated minus "
        "simulated at the baseline's mean wrench). RMSE = sqrt(sum_e (F_expt,e - F_sim,e)^2 / N) "
        f"with N = {len(cfg.labels)} elements (paper Eq. 1); SE = sample SD / sqrt(n trials). "
        "The baseline condition is not listed: its zeroed loads are 0 on both sides, so its RMSE "
        "is 0 by construction (it is kept in `loads.csv` and `conditions.csv`). The load is the "
        "magnitude of the condition's mean force minus the baseline's.",
        "",
        "## Summary (mean ± standard error over trials)",
        "",
        summary_markdown(summary, arms),
        "",
    ]
    if figures and len(summary):
        lines += ["![RMSE per condition and arm model (Fig. 7)](rmse_bars.png)", ""]
    lines += ["## RMSE per trial", "", rmse_markdown(rmse_rows, arms), ""]
    if bands_markdown:
        lines += [bands_markdown, ""]
    if figures:
        lines += ["## Figures per trial", "",
                  "Heat maps: zeroed loads measured | rigid | compliant, rows by angular "
                  "locations, one colour scale per figure (Fig. 8b). Wrench: the load-cell "
                  "reading over time with the condition windows shaded (Fig. 8a).", "",
                  "| experiment | direction | trial | wrench | heat maps |",
                  "|---|---|---|---|---|"]
        for s, wpath, heat in fig_index:
            links = ", ".join(f"[{c}]({p})" for c, p in heat)
            lines.append(f"| {s.experiment} | {s.direction} | {s.trial} | [wrench]({wpath}) | "
                         f"{links} |")
        lines.append("")
    lines += ["## Files", "",
              "- `rmse.csv`: experiment, direction, condition, trial, arm, rmse_N [N], load_N [N]",
              "- `summary.csv`: experiment, direction, condition, arm, mean_rmse_N [N], "
              "se_rmse_N [N], n_trials, load_N [N]",
              "- `loads.csv`: per trial, condition and element: zeroed measured_N and "
              "<arm>_N, absolute *_abs_N [N], the condition's mean wrench Fx..Mz "
              f"[{cfg.force_unit}, {cfg.moment_unit}], load_N, n_samples",
              "- `conditions.csv`: per trial and condition: n_samples, mean and zeroed wrench, "
              "load_N, rmse_<arm>_N", ""]
    return "\n".join(lines)


def bands_markdown(table, *, draws: int, seed: int, laws: dict, figures: bool) -> str:
    """The report section of ``phri compare --uncertainty``: the draws, and per arm model the
    tissue law the draws ran and what was perturbed.

    Parameters
    ----------
    table : pandas.DataFrame
        ``bands.csv`` (its ``arm`` and ``perturbed`` columns).
    draws, seed : int
    laws : dict of str -> str
        Arm model -> its tissue (:func:`~.tissue_law_text.arm_law_text`).
    figures : bool
        Whether ``bands/*.png`` were drawn.
    """
    lines = ["## Model bands (Monte Carlo)", "",
             f"{draws} draws (seed {seed}) of the uncertain inputs, the same draws for every "
             "arm model, each draw zeroed on its own baseline condition: the 5th, 50th and "
             "95th percentiles of the zeroed loads are in `bands.csv`"
             + (" and drawn per trial in `bands/`" if figures else "") + ".", "",
             "| arm | tissue | perturbed |", "|---|---|---|"]
    for arm in dict.fromkeys(table["arm"]):
        perturbed = str(table.loc[table["arm"] == arm, "perturbed"].iloc[0])
        lines.append(f"| {arm} | {laws.get(arm, '')} | {perturbed} |")
    return "\n".join(lines)
