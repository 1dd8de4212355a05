"""An Agg canvas that draws text faster, with the same pixels: laid-out strings and glyphs cached.

Drawing the compare figures is mostly drawing text: every heat map carries 63
cell values, titles and tick labels, and matplotlib's Agg renderer lays out
each string (HarfBuzz shaping) and renders each of its glyphs (FreeType) anew
on every draw. :class:`CachedTextCanvas` is a :class:`FigureCanvasAgg` whose
renderer keeps

- the layout of each string (glyphs and their offsets), by font, size,
  resolution and hinting; and
- the bitmap of each glyph, by font, size, resolution, hinting, rotation and
  the sub-pixel part (1/64 px) of its position. FreeType positions a glyph in
  26.6 fixed point, so a glyph moved by whole pixels has the very same
  bitmap, moved by the same pixels.

It then blends the glyphs into the image exactly as matplotlib does (same
calls, same order), so the images are identical to the byte
(``tests/reports/test_figures_reference.py`` checks it on many strings, sizes, angles
and positions). Math text and text with font features or a language set go
the ordinary way.

The fast path uses matplotlib's private text drawing steps (present since
matplotlib 3.11); with another matplotlib that lacks them, the canvas is an
ordinary :class:`FigureCanvasAgg` (:data:`AVAILABLE` says which).
"""

from __future__ import annotations

import math
import os
import threading
from typing import Optional

import numpy as np
from matplotlib import rcParams
from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg
from matplotlib.font_manager import FontProperties

__all__ = ["AVAILABLE", "CachedTextCanvas", "remember"]

try:                                             # the steps RendererAgg.draw_text takes
    from matplotlib.backends.backend_agg import get_hinting_flag
    from matplotlib.ft2font import FT2Font, RenderMode

    AVAILABLE = all(hasattr(FT2Font, name) for name in ("_layout", "_render_glyph",
                                                        "_set_transform"))
    AVAILABLE = AVAILABLE and hasattr(RendererAgg, "_prepare_font")
except ImportError:                              # pragma: no cover - older matplotlib
    AVAILABLE = False

#: the rcParams that decide which font files a FontProperties resolves to
_FONT_RC = ("font.family", "font.style", "font.variant", "font.weight", "font.stretch",
            "font.size", "font.serif", "font.sans-serif", "font.cursive", "font.fantasy",
            "font.monospace", "text.hinting_factor", "text.hinting")

#: most strings and glyphs kept (a cache that reaches this is emptied, not grown)
_MAX_ENTRIES = 50_000
_LAYOUTS: dict = {}     # (font properties, font rcParams, dpi, hinting, text, thread)
#                           -> ((font, glyph, dx, dy), ...)
_GLYPHS: dict = {}      # (font, size, dpi, hinting, mode, matrix, glyph, phase) -> bitmap


# a forked child must not use its parent's font objects: they read their font files through
# file descriptions the two processes share, and reading glyphs in both at once breaks them
# (matplotlib clears its own font cache in a forked child for the same reason)
if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_LAYOUTS.clear)


def remember(cache: dict, key: tuple, value, limit: Optional[int] = None):
    """Keep ``value`` under ``key`` in a cache emptied (not grown) when it holds ``limit``.

    A :class:`~matplotlib.font_manager.FontProperties` in the key is stored as
    a copy (it hashes by value, and the caller's may change later). ``limit``
    defaults to ``_MAX_ENTRIES`` (read at each call). Returns ``value``.
    """
    if len(cache) >= (_MAX_ENTRIES if limit is None else limit):
        cache.clear()
    cache[tuple(k.copy() if isinstance(k, FontProperties) else k for k in key)] = value
    return value


class _CachedTextRenderer(RendererAgg):
    """:class:`RendererAgg` whose plain-text drawing reuses layouts and glyph bitmaps."""

    def draw_text(self, gc, x, y, s, prop, angle, ismath=False, mtext=None):
        if ismath or (mtext is not None and (mtext.get_fontfeatures() is not None
                                             or mtext.get_language() is not None)):
            return super().draw_text(gc, x, y, s, prop, angle, ismath=ismath, mtext=mtext)
        size = prop.get_size_in_points()
        flags = get_hinting_flag()
        # the fonts a FontProperties resolves to depend on it and on the font rcParams; each
        # thread has its own font objects (matplotlib's rule: they are not thread-safe)
        key = (prop, tuple(str(rcParams[k]) for k in _FONT_RC), self.dpi, flags, s,
               threading.get_ident())
        items = _LAYOUTS.get(key)
        if items is None:
            font = self._prepare_font(prop)
            items = tuple((it.ft_object, it.glyph_index, it.x, it.y)
                          for it in font._layout(s, flags=flags, features=None, language=None))
            remember(_LAYOUTS, key, items)
        cos = math.cos(math.radians(angle))
        sin = math.sin(math.radians(angle))
        matrix = (0x10000 * np.array([[cos, -sin], [sin, cos]])).round().astype(int)
        mkey = tuple(matrix.ravel().tolist())
        aa = bool(gc.get_antialiased())
        mode = RenderMode.NORMAL if aa else RenderMode.MONO
        height = self.height
        draw = self._renderer.draw_text_image
        for ft, glyph, dx, dy in items:                # dy is upwards, as in matplotlib
            tx = round(0x40 * (x + dx * cos - dy * sin))
            ty = round(0x40 * (height - y + dx * sin + dy * cos))   # FreeType's y is upwards
            gkey = (ft.fname, ft.face_index, size, self.dpi, flags, aa, mkey, glyph,
                    tx & 63, ty & 63)
            cached = _GLYPHS.get(gkey)
            if cached is None:
                ft.set_size(size, self.dpi)
                ft._set_transform(matrix, [tx & 63, ty & 63])
                bitmap = ft._render_glyph(glyph, flags, mode)
                buffer = np.array(bitmap.buffer, copy=True)
                if not aa:
                    buffer *= 0xff
                cached = remember(_GLYPHS, gkey, (buffer, bitmap.left, bitmap.top))
            buffer, left, top = cached
            # draw_text_image's y is downwards and the bitmap's bottom side
            draw(buffer, left + (tx >> 6), int(height) - (top + (ty >> 6)) + buffer.shape[0],
                 0, gc)


class CachedTextCanvas(FigureCanvasAgg):
    """A :class:`FigureCanvasAgg` drawing text through the layout and glyph caches.

    Use it like the Agg canvas (``CachedTextCanvas(fig).draw()``, then
    ``buffer_rgba()``); the pixels are those of :class:`FigureCanvasAgg`.
    """

    def get_renderer(self):
        if not AVAILABLE:
            return super().get_renderer()
        w, h = self.get_width_height(physical=True)
        key = w, h, self.figure.dpi
        if self._lastKey != key:
            self.renderer = _CachedTextRenderer(w, h, self.figure.dpi)
            self._lastKey = key
        return self.renderer
