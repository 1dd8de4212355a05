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
           "condition_label", "save_figure", "DEFAULT_DPI", "HeatmapRenderer", "render_job",
           "render_figures", "available_cores", "WrenchRenderer", "write_png"]

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

    See Also
    --------
    HeatmapRenderer : draws many heat maps of one layout into one reused figure.
    """
    renderer = HeatmapRenderer(1 + len(simulated), row_labels=row_labels, n_angles=n_angles,
                               cmap=cmap, value_format=value_format)
    return renderer.fill(measured, simulated, title=title, rmse=rmse)


class _ReusedFigure:
    """A figure built once and drawn many times with other values (base of the renderers).

    Subclasses build ``self.fig`` (with a constrained layout) and
    ``self.suptitle``, list the axes whose tick labels' width moves the layout
    (:meth:`_label_axes`), then call :meth:`_ready`. :meth:`save` computes the
    constrained layout once per *layout signature* (the line counts of the
    titles and the width of the widest tick label of those axes, the only
    sizes that move the panels) and draws the figure once, without a layout
    engine, at those positions.
    """

    fig: Figure

    def _ready(self) -> None:
        self._layouts = {}       # signature -> [(positions of every axes and the suptitle,
        #                            the signature at those positions), ...]
        self._measure = None     # a renderer that measures texts
        self._canvas = None      # the Agg canvas PNGs are drawn on
        self._initial = self._positions()   # the state a new figure's layout starts from

    def _label_axes(self):
        return []

    def _short_axes(self):
        # axes shorter than their neighbours: labels reaching past their ends stay within the
        # figure's other parts and do not move the layout
        return []

    def _positions(self):
        return ([(a.get_position(original=True).frozen(), a.get_position(original=False).frozen())
                 for a in self.fig.axes], self.suptitle.get_position())

    def _set_positions(self, layout) -> None:
        for a, (orig, active) in zip(self.fig.axes, layout[0]):
            a._set_position(orig, which="original")
            a._set_position(active, which="active")
        self.suptitle.set_position(layout[1])

    def _signature(self, dpi: int) -> tuple:
        from matplotlib.backends.backend_agg import RendererAgg

        if self._measure is None or self._measure.dpi != dpi:
            self._measure = RendererAgg(1, 1, dpi)
        sizes = []
        for axis in self._label_axes():
            ends = axis not in self._short_axes()
            axis.axes._unstale_viewLim()
            locs = axis.get_majorticklocs()
            lo, hi = sorted(axis.get_view_interval())
            eps = 1e-9 * abs(hi - lo)
            locs = [x for x in locs if lo - eps <= x <= hi + eps]
            labels = axis.get_major_formatter().format_ticks(locs)
            ticks = axis.get_majorticklabels()
            prop = ticks[0].get_fontproperties() if ticks else self.suptitle.get_fontproperties()
            ext = [self._measure.get_text_width_height_descent(t, prop, ismath=False)[:2]
                   for t in labels]
            across, along = (0, 1) if axis.axis_name == "y" else (1, 0)
            width = max((e[across] for e in ext), default=0.0)
            # how far the end labels reach past the ends of the axis (they move the layout
            # too); zero in most figures, whatever the ticks
            box = axis.axes.bbox
            length = box.height if axis.axis_name == "y" else box.width
            over = [0.0, 0.0]
            if ends and locs and hi > lo:
                over[0] = max(0.0, ext[0][along] / 2 - (locs[0] - lo) / (hi - lo) * length)
                over[1] = max(0.0, ext[-1][along] / 2 - (hi - locs[-1]) / (hi - lo) * length)
            sizes.append((round(float(width), 3), round(over[0], 2), round(over[1], 2)))
        titles = tuple(a.get_title().count("\n") for a in self.fig.axes)
        return (titles, self.suptitle.get_visible(), self.suptitle.get_text().count("\n"),
                tuple(sizes))

    def _layout(self, dpi: int):
        """Set the constrained layout of the current values; return its key.

        The layout is computed (as a new figure's, from the same starting
        positions) the first time a signature is met, and reused after that
        when the labels at the reused positions have the same signature as
        those of the figure it was computed for; so every image depends only
        on its own values, not on what was drawn before.
        """
        fig = self.fig
        self._set_positions(self._initial)
        start = self._signature(dpi)
        entry = None
        for cand in self._layouts.get(start, ()):
            self._set_positions(cand[0])
            if self._signature(dpi) == cand[1]:
                entry = cand
                break
        if entry is None:
            self._set_positions(self._initial)
            fig.set_layout_engine("constrained")
            # the layout alone, as savefig computes it before drawing (not a whole draw)
            fig.get_layout_engine().execute(fig)
            entry = (self._positions(), self._signature(dpi))
            self._layouts.setdefault(start, []).append(entry)
        return tuple(np.round([v for o, a in entry[0][0] for v in (*o.bounds, *a.bounds)], 9))

    def _write(self, path: Path, dpi: int, key) -> None:
        if path.suffix.lower() == ".png":
            self._canvas.draw()
            write_png(path, np.asarray(self._canvas.buffer_rgba()), dpi)
        else:
            self.fig.savefig(path, dpi=dpi)

    def save(self, path, dpi: int = DEFAULT_DPI) -> Path:
        """Save the current figure (PNG, PDF or SVG by the extension), reusing layouts."""
        path = Path(path)
        fig = self.fig
        dpi = int(dpi)
        if self._canvas is None:
            from matplotlib.backends.backend_agg import FigureCanvasAgg

            self._canvas = FigureCanvasAgg(fig)
        with _style():
            fig.dpi = dpi
            key = (self._layout(dpi), dpi)
            # no layout engine at all: the figure is then drawn once (with one, even a
            # placeholder, savefig draws twice: once for the layout, once for the pixels)
            engine, fig._layout_engine = fig._layout_engine, None
            try:
                self._write(path, dpi, key)
            finally:
                fig._layout_engine = engine
        return path


class HeatmapRenderer(_ReusedFigure):
    """Many heat maps (Fig. 8b) of one layout, drawn into one figure built once.

    Building a figure (axes, ticks, the colour bar, one text per cell) costs
    more than drawing it, and the constrained layout is recomputed on every
    save although it depends only on a few text sizes. A renderer builds the
    figure once; :meth:`fill` then only changes the values, colours, texts and
    titles; :meth:`save` reuses the layout computed for the same *layout
    signature* (the line counts of the titles and the colour bar's tick
    labels, the only texts whose size moves the panels) and computes it once
    for each new signature. The images are those :func:`heatmap_figure` draws
    (a test compares them with a reference rendering).

    Parameters
    ----------
    n_panels : int
        Panels: the measured loads, then one per arm model.
    row_labels : sequence of str
        Row labels, top to bottom.
    n_angles : int
        Angular locations per row.
    cmap, value_format
        See :func:`heatmap_figure`.
    """

    def __init__(self, n_panels: int, *, row_labels: Sequence[str], n_angles: int,
                 cmap: str = "RdBu_r", value_format: str = "{:.1f}"):
        self.n_panels = int(n_panels)
        self.row_labels = tuple(row_labels)
        self.n_angles = int(n_angles)
        self.value_format = value_format
        self._static = {}        # layout key -> the pixels of the parts that never change
        n_rows = len(self.row_labels)
        with _style():
            cell = 0.42
            fig = Figure(figsize=(max(self.n_panels * (n_angles * cell + 0.55) + 1.1, 5.5),
                                  n_rows * cell + 1.75), layout="constrained")
            axes = fig.subplots(1, self.n_panels, squeeze=False)[0]
            self.images, self.texts = [], []
            zeros = np.zeros((n_rows, n_angles))
            for j, ax in enumerate(axes):
                im = ax.imshow(zeros, cmap=cmap, vmin=-1.0, vmax=1.0, aspect="equal")
                ax.set_title(" ")
                ax.set_xticks(np.arange(n_angles), [str(i) for i in range(n_angles)])
                ax.set_yticks(np.arange(n_rows), list(self.row_labels))
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
                self.images.append(im)
                self.texts.append([[ax.text(c, r, "", ha="center", va="center", fontsize=7)
                                    for c in range(n_angles)] for r in range(n_rows)])
            self.cbar = fig.colorbar(self.images[-1], ax=list(axes), shrink=0.8, pad=0.02,
                                     aspect=15)
            self.cbar.set_label("zeroed load [N]")
            self.suptitle = fig.suptitle(" ", fontsize=9.5)
            self.suptitle.set_visible(False)
        self.axes = list(axes)
        self.fig = fig
        self._ready()

    def fill(self, measured, simulated: dict, *, title: str = "",
             rmse: Optional[dict] = None) -> Figure:
        """Put one heat map's values into the figure (see :func:`heatmap_figure`); returns it."""
        n_rows, n_angles = len(self.row_labels), self.n_angles
        panels = [("Measured (sensors)", np.asarray(measured, dtype=float))]
        for arm, values in simulated.items():
            name = ARM_NAMES.get(arm, arm)
            if rmse is not None and arm in rmse and np.isfinite(rmse[arm]):
                name = f"{name}\nRMSE {rmse[arm]:.2f} N"
            panels.append((name, np.asarray(values, dtype=float)))
        if len(panels) != self.n_panels:
            raise ValueError(f"heatmap: expected {self.n_panels} panels, got {len(panels)}")
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
            for ax, im, texts, (name, _), grid in zip(self.axes, self.images, self.texts,
                                                      panels, grids):
                im.set_data(grid)
                im.set_clim(-vmax, vmax)
                ax.set_title(name)
                for r in range(n_rows):
                    for c in range(n_angles):
                        val = grid[r, c]
                        t = texts[r][c]
                        if not np.isfinite(val):
                            t.set_visible(False)
                            continue
                        txt = self.value_format.format(val)
                        if txt.startswith("-") and not txt.strip("-0.").strip():
                            txt = txt[1:]                      # no "-0.0"
                        t.set_text(txt)
                        t.set_color("white" if abs(val) > 0.55 * vmax else "0.1")
                        t.set_visible(True)
            self.suptitle.set_text(title or " ")
            self.suptitle.set_visible(bool(title))
            self.suptitle.set_in_layout(bool(title))
        return self.fig

    def _label_axes(self):
        # the colour bar's labels are left-aligned beside it: only the widest one counts
        return [self.cbar.ax.yaxis if self.cbar.orientation == "vertical" else
                self.cbar.ax.xaxis]

    def _short_axes(self):
        return self._label_axes()           # the bar is 80 % of the panels' height

    def _save_png(self, path: Path, dpi: int, key) -> None:
        """Draw the changing parts, lay the unchanging ones over them, write the PNG.

        The panels' axes (tick labels, axis labels, the white cell borders) are
        the same in every heat map of a layout: they are drawn once, on a
        transparent layer, and laid over the rest (they overlap only the images,
        which they cover, as when drawn in one pass).
        """
        fig = self.fig
        fixed = [a for ax in self.axes for a in (ax.xaxis, ax.yaxis)]   # drawn once per layout
        layer = self._static.get(key)
        if layer is None:
            hide = [fig.patch, *(ax.patch for ax in self.axes), *self.images, self.suptitle,
                    self.cbar.ax, *(ax.title for ax in self.axes),
                    *(t for rows in self.texts for row in rows for t in row)]
            shown = [a.get_visible() for a in hide]
            for a in hide:
                a.set_visible(False)
            try:
                self._canvas.draw()
            finally:
                for a, v in zip(hide, shown):
                    a.set_visible(v)
            rgba = np.asarray(self._canvas.buffer_rgba()).reshape(-1, 4)
            where = np.flatnonzero(rgba[:, 3])          # the few pixels the layer covers
            alpha = rgba[where, 3:4].astype(np.float32) / 255.0
            layer = self._static[key] = (where, rgba[where, :3].astype(np.float32) * alpha,
                                         1.0 - alpha)
        for a in fixed:
            a.set_visible(False)
        try:
            self._canvas.draw()
        finally:
            for a in fixed:
                a.set_visible(True)
        out = np.array(self._canvas.buffer_rgba())
        flat = out.reshape(-1, 4)
        where, premult, keep = layer
        rgb = flat[where, :3].astype(np.float32)
        rgb *= keep
        rgb += premult
        flat[where, :3] = np.clip(np.rint(rgb), 0, 255).astype(np.uint8)
        write_png(path, out, dpi)

    def _write(self, path: Path, dpi: int, key) -> None:
        if path.suffix.lower() == ".png":
            self._save_png(path, dpi, key)
        else:
            self.fig.savefig(path, dpi=dpi)


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

    See Also
    --------
    WrenchRenderer : draws many of these into one reused figure.
    """
    return WrenchRenderer(force_unit, moment_unit).fill(time, wrench, conditions, title=title)


class WrenchRenderer(_ReusedFigure):
    """Many wrench traces (Fig. 8a) drawn into one figure built once.

    :meth:`fill` changes the lines' data, the shaded windows and their names
    and the title; :meth:`save` reuses the constrained layout of the same
    signature (the widest tick label of each axis). The images are those of
    :func:`wrench_figure` (a test compares them with a reference rendering).
    """

    _COLORS = ("#d62728", "#2ca02c", "#1f77b4")

    def __init__(self, force_unit: str = "N", moment_unit: str = "N*m"):
        with _style():
            fig = Figure(figsize=(7.0, 3.9), layout="constrained")
            ax_f, ax_m = fig.subplots(2, 1, sharex=True)
            self.lines = []
            for j, axis in enumerate("xyz"):
                self.lines.append(ax_f.plot([], [], color=self._COLORS[j], lw=0.9,
                                            label=f"F{axis}")[0])
            for j, axis in enumerate("xyz"):
                self.lines.append(ax_m.plot([], [], color=self._COLORS[j], lw=0.9,
                                            label=f"M{axis}")[0])
            ax_f.set_ylabel(f"force [{force_unit}]")
            ax_m.set_ylabel(f"moment [{moment_unit.replace('*', '·')}]")
            ax_m.set_xlabel("time [s]")
            for ax in (ax_f, ax_m):
                ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), frameon=False)
                ax.grid(color="0.9", lw=0.6)
                for side in ("top", "right"):
                    ax.spines[side].set_visible(False)
            self.suptitle = fig.suptitle(" ", fontsize=9.5)
            self.suptitle.set_visible(False)
            self.suptitle.set_in_layout(False)
        self.ax_f, self.ax_m = ax_f, ax_m
        self.fig = fig
        self._marks = []          # the shaded windows and their names of the current trace
        self._ready()

    def _label_axes(self):
        return [self.ax_f.yaxis, self.ax_m.yaxis, self.ax_m.xaxis]

    def fill(self, time, wrench, conditions, *, title: str = "") -> Figure:
        """Put one trial's wrench into the figure (see :func:`wrench_figure`); returns it."""
        t = np.asarray(time, dtype=float)
        w = np.asarray(wrench, dtype=float)
        cond = np.asarray(conditions, dtype=object)
        ax_f, ax_m = self.ax_f, self.ax_m
        for mark in self._marks:
            mark.remove()
        self._marks = []
        with _style():
            for j, line in enumerate(self.lines):
                line.set_data(t, w[:, j])
            # shade each steady window and name it
            edges = np.flatnonzero(np.r_[True, cond[1:] != cond[:-1]])
            ends = np.r_[edges[1:], len(cond)]
            for k, (s, e) in enumerate(zip(edges, ends)):
                if not cond[s]:
                    continue
                for ax in (ax_f, ax_m):
                    self._marks.append(ax.axvspan(t[s], t[e - 1], color="0.5" if k % 2 else "0.7",
                                                  alpha=0.15, lw=0))
                self._marks.append(ax_f.text(0.5 * (t[s] + t[e - 1]), 1.0, str(cond[s]),
                                             ha="center", va="bottom", fontsize=8,
                                             transform=ax_f.get_xaxis_transform()))
            for ax in (ax_f, ax_m):
                ax.relim()
                ax.autoscale_view()
            self.suptitle.set_text(title or " ")
            self.suptitle.set_visible(bool(title))
            self.suptitle.set_in_layout(bool(title))
        return self.fig


