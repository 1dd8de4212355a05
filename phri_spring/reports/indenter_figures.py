"""Figures of the indenter analysis (paper Fig. 6), as ``matplotlib.figure.Figure`` objects.

- :func:`force_displacement_grid`: Fig. 6a for every location, a rows x angles
  grid of small force-depth panels with the fitted unloading lines (or, for
  locations fitted with the exponential law, the fitted exponential curves);
- :func:`indentation_response`: Fig. 6a for one location, loading and
  unloading drawn apart, with the fitted unloading lines;
- :func:`stiffness_map`: Fig. 6b, the rows x angles stiffness heat map with the
  values written in the cells and a colour bar in N/m.

No pyplot: the figures are built directly and saved with ``fig.savefig``
(Agg canvas), so nothing opens a window and nothing leaks between calls.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ..io.recordings.indenter import split_label
from ..physics.indentation.linear import LocationFit, TrialFit, location_statistics
from ..physics.indentation.exponential import ExponentialFit, ExponentialLocationFit

__all__ = ["force_displacement_grid", "indentation_response", "stiffness_map", "map_grid"]

_FIT_STYLE = {"color": "black", "linestyle": "--", "linewidth": 1.0}


def map_grid(locations, rows=None, n_angles=None):
    """Row labels, angle count and the (row, angle) cell of every location.

    Parameters
    ----------
    locations : sequence of LocationFit
    rows : sequence of str, optional
        Row labels top to bottom (default: those present, sorted A, B, ..., AA).
    n_angles : int, optional
        Angular locations (default: the largest angle index present + 1).

    Returns
    -------
    rows : list of str
    n_angles : int
    cells : list of (int, int)
        Grid cell of each location, in input order.
    """
    parsed = [split_label(loc.location) for loc in locations]
    if rows is None:
        rows = sorted({r for r, _ in parsed}, key=lambda r: (len(r), r))
    rows = list(rows)
    if n_angles is None:
        n_angles = max((a for _, a in parsed), default=-1) + 1
    cells = []
    for (r, a), loc in zip(parsed, locations):
        if r not in rows or a >= n_angles:
            raise ValueError(f"location {loc.location} is outside the rows {rows} x "
                             f"{n_angles} angles grid")
        cells.append((rows.index(r), a))
    return rows, int(n_angles), cells


def _contact_span(trial: TrialFit) -> slice:
    """From onset to the last sample in contact."""
    above = np.flatnonzero(trial.force > trial.threshold)
    stop = int(above[-1]) + 1 if above.size else trial.onset_index + 1
    return slice(trial.onset_index, stop)


def _fit_lines(ax, trial: TrialFit, fit: ExponentialFit | None = None, **style):
    """The unloading fits of a trial: straight lines, or the exponential ``fit``'s curves."""
    style = {**_FIT_STYLE, **style}
    if fit is not None:
        if fit.converged:
            for i in range(trial.unloading.n):
                dd, ff = fit.curve(i)
                ax.plot(dd * 1e3, ff, **style)
        return
    for k, b, s0, s1 in zip(trial.unloading.slope, trial.unloading.intercept,
                            trial.unloading.start, trial.unloading.stop):
        d = trial.depth[s0:s1]
        dd = np.array([d.min(), d.max()])
        ax.plot(dd * 1e3, k * dd + b, **style)


def _law_fits(location) -> tuple:
    """The exponential fits of a location's trials, or Nones for a linear LocationFit."""
    if isinstance(location, ExponentialLocationFit):
        return location.fits
    return (None,) * len(location.trials)


def _values_text(location) -> str:
    """``4242 N/m``, or k0 [N/m] and the stiffening rate [1/m] for the exponential law."""
    if isinstance(location, ExponentialLocationFit):
        return f"k0 {location.stiffness:.0f} N/m, \u03b2 {location.stiffening:.0f}/m"
    return f"{location.stiffness:.0f} N/m"


