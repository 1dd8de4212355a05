"""Figures of the QLV indenter fit, as ``matplotlib.figure.Figure`` objects (no pyplot).

- :func:`force_time_grid`: one panel per location, the force of each trial over time
  (from the onset, through the hold) with the fitted QLV model drawn over it.
"""

from __future__ import annotations

import math

from matplotlib.figure import Figure
from matplotlib.lines import Line2D

__all__ = ["force_time_grid"]

_FIT_STYLE = {"color": "black", "linestyle": "--", "linewidth": 1.0}


def _values_text(loc) -> str:
    fit = loc.fit
    if fit.prony is None:
        return "fit failed"
    text = f"k {fit.stiffness:.0f} N/m"
    if fit.elastic == "exponential":
        text += f", \u03b2 {fit.stiffening:.0f}/m"
    g = "/".join(f"{v:.2f}" for v in fit.fractions)
    tau = "/".join(f"{v:.3g}" for v in fit.times_s)
    return f"{text}\ng {g}, \u03c4 {tau} s"


def force_time_grid(locations, *, title: str | None = None, ncols: int | None = None,
                    panel_size=(3.2, 2.3)) -> Figure:
    """Force over time of every trial with the fitted QLV model, one panel per location.

    Parameters
    ----------
    locations : sequence of QlvLocationFit
    title : str, optional
    ncols : int, optional
        Panels per row (default up to 4).
    panel_size : (float, float)
        Size of one panel [inch].

    Returns
    -------
    matplotlib.figure.Figure
        One axes per location, in order (time [s] from the onset, force [N]).
    """
    locations = list(locations)
    n = max(len(locations), 1)
    ncols = ncols or min(n, 4)
    nrows = math.ceil(n / ncols)
    fig = Figure(figsize=(panel_size[0] * ncols + 0.6, panel_size[1] * nrows + 1.0),
                 layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False, sharey=True)
    n_trials_max = 0
    for j, loc in enumerate(locations):
        ax = axes[j // ncols, j % ncols]
        for i, w in enumerate(loc.windows):
            t0 = float(w.time[w.onset])
            ax.plot(w.time - t0, w.force, color=f"C{i % 10}", linewidth=0.8)
            ax.plot(w.time - t0, loc.fit.model(w, i), **_FIT_STYLE)
        n_trials_max = max(n_trials_max, len(loc.windows))
        flag = " *" if loc.flags else ""
        ax.set_title(f"{loc.location}{flag}: {_values_text(loc)}", fontsize=8,
                     color="tab:red" if flag else "black")
    for j in range(nrows * ncols):
        ax = axes[j // ncols, j % ncols]
        ax.tick_params(labelsize=7)
        ax.grid(True, linewidth=0.3, alpha=0.5)
        if j >= len(locations):
            ax.set_axis_off()
    for a in range(ncols):
        axes[-1, a].set_xlabel("time from onset [s]", fontsize=8)
    for r in range(nrows):
        axes[r, 0].set_ylabel("force [N]", fontsize=8)
    handles = [Line2D([], [], color=f"C{i % 10}", linewidth=1.2, label=f"trial {i + 1}")
               for i in range(n_trials_max)]
    handles.append(Line2D([], [], label="QLV fit", **_FIT_STYLE))
    fig.legend(handles=handles, loc="outside lower center", ncols=len(handles), fontsize=8,
               frameon=False)
    fig.suptitle(title or "Indenter force over time with the fitted quasi-linear "
                 "viscoelastic model (* flagged, see the flags column)", fontsize=10)
    return fig