def write_png(path, rgba, dpi: float) -> Path:
    """Write pixels (h, w, 4) uint8 as a PNG, RGB when every pixel is opaque.

    The same pixels as matplotlib's PNG writer (lossless), about twice as fast:
    rows are stored unfiltered and deflated once (Pillow tries a filter per row,
    which costs more than it saves on figures' flat colours). Carries the
    resolution (pHYs) and the writing software, as matplotlib's does.
    """
    import struct
    import zlib

    import matplotlib

    rgba = np.asarray(rgba, dtype=np.uint8)
    h, w = rgba.shape[:2]
    opaque = bool(np.all(rgba[..., 3] == 255))
    px = rgba[..., :3] if opaque else rgba
    raw = np.zeros((h, 1 + w * px.shape[2]), dtype=np.uint8)   # filter byte 0: none
    raw[:, 1:] = px.reshape(h, -1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data +
                struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    ppm = int(round(float(dpi) / 0.0254))
    data = b"".join([
        b"\x89PNG\r\n\x1a\n",
        chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2 if opaque else 6, 0, 0, 0)),
        chunk(b"pHYs", struct.pack(">IIB", ppm, ppm, 1)),
        chunk(b"tEXt", b"Software\0" + f"Matplotlib version{matplotlib.__version__}, "
              "https://matplotlib.org/".encode("latin-1")),
        chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)),
        chunk(b"IEND", b""),
    ])
    path = Path(path)
    path.write_bytes(data)
    return path