def force_displacement_grid(locations, *, rows=None, n_angles=None, title: str | None = None,
                            panel_size=(1.9, 1.5)) -> Figure:
    """Force-depth curves of every location with their fitted unloading lines (Fig. 6a).

    Parameters
    ----------
    locations : sequence of LocationFit or ExponentialLocationFit
        With ExponentialLocationFit the fitted exponential curves are drawn, and
        each panel's title gives k0 [N/m] and the stiffening rate beta [1/m].
    rows, n_angles : optional
        Grid layout (see :func:`map_grid`).
    title : str, optional
    panel_size : (float, float)
        Size of one panel [inch].

    Returns
    -------
    matplotlib.figure.Figure
        ``len(rows) * n_angles`` axes, row-major; panels without data say so.
    """
    rows, n_angles, cells = map_grid(locations, rows, n_angles)
    fig = Figure(figsize=(panel_size[0] * n_angles + 0.8, panel_size[1] * len(rows) + 1.2),
                 layout="constrained")
    axes = fig.subplots(len(rows), n_angles, sharex=True, sharey=True, squeeze=False)
    n_trials_max = 0
    exponential = False
    filled = set()
    for loc, (r, a) in zip(locations, cells):
        ax = axes[r, a]
        filled.add((r, a))
        for i, (tr, law_fit) in enumerate(zip(loc.trials, _law_fits(loc))):
            span = _contact_span(tr)
            ax.plot(tr.depth[span] * 1e3, tr.force[span], color=f"C{i % 10}", linewidth=0.8)
            _fit_lines(ax, tr, law_fit)
        n_trials_max = max(n_trials_max, len(loc.trials))
        exponential = exponential or isinstance(loc, ExponentialLocationFit)
        flag = " *" if loc.flags and set(loc.flags) - {"single_trial"} else ""
        ax.set_title(f"{loc.location}: {_values_text(loc)}{flag}", fontsize=8,
                     color="tab:red" if flag else "black")
    for r in range(len(rows)):
        for a in range(n_angles):
            ax = axes[r, a]
            ax.tick_params(labelsize=7)
            ax.grid(True, linewidth=0.3, alpha=0.5)
            if (r, a) not in filled:
                ax.set_title(f"{rows[r]}{a}", fontsize=8)
                ax.text(0.5, 0.5, "no data", transform=ax.transAxes, ha="center",
                        va="center", fontsize=8, color="0.5")
    for a in range(n_angles):
        axes[-1, a].set_xlabel("depth [mm]", fontsize=8)
    for r in range(len(rows)):
        axes[r, 0].set_ylabel(f"row {rows[r]}\nforce [N]", fontsize=8)
    handles = [Line2D([], [], color=f"C{i % 10}", linewidth=1.2, label=f"trial {i + 1}")
               for i in range(n_trials_max)]
    fit_name = "exponential unloading fit" if exponential else "unloading fit"
    handles.append(Line2D([], [], label=fit_name, **_FIT_STYLE))
    fig.legend(handles=handles, loc="outside lower center", ncols=len(handles), fontsize=8,
               frameon=False)
    what = "curves F = (k0/\u03b2)(exp(\u03b2 (d - d0)) - 1)" if exponential else "lines"
    fig.suptitle(title or "Indenter force vs depth from onset, with the fitted unloading "
                 f"{what} (* flagged, see the flags column)", fontsize=10)
    return fig


def indentation_response(location: LocationFit, *, title: str | None = None,
                         figsize=(5.0, 3.8)) -> Figure:
    """One location's force-depth response: loading, unloading and the fitted lines (Fig. 6a).

    Parameters
    ----------
    location : LocationFit or ExponentialLocationFit
        With ExponentialLocationFit the fitted exponential curves are drawn.
    title : str, optional
    figsize : (float, float)
        [inch]

    Returns
    -------
    matplotlib.figure.Figure
        One axes.
    """
    fig = Figure(figsize=figsize, layout="constrained")
    ax = fig.add_subplot()
    for tr, law_fit in zip(location.trials, _law_fits(location)):
        for s0, s1 in zip(tr.loading.start, tr.loading.stop):
            ax.plot(tr.depth[s0:s1] * 1e3, tr.force[s0:s1], color="C0", linewidth=1.0)
        for s0, s1 in zip(tr.unloading.start, tr.unloading.stop):
            ax.plot(tr.depth[s0:s1] * 1e3, tr.force[s0:s1], color="C1", linewidth=1.0)
        _fit_lines(ax, tr, law_fit)
    handles = [Line2D([], [], color="C0", label="loading"),
               Line2D([], [], color="C1", label="unloading"),
               Line2D([], [], label=f"unloading fit (mean {_values_text(location)})",
                      **_FIT_STYLE)]
    ax.legend(handles=handles, loc="upper left", fontsize=8)
    ax.set_xlabel("depth from onset [mm]")
    ax.set_ylabel("force [N]")
    ax.grid(True, linewidth=0.3, alpha=0.5)
    ax.set_title(title or f"Indentation response at {location.location} "
                 f"({location.n_trials} trials)", fontsize=10)
    return fig


