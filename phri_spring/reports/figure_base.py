"""Shared pieces of the report figures: style, arm colours, the reused-figure renderer base.

The font sizes every report figure is drawn with (:func:`figure_style`), the colours and
names of the arm models, the resolution of saved figures, the base class of the
renderers that draw many figures of one layout into one figure built once
(:class:`ReusedFigure`, used by :mod:`phri_spring.reports.compare.heatmap` and
:mod:`phri_spring.reports.compare.figures`) and a fast PNG writer
(:func:`write_png`). Split out of :mod:`phri_spring.reports.compare.figures`,
which re-exports every public name. Only :class:`matplotlib.figure.Figure` is
used, never pyplot.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..plugins import arm_models

__all__ = ["ARM_COLORS", "ARM_NAMES", "DEFAULT_DPI", "fast_png", "write_png", "figure_style"]



class _ArmField(Mapping):
    """A read-only view ``arm name -> one field of its registered record`` (a live view: an
    arm registered later is in it; :func:`phri_spring.plugins.arm_models`)."""

    def __init__(self, attribute: str):
        self._attribute = attribute

    def __getitem__(self, arm):
        return getattr(arm_models()[arm], self._attribute)

    def __iter__(self):
        return iter(arm_models())

    def __len__(self):
        return len(arm_models())


#: the colours the arm models declared (the built-ins: colour-blind-safe Okabe-Ito)
ARM_COLORS = _ArmField("colour")
#: how the arm models are named in figures and tables (their declared labels)
ARM_NAMES = _ArmField("label")
#: resolution of saved figures [dpi]
DEFAULT_DPI = 170

_FONT = {"font.size": 9, "axes.titlesize": 10, "axes.labelsize": 9, "xtick.labelsize": 8.5,
         "ytick.labelsize": 8.5, "legend.fontsize": 8.5}


def figure_style():
    """The project's figure fonts, as a context manager."""
    import matplotlib

    return matplotlib.rc_context(_FONT)


class ReusedFigure:
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
        self._sizes = {}         # (text, font properties, dpi) -> its width and height [px]
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
            ext = [self._text_size(t, prop, dpi) for t in labels]
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

    def _text_size(self, text: str, prop, dpi: int) -> tuple:
        """Width and height [px] of a tick label, measured once per string, font and dpi."""
        from .agg_text import remember

        key = (text, prop, dpi)
        size = self._sizes.get(key)
        if size is None:
            size = remember(self._sizes, key, self._measure.get_text_width_height_descent(
                text, prop, ismath=False)[:2], limit=10_000)
        return size

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
        if fast_png(path):
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
            from .agg_text import CachedTextCanvas

            self._canvas = CachedTextCanvas(fig)
        with figure_style():
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


def fast_png(path) -> bool:
    """True when ``path`` is a PNG that ``savefig`` would write as the canvas draws it.

    The fast PNG paths (drawing once on the canvas and :func:`write_png`) are
    taken only then, with the default ``savefig.*`` rcParams; a user's
    ``matplotlibrc`` asking for a tight bounding box, a transparent or another
    background goes through ``Figure.savefig``, as do PDF and SVG.
    """
    import matplotlib

    rc = matplotlib.rcParams
    return (Path(path).suffix.lower() == ".png"
            and rc["savefig.bbox"] in (None, "standard") and not rc["savefig.transparent"]
            and rc["savefig.facecolor"] == "auto" and rc["savefig.edgecolor"] == "auto")


def write_png(path, rgba, dpi: float) -> Path:
    """Write pixels (h, w, 4) uint8 as a PNG, RGB when every pixel is opaque.

    The same pixels as matplotlib's PNG writer (lossless), several times as
    fast: rows are stored unfiltered and deflated once at level 1 (Pillow tries
    a filter per row, which costs more than it saves on figures' flat colours;
    level 1 takes half the time of level 6 for files a fifth larger). Carries the
    resolution (pHYs) and the writing software, as matplotlib's does.
    """
    import struct
    import zlib

    import matplotlib

    rgba = np.ascontiguousarray(rgba, dtype=np.uint8)
    h, w = rgba.shape[:2]
    # every alpha byte 255: one pass over the pixels as 32-bit words (native byte order)
    alpha = np.frombuffer(np.uint8([0, 0, 0, 255]).tobytes(), dtype=np.uint32)[0]
    opaque = bool(np.all(rgba.view(np.uint32) & alpha == alpha))
    px = rgba[..., :3] if opaque else rgba
    depth = px.shape[2]
    raw = np.empty((h, 1 + w * depth), dtype=np.uint8)
    raw[:, 0] = 0                                          # filter byte of each row: none
    np.copyto(raw[:, 1:].reshape(h, w, depth), px)        # one copy, into the rows

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
        chunk(b"IDAT", zlib.compress(raw, 1)),
        chunk(b"IEND", b""),
    ])
    path = Path(path)
    path.write_bytes(data)
    return path