def save_figure(fig: Figure, path, dpi: int = DEFAULT_DPI) -> Path:
    """Write a figure (PNG, PDF or SVG by the extension) without pyplot."""
    path = Path(path)
    with _style():
        fig.savefig(path, dpi=dpi)
    return path


# --------------------------------------------------------------------------- many figures
#: heat-map renderers of this process, by layout (kept between figures and between tasks)
_RENDERERS: dict = {}


def _heatmap_renderer(n_panels: int, row_labels, n_angles: int) -> "HeatmapRenderer":
    key = (int(n_panels), tuple(row_labels), int(n_angles))
    r = _RENDERERS.get(key)
    if r is None:
        r = _RENDERERS[key] = HeatmapRenderer(n_panels, row_labels=row_labels,
                                              n_angles=n_angles)
    return r


def _renderer_for(job) -> "_ReusedFigure":
    """This process's renderer for a heat-map or wrench job (built on first use)."""
    kind, _, kw = job
    if kind == "heatmap":
        return _heatmap_renderer(1 + len(kw["simulated"]), kw["row_labels"], kw["n_angles"])
    key = ("wrench", kw.get("force_unit", "N"), kw.get("moment_unit", "N*m"))
    r = _RENDERERS.get(key)
    if r is None:
        r = _RENDERERS[key] = WrenchRenderer(key[1], key[2])
    return r


