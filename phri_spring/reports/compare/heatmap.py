"""Heat maps of ``phri compare`` (the paper's Fig. 8b), as matplotlib ``Figure`` objects.

:func:`heatmap_figure` draws measured | rigid | compliant zeroed loads on the
rows x locations grid with one diverging colour scale centred on zero;
:class:`HeatmapRenderer` draws many such heat maps of one layout into one figure
built once. Split out of :mod:`phri_spring.reports.compare.figures`, which
re-exports both. Only :class:`matplotlib.figure.Figure` is used, never pyplot.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional, Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.text import Text

from ..agg_text import remember
from ..figure_base import ARM_NAMES, ReusedFigure, figure_style, fast_png, write_png

__all__ = ["heatmap_figure", "HeatmapRenderer"]


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


class _CellText(Text):
    """The value in a heat-map cell: a :class:`~matplotlib.text.Text` laying out a string once.

    A text's layout (its lines' sizes and offsets from the anchor) depends on
    the string, the font, the alignment and the resolution, not on where it
    is drawn; the 63 cells of a heat map repeat a few hundred strings over
    many figures, so the layouts are kept (by string and resolution, for
    these cells' unchanging font and alignment) instead of measured on every
    draw. Everything else is drawn as by ``Text``.
    """

    _layouts: dict = {}      # (string, dpi, font, alignment) -> Text._get_layout's result

    def _get_layout(self, renderer):
        key = (self.get_text(), self.figure.dpi, self._fontproperties,
               self._horizontalalignment, self._verticalalignment, self.get_rotation(),
               self._linespacing, type(renderer))
        try:
            return self._layouts[key]
        except (KeyError, TypeError):
            pass
        return remember(self._layouts, key, super()._get_layout(renderer), limit=20_000)


class HeatmapRenderer(ReusedFigure):
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
        with figure_style():
            cell = 0.42
            fig = Figure(figsize=(max(self.n_panels * (n_angles * cell + 0.55) + 1.1, 5.5),
                                  n_rows * cell + 1.75), layout="constrained")
            axes = fig.subplots(1, self.n_panels, squeeze=False)[0]
            self.meshes, self.texts = [], []
            zeros = np.zeros((n_rows, n_angles))
            for j, ax in enumerate(axes):
                # one quadrilateral per cell (drawn as 21 polygons, not resampled as an image)
                im = ax.pcolormesh(np.arange(-0.5, n_angles), np.arange(-0.5, n_rows), zeros,
                                   cmap=cmap, vmin=-1.0, vmax=1.0, shading="flat")
                ax.set_aspect("equal")
                ax.set_xlim(-0.5, n_angles - 0.5)
                ax.set_ylim(n_rows - 0.5, -0.5)          # row A on top
                ax.set_title(" ")
                ax.set_xticks(np.arange(n_angles), [str(i) for i in range(n_angles)])
                ax.set_yticks(np.arange(n_rows), list(self.row_labels))
                ax.set_xlabel("angular location")
                if j == 0:
                    ax.set_ylabel("row")
                ax.tick_params(length=0)
                # the white cell borders: lines like grid lines, kept out of the layout
                # (as minor-tick grid lines they made every layout measure 24 empty ticks)
                for x in np.arange(-0.5, n_angles, 1):
                    ax.axvline(x, color="white", lw=1.2, in_layout=False, zorder=2.5)
                for y in np.arange(-0.5, n_rows, 1):
                    ax.axhline(y, color="white", lw=1.2, in_layout=False, zorder=2.5)
                for side in ax.spines.values():
                    side.set_visible(False)
                self.meshes.append(im)
                # the values sit inside their cells: they never move the layout
                self.texts.append([[ax.add_artist(_CellText(c, r, "", ha="center", va="center",
                                                            fontsize=7, in_layout=False))
                                    for c in range(n_angles)] for r in range(n_rows)])
            self.cbar = fig.colorbar(self.meshes[-1], ax=list(axes), shrink=0.8, pad=0.02,
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
        with figure_style():
            for ax, im, texts, (name, _), grid in zip(self.axes, self.meshes, self.texts,
                                                      panels, grids):
                im.set_array(grid)
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
        transparent layer, and laid over the rest (they overlap only the cells,
        which they cover, as when drawn in one pass).
        """
        fig = self.fig
        fixed = [a for ax in self.axes for a in (ax.xaxis, ax.yaxis, *ax.lines)]  # once per layout
        layer = self._static.get(key)
        if layer is None:
            hide = [fig.patch, *(ax.patch for ax in self.axes), *self.meshes, self.suptitle,
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
        out = np.asarray(self._canvas.buffer_rgba())     # laid over in place (redrawn anyway)
        flat = out.reshape(-1, 4)
        where, premult, keep = layer
        rgb = flat[where, :3].astype(np.float32)
        rgb *= keep
        rgb += premult
        flat[where, :3] = np.clip(np.rint(rgb), 0, 255).astype(np.uint8)
        write_png(path, out, dpi)

    def _write(self, path: Path, dpi: int, key) -> None:
        if fast_png(path):
            self._save_png(path, dpi, key)
        else:
            self.fig.savefig(path, dpi=dpi)
