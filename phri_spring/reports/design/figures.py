"""Figures of ``phri design``, as matplotlib ``Figure`` objects (never pyplot).

- :func:`pareto_figure`                      the first two objectives of every design,
  Pareto designs joined, the best design marked.
- :func:`objectives_vs_parameters_figure`    each objective against each varied parameter.
- :func:`peak_pressure_heatmap_figure`       the best design's peak pressure per element.
"""

from __future__ import annotations

from typing import Optional, Sequence

import numpy as np
from matplotlib.figure import Figure

from ..figure_base import figure_style

__all__ = ["pareto_figure", "objectives_vs_parameters_figure", "peak_pressure_heatmap_figure"]

_FEASIBLE = "#0072B2"
_PARETO = "#D55E00"
_INFEASIBLE = "0.7"


def pareto_figure(table, objectives: Sequence[str], senses: Sequence[int] = (),
                  best: Optional[int] = None) -> Figure:
    """Designs in the plane of the first two objectives (one objective: against design id).

    Parameters
    ----------
    table : pandas.DataFrame
        designs.csv: ``design``, the objectives, ``feasible`` and ``pareto``.
    objectives : sequence of str
        Objective names; the first two are drawn.
    senses : sequence of int
        +1 minimised, -1 maximised (shown in the axis labels).
    best : int, optional
        Design id to mark.

    Returns
    -------
    matplotlib.figure.Figure
        One axes; infeasible designs grey crosses, feasible blue dots, Pareto designs
        orange (joined in order of the first objective), the best a star.
    """
    senses = list(senses) or [1] * len(objectives)
    feas = table["feasible"].to_numpy(bool)
    par = table["pareto"].to_numpy(bool)
    if len(objectives) >= 2:
        x = table[objectives[0]].to_numpy(float)
        y = table[objectives[1]].to_numpy(float)
        xl = objectives[0] + (" (maximised)" if senses[0] < 0 else "")
        yl = objectives[1] + (" (maximised)" if senses[1] < 0 else "")
    else:
        x = table["design"].to_numpy(float)
        y = table[objectives[0]].to_numpy(float)
        xl, yl = "design", objectives[0] + (" (maximised)" if senses[0] < 0 else "")
    with figure_style():
        fig = Figure(figsize=(5.6, 4.2), layout="constrained")
        ax = fig.subplots()
        ax.scatter(x[~feas], y[~feas], marker="x", s=14, color=_INFEASIBLE, lw=0.8,
                   label=f"infeasible ({int((~feas).sum())})")
        ax.scatter(x[feas & ~par], y[feas & ~par], s=12, color=_FEASIBLE, alpha=0.7,
                   label=f"feasible ({int((feas & ~par).sum())})")
        order = np.argsort(x[par], kind="stable")
        ax.plot(x[par][order], y[par][order], "-o", color=_PARETO, ms=4, lw=1.0,
                label=f"Pareto ({int(par.sum())})")
        if best is not None and best >= 0:
            ax.scatter([x[best]], [y[best]], marker="*", s=160, color="black", zorder=5,
                       label=f"best (design {best})")
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7.5, loc="best")
        ax.set_title("Designs and their Pareto front")
    return fig


def objectives_vs_parameters_figure(table, parameters: Sequence[str],
                                    objectives: Sequence[str]) -> Figure:
    """A grid of panels: objective (row) against varied parameter (column).

    Returns
    -------
    matplotlib.figure.Figure
        len(objectives) x len(parameters) axes; Pareto designs in orange.
    """
    nr, nc = len(objectives), len(parameters)
    feas = table["feasible"].to_numpy(bool)
    par = table["pareto"].to_numpy(bool)
    with figure_style():
        fig = Figure(figsize=(min(2.6 * nc + 0.8, 16), min(2.1 * nr + 0.6, 14)),
                     layout="constrained")
        axes = fig.subplots(nr, nc, squeeze=False)
        for i, o in enumerate(objectives):
            y = table[o].to_numpy(float)
            for j, p in enumerate(parameters):
                ax = axes[i, j]
                x = table[p].to_numpy(float)
                ax.scatter(x[~feas], y[~feas], marker="x", s=8, color=_INFEASIBLE, lw=0.6)
                ax.scatter(x[feas & ~par], y[feas & ~par], s=7, color=_FEASIBLE, alpha=0.6)
                ax.scatter(x[par], y[par], s=10, color=_PARETO)
                pos = x[np.isfinite(x)]
                if pos.size and np.all(pos > 0) and pos.max() / pos.min() > 50:
                    ax.set_xscale("log")
                if i == nr - 1:
                    ax.set_xlabel(p, fontsize=8)
                if j == 0:
                    ax.set_ylabel(o, fontsize=7)
                ax.tick_params(labelsize=7)
                ax.grid(alpha=0.3)
    return fig


def peak_pressure_heatmap_figure(peak_kpa, *, row_labels: Sequence[str], n_angles: int,
                                 pain_threshold_kpa: float = 120.0, title: str = "") -> Figure:
    """Peak pressure [kPa] of each element on the rows x angles grid.

    Parameters
    ----------
    peak_kpa : array_like, shape (n,)
        Max over the load set of each element's pressure [kPa], row-major.
    row_labels : sequence of str
    n_angles : int
    pain_threshold_kpa : float
        Upper end of the colour scale (cells above it are outlined in black).
    title : str

    Returns
    -------
    matplotlib.figure.Figure
        One heat-map axes and a colour bar labelled ``peak pressure [kPa]``.
    """
    v = np.asarray(peak_kpa, dtype=float)
    n_rows = len(row_labels)
    if v.size != n_rows * n_angles:
        raise ValueError(f"peak_pressure_heatmap_figure: expected {n_rows * n_angles} values, "
                         f"got {v.size}")
    grid = v.reshape(n_rows, n_angles)
    vmax = max(float(pain_threshold_kpa), float(np.nanmax(grid)) if np.isfinite(grid).any()
               else 1.0)
    with figure_style():
        cell = 0.5
        fig = Figure(figsize=(max(n_angles * cell + 2.2, 4.8), n_rows * cell + 1.6),
                     layout="constrained")
        ax = fig.subplots()
        im = ax.imshow(grid, cmap="magma_r", vmin=0.0, vmax=vmax, aspect="equal")
        ax.set_xticks(np.arange(n_angles), [str(i) for i in range(n_angles)])
        ax.set_yticks(np.arange(n_rows), list(row_labels))
        ax.set_xlabel("angular location")
        ax.set_ylabel("row")
        for r in range(n_rows):
            for c in range(n_angles):
                val = grid[r, c]
                if np.isfinite(val):
                    ax.text(c, r, f"{val:.0f}", ha="center", va="center", fontsize=7,
                            color="white" if val > 0.55 * vmax else "0.1")
                    if val >= pain_threshold_kpa:
                        ax.add_patch(_box(c, r))
        cbar = fig.colorbar(im, ax=ax, shrink=0.85)
        cbar.set_label("peak pressure [kPa]")
        if title:
            ax.set_title(title, fontsize=9)
    return fig


def _box(c, r):
    from matplotlib.patches import Rectangle

    return Rectangle((c - 0.5, r - 0.5), 1, 1, fill=False, ec="black", lw=1.5)
