"""Text of the Monte Carlo outputs: a design study's uncertainty section, the summary line
of ``phri simulate --uncertainty``.

Plain data in, text out: the numbers come from
:func:`phri_spring.workflows.design.uncertainty.study_uncertainty` and
:func:`phri_spring.workflows.uncertainty.run.simulate_uncertainty_file`.
"""

from __future__ import annotations

import math
from typing import Optional, Sequence

__all__ = ["study_uncertainty_markdown", "monte_carlo_summary_line"]


def study_uncertainty_markdown(objectives_table, *, draws: int, seed: int, arm: str,
                               perturbed: str, objectives: Sequence[str] = (),
                               sobol_base: Optional[int] = None, sobol=None,
                               tissue_law: str = "") -> str:
    """The report section of a study's Monte Carlo (and Sobol indices) at its best design.

    Parameters
    ----------
    objectives_table : pandas.DataFrame
        One row per objective: ``objective``, ``p5``, ``p50``, ``p95`` (in the
        objective's unit) and ``draws_converged``.
    draws, seed : int
        Monte Carlo draws and their seed.
    arm : str
    perturbed : str
        The inputs that scattered for the arm.
    objectives : sequence of str
        The objectives, in the order their Sobol rows are listed.
    sobol_base : int, optional
        Saltelli base samples when Sobol indices were asked for (None or 0: not asked).
    sobol : pandas.DataFrame, optional
        The indices (``objective``, ``input``, ``S1``, ``ST`` [-], ``note``); None
        when no input the arm uses has an SD.
    tissue_law : str
        The arm's tissue the draws ran (``exponential tissue law (beta 150 1/m)``);
        '' leaves it out.

    Returns
    -------
    str
        Markdown, without a trailing newline.
    """
    obj = objectives_table
    md = ["## Uncertainty of the best design", "",
          f"Monte Carlo, {draws} draws (seed {seed}), {arm} arm "
          "(uncertainty_objectives.csv, uncertainty_patches.csv). "
          + (f"Tissue: {tissue_law}. " if tissue_law else "")
          + f"Perturbed for this arm: {perturbed}.", "",
          "| objective | p5 | p50 | p95 |", "|---|---|---|---|"]
    for _, r in obj.iterrows():
        md.append(f"| {r['objective']} | {r['p5']:.4g} | {r['p50']:.4g} | {r['p95']:.4g} |")
    lost = draws - obj["draws_converged"].min()
    if lost:
        md += ["", f"{lost} of {draws} draws did not converge and are left out."]
    if sobol_base:
        md += _sobol_markdown(sobol, sobol_base, arm, objectives)
    return "\n".join(md)


def _sobol_markdown(sob, n_base: int, arm: str, objectives) -> list:
    """Lines of the Sobol table: the three inputs of largest total index per objective."""
    if sob is None:
        return ["", f"(No Sobol indices: no input the {arm} arm uses has a non-zero SD.)"]
    md = ["", "Sobol indices (SALib, Saltelli sampling with "
          f"{n_base} base samples; sobol.csv): the inputs with the largest total "
          "index ST are the measurements most worth repeating.", "",
          "| objective | input | S1 | ST |", "|---|---|---|---|"]
    notes = []
    for o in objectives:
        mine = sob[sob["objective"] == o]
        if mine["note"].iloc[0]:     # unavailable: never printed as a measured 0
            md.append(f"| {o} | (all) | unavailable | unavailable |")
            notes.append(f"- {o}: {mine['note'].iloc[0]}.")
            continue
        for _, r in mine.sort_values("ST", ascending=False).head(3).iterrows():
            md.append(f"| {o} | {r['input']} | {r['S1']:.3f} | {r['ST']:.3f} |")
    if notes:
        md += ["", *notes]
    return md


def monte_carlo_summary_line(output, *, samples: int, elements: int, draws: int, seed: int,
                             not_converged: int, perturbed: str,
                             max_pain_ratio_p95: float = math.nan,
                             max_pain_ratio_time: float = math.nan,
                             tissue_law: str = "", dose: Optional[tuple] = None) -> str:
    """The line ``phri simulate --uncertainty`` ends with: sizes, draws, the peak.

    Parameters
    ----------
    output : path
        The percentile table written.
    samples, elements, draws, seed, not_converged : int
        Samples of the log, cuff elements, Monte Carlo draws and their seed,
        (draw, sample) pairs the solver did not converge on.
    perturbed : str
        The inputs that scattered ('' or ``none``: none did).
    max_pain_ratio_p95 : float
        The largest 95th percentile of peak pressure / pain threshold [-] (NaN: none).
    max_pain_ratio_time : float
        Its time [s].
    tissue_law : str
        The arm and its tissue law the draws ran (``compliant arm: exponential tissue law,
        beta 150 1/m``); '' leaves it out.
    dose : tuple, optional
        With a tolerance curve: ``(curve name, p5, p50, p95)`` of the largest dose over
        the elements at the end of the log [-].
    """
    peak = (f"; 95th percentile of peak pressure up to {100 * max_pain_ratio_p95:.3g}%"
            f" of the pain threshold (t = {max_pain_ratio_time:g} s)"
            if math.isfinite(max_pain_ratio_p95) else "")
    bad = (f"; {not_converged} draw-samples did not converge and were left out"
           if not_converged else "")
    return (f"wrote {output} ({samples:,} samples x {elements} elements, "
            f"5/50/95th percentiles over {draws} Monte Carlo draws, seed {seed}"
            f"{bad}; {tissue_law + '; ' if tissue_law else ''}perturbed: {perturbed or 'none'})"
            f"{peak}{_dose_clause(dose)}")


def _dose_clause(dose) -> str:
    if dose is None:
        return ""
    name, p5, p50, p95 = dose
    return (f"; dose ({name}) at the end, largest over the elements: p5 {p5:.3g}, "
            f"p50 {p50:.3g}, p95 {p95:.3g}")