def render_job(job, dpi: int = DEFAULT_DPI) -> str:
    """Draw and save one figure described by ``job = (kind, path, arguments)``.

    ``kind`` is ``"heatmap"`` (arguments of :func:`heatmap_figure`, drawn by a
    reused :class:`HeatmapRenderer`), ``"wrench"`` (of :func:`wrench_figure`)
    or ``"bars"`` (of :func:`rmse_bars_figure`). Returns the path written.
    """
    kind, path, kw = job
    kw = dict(kw)
    if kind in ("heatmap", "wrench"):
        r = _renderer_for(job)
        for name in ("row_labels", "n_angles", "force_unit", "moment_unit"):
            kw.pop(name, None)
        if kind == "heatmap":
            r.fill(kw.pop("measured"), kw.pop("simulated"), **kw)
        else:
            r.fill(kw.pop("time"), kw.pop("wrench"), kw.pop("conditions"), **kw)
        r.save(path, dpi)
    elif kind == "bars":
        save_figure(rmse_bars_figure(kw.pop("summary"), kw.pop("rmse", None), **kw), path, dpi)
    else:
        raise ValueError(f"render_job: unknown figure kind {kind!r}")
    return str(path)


def _worker_init() -> None:
    import signal

    # an interrupt is the parent's to handle: it stops the pool and cleans up
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def available_cores() -> int:
    """Processors this process may run on."""
    import os

    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def _pool(workers: int):
    """A process pool whose workers are forked from this process (None where fork is missing).

    Forked workers start at once, with matplotlib already imported, and never
    re-import the caller's main script (as spawned ones do, which breaks a
    script without an ``if __name__ == "__main__"`` guard). Where fork is not
    available the figures are drawn in this process.
    """
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    if "fork" not in mp.get_all_start_methods():
        return None
    return ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("fork"),
                               initializer=_worker_init)