def stiffness_map(locations, *, rows=None, n_angles=None, title: str | None = None,
                  cmap: str = "viridis", figsize=None) -> Figure:
    """Stiffness map, rows x angular locations, values written in the cells (Fig. 6b).

    Parameters
    ----------
    locations : sequence of LocationFit or ExponentialLocationFit
        With ExponentialLocationFit the map shows k0, the slope at contact.
    rows, n_angles : optional
        Grid layout (see :func:`map_grid`).
    title : str, optional
        Default gives the mean +- SD over the locations.
    cmap : str
        Colour map name.
    figsize : (float, float), optional
        [inch]

    Returns
    -------
    matplotlib.figure.Figure
        Two axes: the map and its colour bar (label ``indenter stiffness [N/m]``).
    """
    import matplotlib as mpl
    from matplotlib.colors import Normalize

    rows, n_angles, cells = map_grid(locations, rows, n_angles)
    grid = np.full((len(rows), n_angles), np.nan)
    sd = np.full_like(grid, np.nan)
    flagged = np.zeros(grid.shape, bool)
    for loc, (r, a) in zip(locations, cells):
        grid[r, a] = loc.stiffness
        sd[r, a] = loc.std
        flagged[r, a] = bool(set(loc.flags) - {"single_trial"})
    if figsize is None:
        figsize = (1.0 * n_angles + 2.2, 0.9 * len(rows) + 1.6)
    fig = Figure(figsize=figsize, layout="constrained")
    ax = fig.add_subplot()
    cm = mpl.colormaps[cmap].with_extremes(bad="0.85")
    finite = grid[np.isfinite(grid)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    if hi <= lo:
        lo, hi = lo - 0.5, hi + 0.5
    norm = Normalize(lo, hi)
    im = ax.imshow(np.ma.masked_invalid(grid), cmap=cm, norm=norm, aspect="auto")
    for r in range(len(rows)):
        for a in range(n_angles):
            v = grid[r, a]
            if not np.isfinite(v):
                ax.text(a, r, "-", ha="center", va="center", fontsize=9, color="0.3")
                continue
            rgba = cm(norm(v))
            lum = 0.299 * rgba[0] + 0.587 * rgba[1] + 0.114 * rgba[2]
            color = "black" if lum > 0.5 else "white"
            ax.text(a, r - 0.08, f"{v:.0f}{' *' if flagged[r, a] else ''}", ha="center",
                    va="center", fontsize=9, color=color, fontweight="bold")
            if np.isfinite(sd[r, a]):
                ax.text(a, r + 0.25, f"\u00b1{sd[r, a]:.0f}", ha="center", va="center",
                        fontsize=7, color=color)
    ax.set_xticks(range(n_angles))
    ax.set_yticks(range(len(rows)))
    ax.set_yticklabels(rows)
    ax.set_xlabel("angular location")
    ax.set_ylabel("row")
    cbar = fig.colorbar(im, ax=ax)
    exponential = any(isinstance(loc, ExponentialLocationFit) for loc in locations)
    cbar.set_label("indenter stiffness k0 at contact [N/m]" if exponential
                   else "indenter stiffness [N/m]")
    if title is None:
        mean, s, n = location_statistics(finite)
        title = (f"Tissue stiffness (indenter), {n} locations: {mean:.0f} \u00b1 {s:.1f} N/m"
                 if n > 1 else "Tissue stiffness (indenter)")
        if flagged.any():
            title += "\n(* flagged, see the flags column; small: SD over trials)"
        else:
            title += "\n(small: SD over trials)"
    ax.set_title(title, fontsize=9)
    return fig
