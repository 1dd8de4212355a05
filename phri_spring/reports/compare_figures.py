"""Figures of ``phri compare`` (the paper's Figs. 7 and 8), as matplotlib ``Figure`` objects.

Only :class:`matplotlib.figure.Figure` is used (never pyplot), so the figures
work in any thread and need no display. Save them with :func:`save_figure`.

- :func:`rmse_bars_figure`  Fig. 7: mean RMSE per condition, rigid vs compliant,
  error bars = standard error, one panel per experiment and direction.
- :func:`heatmap_figure`    Fig. 8b: measured | rigid | compliant zeroed loads on
  the rows x locations grid, one diverging colour scale centred on zero.
- :func:`wrench_figure`     Fig. 8a: the load-cell wrench of a trial over time,
  with its condition windows shaded.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional, Sequence

import numpy as np
from matplotlib.figure import Figure

__all__ = ["ARM_COLORS", "ARM_NAMES", "rmse_bars_figure", "heatmap_figure", "wrench_figure",
           "condition_label", "save_figure", "DEFAULT_DPI"]

#: colour-blind-safe colours of the arm models (Okabe-Ito orange and blue)
ARM_COLORS = {"rigid": "#E69F00", "compliant": "#0072B2"}
#: how the arm models are named in figures
ARM_NAMES = {"rigid": "Rigid arm", "compliant": "Compliant arm"}
#: resolution of saved figures [dpi]
DEFAULT_DPI = 170

_FONT = {"font.size": 9, "axes.titlesize": 10, "axes.labelsize": 9, "xtick.labelsize": 8.5,
         "ytick.labelsize": 8.5, "legend.fontsize": 8.5}


def _style():
    import matplotlib

    return matplotlib.rc_context(_FONT)


def condition_label(condition: str, load_n: Optional[float]) -> str:
    """Tick label of a condition: the label and, when known, its load, e.g. ``L2\\n33.4 N``."""
    if load_n is None or not np.isfinite(load_n):
        return str(condition)
    return f"{condition}\n{load_n:.1f} N"


def rmse_bars_figure(summary, rmse=None, *, arms: Sequence[str] = ("rigid", "compliant"),
                     ncols: Optional[int] = None) -> Figure:
    """Fig. 7: grouped bars of the mean RMSE per condition, rigid vs compliant.

    Parameters
    ----------
    summary : pandas.DataFrame
        ``experiment, direction, condition, arm, mean_rmse_N, se_rmse_N, n_trials``
        and optionally ``load_N`` (the condition's mean load [N], shown in the
        tick labels). The baseline condition should not be in it.
    rmse : pandas.DataFrame, optional
        Per-trial ``experiment, direction, condition, arm, rmse_N``; each trial
        is drawn as a dot over its bar.
    arms : sequence of str
        Arm models to draw, in this order.
    ncols : int, optional
        Panels per row (default 2, or 1 for a single panel).

    Returns
    -------
    matplotlib.figure.Figure
        One axes per (experiment, direction), titled ``"<experiment>, <direction>"``,
        y label ``RMSE [N]``.
    """
    groups = list(dict.fromkeys(zip(summary["experiment"], summary["direction"])))
    if not groups:
        raise ValueError("rmse_bars_figure: the summary is empty")
    n = len(groups)
    ncols = ncols or (1 if n == 1 else 2)
    nrows = int(np.ceil(n / ncols))
    arms = [a for a in arms if a in set(summary["arm"])]
    with _style():
        fig = Figure(figsize=(3.7 * ncols, 2.9 * nrows + 0.35), layout="constrained")
        axes = fig.subplots(nrows, ncols, squeeze=False)
        for ax in axes.ravel()[n:]:
            fig.delaxes(ax)
        width = 0.8 / max(len(arms), 1)
        for (exp, direc), ax in zip(groups, axes.ravel()):
            sub = summary[(summary["experiment"] == exp) & (summary["direction"] == direc)]
            conds = list(dict.fromkeys(sub["condition"]))
            x = np.arange(len(conds))
            top = 0.0
            for k, arm in enumerate(arms):
                a = sub[sub["arm"] == arm].set_index("condition")
                mean = np.array([a["mean_rmse_N"].get(c, np.nan) for c in conds], dtype=float)
                se = np.array([a["se_rmse_N"].get(c, np.nan) for c in conds], dtype=float)
                pos = x + (k - (len(arms) - 1) / 2) * width
                ax.bar(pos, mean, width * 0.92, color=ARM_COLORS.get(arm, f"C{k}"),
                       label=ARM_NAMES.get(arm, arm), zorder=2,
                       yerr=np.where(np.isfinite(se), se, 0.0),
                       error_kw={"elinewidth": 1.0, "capsize": 3, "ecolor": "0.15"})
                top = max(top, np.nanmax(np.where(np.isfinite(se), mean + se, mean))
                          if np.isfinite(mean).any() else 0.0)
                if rmse is not None:
                    r = rmse[(rmse["experiment"] == exp) & (rmse["direction"] == direc)
                             & (rmse["arm"] == arm)]
                    for j, c in enumerate(conds):
                        vals = r.loc[r["condition"] == c, "rmse_N"].to_numpy(dtype=float)
                        if vals.size:
                            ax.plot(np.full(vals.size, pos[j]), vals, "o", ms=2.6,
                                    mfc="white", mec="0.1", mew=0.7, zorder=3)
                            top = max(top, float(np.nanmax(vals)))
            if "load_N" in sub.columns:
                loads = sub.drop_duplicates("condition").set_index("condition")["load_N"]
                ticks = [condition_label(c, loads.get(c)) for c in conds]
            else:
                ticks = list(conds)
            ax.set_xticks(x, ticks)
            ax.set_title(f"{exp}, {direc}")
            ax.set_ylabel("RMSE [N]")
            ax.set_ylim(0, top * 1.12 if top > 0 else 1.0)
            ax.grid(axis="y", color="0.88", lw=0.6, zorder=0)
            ax.set_axisbelow(True)
            for side in ("top", "right"):
                ax.spines[side].set_visible(False)
        handles, labels = axes.ravel()[0].get_legend_handles_labels()
        if rmse is not None:
            from matplotlib.lines import Line2D

            handles.append(Line2D([], [], ls="", marker="o", ms=3, mfc="white", mec="0.1"))
            labels.append("trial")
        fig.legend(handles, labels, loc="outside upper center", ncol=len(handles),
                   frameon=False)
    return fig


def heatmap_figure(measured, simulated: dict, *, row_labels: Sequence[str], n_angles: int,
                   title: str = "", rmse: Optional[dict] = None, cmap: str = "RdBu_r",
                   value_format: str = "{:.1f}") -> Figure:
    """Fig. 8b: zeroed loads measured | rigid | compliant on the element grid.

    Parameters
    ----------
    measured : array_like, shape (n,)
        Zeroed measured load of each element [N], row-major (A0..A6, B0..B6, ...).
    simulated : dict of str -> array_like, shape (n,)
        Zeroed simulated loads [N] of each arm model (``rigid``, ``compliant``).
    row_labels : sequence of str
        Row labels (A, B, C): the y axis, top to bottom.
    n_angles : int
        Angular locations (0..n_angles-1): the x axis.
    title : str
        Figure title (e.g. the trial, condition and wrench).
    rmse : dict of str -> float, optional
        RMSE [N] of each arm model, shown in its panel title.
    cmap : str
        A diverging colour map.
    value_format : str
        Format of the value written in each cell.

    Returns
    -------
    matplotlib.figure.Figure
        One heat-map axes per panel (titled ``Measured``, ``Rigid arm ...``,
        ``Compliant arm ...``) plus one colour-bar axes labelled
        ``zeroed load [N]``; all panels share one colour scale symmetric about 0.
    """
    n_rows = len(row_labels)
    panels = [("Measured (sensors)", np.asarray(measured, dtype=float))]
    for arm, values in simulated.items():
        name = ARM_NAMES.get(arm, arm)
        if rmse is not None and arm in rmse and np.isfinite(rmse[arm]):
            name = f"{name}\nRMSE {rmse[arm]:.2f} N"
        panels.append((name, np.asarray(values, dtype=float)))
    grids = []
    for name, v in panels:
        if v.size != n_rows * n_angles:
            raise ValueError(f"heatmap_figure: {name}: expected {n_rows * n_angles} values, "
                             f"got {v.size}")
        grids.append(v.reshape(n_rows, n_angles))
    finite = np.concatenate([g[np.isfinite(g)] for g in grids])
    vmax = float(np.max(np.abs(finite))) if finite.size else 0.0
    vmax = vmax if vmax > 0 else 1.0
    with _style():
        cell = 0.42
        fig = Figure(figsize=(max(len(panels) * (n_angles * cell + 0.55) + 1.1, 5.5),
                              n_rows * cell + 1.75), layout="constrained")
        axes = fig.subplots(1, len(panels), squeeze=False)[0]
        im = None
        for j, (ax, (name, _), grid) in enumerate(zip(axes, panels, grids)):
            im = ax.imshow(grid, cmap=cmap, vmin=-vmax, vmax=vmax, aspect="equal")
            ax.set_title(name)
            ax.set_xticks(np.arange(n_angles), [str(i) for i in range(n_angles)])
            ax.set_yticks(np.arange(n_rows), list(row_labels))
            ax.set_xlabel("angular location")
            if j == 0:
                ax.set_ylabel("row")
            ax.tick_params(length=0)
            ax.set_xticks(np.arange(-0.5, n_angles, 1), minor=True)
            ax.set_yticks(np.arange(-0.5, n_rows, 1), minor=True)
            ax.grid(which="minor", color="white", lw=1.2)
            ax.tick_params(which="minor", length=0)
            for side in ax.spines.values():
                side.set_visible(False)
            for r in range(n_rows):
                for c in range(n_angles):
                    val = grid[r, c]
                    if not np.isfinite(val):
                        continue
                    txt = value_format.format(val)
                    if txt.startswith("-") and not txt.strip("-0.").strip():
                        txt = txt[1:]                      # no "-0.0"
                    ax.text(c, r, txt, ha="center", va="center", fontsize=7,
                            color="white" if abs(val) > 0.55 * vmax else "0.1")
        cbar = fig.colorbar(im, ax=list(axes), shrink=0.8, pad=0.02, aspect=15)
        cbar.set_label("zeroed load [N]")
        if title:
            fig.suptitle(title, fontsize=9.5)
    return fig


def wrench_figure(time, wrench, conditions, *, title: str = "",
                  force_unit: str = "N", moment_unit: str = "N*m") -> Figure:
    """Fig. 8a: the load-cell wrench over time with the condition windows shaded.

    Parameters
    ----------
    time : array_like, shape (m,)
        Sample times [s].
    wrench : array_like, shape (m, 6)
        Load-cell readings Fx Fy Fz [force unit], Mx My Mz [moment unit].
    conditions : array_like of str, shape (m,)
        Condition of each sample ('' between windows).
    title : str
    force_unit, moment_unit : str
        Units for the axis labels.

    Returns
    -------
    matplotlib.figure.Figure
        Two axes: forces (x red, y green, z blue) and moments.
    """
    t = np.asarray(time, dtype=float)
    w = np.asarray(wrench, dtype=float)
    cond = np.asarray(conditions, dtype=object)
    colors = ("#d62728", "#2ca02c", "#1f77b4")
    with _style():
        fig = Figure(figsize=(7.0, 3.9), layout="constrained")
        ax_f, ax_m = fig.subplots(2, 1, sharex=True)
        for j, axis in enumerate("xyz"):
            ax_f.plot(t, w[:, j], color=colors[j], lw=0.9, label=f"F{axis}")
            ax_m.plot(t, w[:, 3 + j], color=colors[j], lw=0.9, label=f"M{axis}")
        ax_f.set_ylabel(f"force [{force_unit}]")
        ax_m.set_ylabel(f"moment [{moment_unit.replace('*', '·')}]")
        ax_m.set_xlabel("time [s]")
        # shade each steady window and name it
        edges = np.flatnonzero(np.r_[True, cond[1:] != cond[:-1]])
        ends = np.r_[edges[1:], len(cond)]
        for k, (s, e) in enumerate(zip(edges, ends)):
            if not cond[s]:
                continue
            for ax in (ax_f, ax_m):
                ax.axvspan(t[s], t[e - 1], color="0.5" if k % 2 else "0.7", alpha=0.15, lw=0)
            ax_f.text(0.5 * (t[s] + t[e - 1]), 1.0, str(cond[s]), ha="center", va="bottom",
                      fontsize=8, transform=ax_f.get_xaxis_transform())
        for ax in (ax_f, ax_m):
            ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), frameon=False)
            ax.grid(color="0.9", lw=0.6)
            for side in ("top", "right"):
                ax.spines[side].set_visible(False)
        if title:
            fig.suptitle(title, fontsize=9.5)
    return fig


def save_figure(fig: Figure, path, dpi: int = DEFAULT_DPI) -> Path:
    """Write a figure (PNG, PDF or SVG by the extension) without pyplot."""
    path = Path(path)
    with _style():
        fig.savefig(path, dpi=dpi)
    return path
