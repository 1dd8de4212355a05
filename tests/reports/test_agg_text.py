"""The text-caching Agg canvas draws the very pixels matplotlib's own Agg canvas draws.

The reference is matplotlib's :class:`FigureCanvasAgg` itself, drawing the same
figure: every byte of the two images must be equal, for strings of many
characters, sizes, rotations, weights and sub-pixel positions, drawn twice (the
second draw comes from the caches), with and without antialiasing.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from phri_spring.reports import agg_text
from phri_spring.reports.agg_text import CachedTextCanvas


def _pixels(canvas_cls, fig) -> np.ndarray:
    canvas = canvas_cls(fig)
    canvas.draw()
    first = np.array(canvas.buffer_rgba())
    canvas.draw()                                   # again: now from the caches
    again = np.array(canvas.buffer_rgba())
    np.testing.assert_array_equal(first, again)
    return first


def _text_figure(strings, dpi, seed=0, antialiased=True) -> Figure:
    rng = np.random.default_rng(seed)
    fig = Figure(figsize=(4.3, 3.1), dpi=dpi)
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1])
    ax.set_title("Rigid arm\nRMSE 1.23 N")
    fig.suptitle("load-cell wrench, zeroed: Fx +1.00, Fy −2.00 N; Mx +0.100 N·m")
    for s in strings:
        ax.text(rng.uniform(0, 1), rng.uniform(0, 1), s, fontsize=float(rng.uniform(5, 14)),
                rotation=float(rng.choice([0.0, 90.0, 33.3, -12.0])),
                ha=str(rng.choice(["left", "center", "right"])),
                va=str(rng.choice(["baseline", "center", "top"])),
                weight=str(rng.choice(["normal", "bold"])),
                color=str(rng.choice(["k", "w", "C1"])),
                antialiased=antialiased)
    return fig


def test_fast_path_is_on_with_this_matplotlib():
    import matplotlib

    major, minor = (int(p) for p in matplotlib.__version__.split(".")[:2])
    if (major, minor) >= (3, 11):
        assert agg_text.AVAILABLE


@pytest.mark.filterwarnings("ignore:Glyph .* missing from font")
@pytest.mark.parametrize("dpi", [40, 100, 170, 97.3])
@pytest.mark.parametrize("antialiased", [True, False])
def test_same_pixels_as_matplotlib(dpi, antialiased):
    strings = ["-12.3", "0.0", "45.6", "RMSE 3.25 N", "zeroed load [N]", "A", "ÄÖü ß",
               "−7.5",
               "two\nlines", "$x^2$", "  spaced  ", "N·m", "ﬁ", "日本"]
    fig = _text_figure(strings, dpi, antialiased=antialiased)
    agg_text._GLYPHS.clear()
    np.testing.assert_array_equal(_pixels(CachedTextCanvas, fig), _pixels(FigureCanvasAgg, fig))
    assert len(agg_text._GLYPHS) > 0 or not agg_text.AVAILABLE     # the fast path drew


@settings(max_examples=25, deadline=None)
@given(st.lists(st.text(st.characters(min_codepoint=32, max_codepoint=0x24F,
                                      blacklist_categories=("Cc",),
                                      blacklist_characters="$\\"),
                        min_size=1, max_size=12), min_size=1, max_size=8),
       st.integers(0, 2**16), st.floats(30, 200))
def test_same_pixels_as_matplotlib_for_any_text(strings, seed, dpi):
    fig = _text_figure(strings, dpi, seed=seed)
    np.testing.assert_array_equal(_pixels(CachedTextCanvas, fig), _pixels(FigureCanvasAgg, fig))


def test_caches_stay_bounded(monkeypatch):
    monkeypatch.setattr(agg_text, "_MAX_ENTRIES", 10)
    fig = _text_figure([f"{v:.1f}" for v in np.linspace(-50, 50, 40)], 100)
    np.testing.assert_array_equal(_pixels(CachedTextCanvas, fig), _pixels(FigureCanvasAgg, fig))
    assert len(agg_text._GLYPHS) <= 10 and len(agg_text._LAYOUTS) <= 10


def test_threads_draw_with_their_own_fonts():
    # figures drawn at once in several threads (each its own figure): the same pixels as one
    # thread alone; cached layouts never hand one thread's font objects to another
    from concurrent.futures import ThreadPoolExecutor

    strings = [f"{v:.1f}" for v in np.linspace(-30, 30, 25)] + ["RMSE 1.25 N", "N·m"]
    alone = _pixels(FigureCanvasAgg, _text_figure(strings, 90, seed=5))
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(lambda k: _pixels(CachedTextCanvas, _text_figure(strings, 90, seed=5)),
                            range(8)))
    for g in got:
        np.testing.assert_array_equal(g, alone)
    owners = {key[-1] for key in agg_text._LAYOUTS}
    assert len(owners) >= 2 or not agg_text.AVAILABLE       # layouts kept per thread


def _forked_draw(strings):
    return len(agg_text._LAYOUTS), _pixels(CachedTextCanvas, _text_figure(strings, 90, seed=9))


def test_a_forked_child_uses_its_own_fonts():
    # the font objects kept with the layouts read their files through descriptions a forked
    # child shares with its parent ("failed to load glyph" when both read at once): a child
    # starts with no layouts of its parent's, and draws the same pixels
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    strings = ["12.5", "-3.0", "RMSE 0.75 N", "zeroed load [N]"]
    parent = _pixels(CachedTextCanvas, _text_figure(strings, 90, seed=9))
    assert agg_text._LAYOUTS or not agg_text.AVAILABLE
    with ProcessPoolExecutor(1, mp_context=mp.get_context("fork")) as pool:
        inherited, child = pool.submit(_forked_draw, strings).result()
    assert inherited == 0
    np.testing.assert_array_equal(child, parent)