def _submit(pool, *args):
    import warnings

    with warnings.catch_warnings():
        # Python >= 3.12 warns about fork in a process with threads (pyarrow's, the
        # writer's); the workers only draw with matplotlib, which those threads never touch
        warnings.simplefilter("ignore", DeprecationWarning)
        return pool.submit(*args)


def render_figures(jobs, dpi: int = DEFAULT_DPI, *, workers: Optional[int] = None,
                   local=()) -> list:
    """Draw and save many independent figures on the available cores.

    This process draws too (``local`` jobs, which need not be picklable, then
    jobs from the front of the list) while ``workers - 1`` worker processes
    take jobs from the back, a few at a time, so that the work is shared
    whatever each figure costs. Every image depends only on its own job (the
    same pixels whichever process draws it), so the output is deterministic.
    The caller writes into a temporary folder (the figures of a failed run
    never land); on an error or an interrupt the pending jobs are cancelled
    and the running ones finished before the error is raised.

    Parameters
    ----------
    jobs : sequence of (kind, path, arguments)
        See :func:`render_job`; the arguments are pickled to the workers.
    dpi : int
        Resolution [dots per inch].
    workers : int, optional
        Processes drawing, this one included (default: the available cores;
        1 draws everything here).
    local : sequence of (kind, path, arguments)
        Jobs drawn in this process only.

    Returns
    -------
    list of str
        The paths written, in the order of ``local`` then ``jobs``.
    """
    import collections
    from concurrent.futures import FIRST_COMPLETED, wait

    jobs, local = list(jobs), list(local)
    workers = available_cores() if workers is None else max(1, int(workers))
    workers = min(workers, 1 + len(jobs) // 4)       # a process per few figures at most
    if workers <= 1:
        for job in (*local, *jobs):
            render_job(job, dpi)
        return [str(j[1]) for j in (*local, *jobs)]
    # build the renderers before the workers are forked: they inherit them, built once
    for job in jobs:
        if job[0] in ("heatmap", "wrench"):
            _renderer_for(job)
    try:
        pool = _pool(workers - 1)
    except (OSError, ImportError, ValueError):   # no process support here: draw serially
        pool = None
    if pool is None:
        for job in (*local, *jobs):
            render_job(job, dpi)
        return [str(j[1]) for j in (*local, *jobs)]
    pending = collections.deque(jobs)
    inflight = set()
    mine = collections.deque(local)
    try:
        while pending or inflight or mine:
            while pending and len(inflight) < 2 * (workers - 1):
                inflight.add(_submit(pool, render_job, pending.pop(), dpi))
            if mine:                                  # while the workers start drawing
                render_job(mine.popleft(), dpi)
                done = {f for f in inflight if f.done()}
            elif pending:
                render_job(pending.popleft(), dpi)
                done = {f for f in inflight if f.done()}
            else:
                done, _ = wait(inflight, return_when=FIRST_COMPLETED)
            for fut in done:
                inflight.discard(fut)
                fut.result()                          # raises a worker's error here
    finally:
        for fut in inflight:
            fut.cancel()
        pool.shutdown(wait=True, cancel_futures=True)
    return [str(j[1]) for j in (*local, *jobs)]
