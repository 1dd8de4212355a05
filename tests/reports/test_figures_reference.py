"""The compare figures look the same as before the rendering was made faster.

``tests/data/heatmap_reference.png`` and ``tests/data/wrench_reference.png``
were rendered by the rendering code as it was before it was optimised (commit
"tests: reference renderings of the compare figures"), from the fixed inputs
below; the images rendered today must match them within a small tolerance (RMS
difference of the pixel values, matplotlib's ``compare_images``).
"""

from __future__ import annotations
from support.helpers import TESTS  # noqa: E402


import numpy as np
import pytest

pytest.importorskip("matplotlib")

from matplotlib.testing.compare import compare_images  # noqa: E402

from phri_spring.reports.compare.figures import heatmap_figure, save_figure, wrench_figure  # noqa: E402

DATA = TESTS / "data"
TOL = 2.0


def heatmap_inputs():
    """Fixed, hand-made inputs: 3 rows x 7 angles, a NaN cell, values of both signs."""
    e = np.arange(21, dtype=float)
    measured = 6.0 * np.sin(0.7 * e) - 1.0
    measured[5] = np.nan
    simulated = {"rigid": 8.0 * np.cos(0.5 * e), "compliant": 5.0 * np.sin(0.7 * e + 0.3)}
    rmse = {"rigid": 3.25, "compliant": 1.5}
    title = ("I-Act horizontal, trial 1, L2 (33.4 N), zeroed on no_load\n"
             "load-cell wrench, zeroed: Fx +1.00, Fy -2.00, Fz +33.40 N; "
             "Mx +0.100, My -0.200, Mz +0.300 N·m")
    return measured, simulated, rmse, title


def wrench_inputs():
    t = np.linspace(0.0, 13.0, 1301)
    w = np.column_stack([np.sin(t), np.cos(t), 10 * (t > 4) + 20 * (t > 8), 0.1 * np.sin(2 * t),
                         0.05 * t, -0.02 * t])
    cond = np.full(t.size, "", dtype=object)
    cond[(t > 0.5) & (t < 3.5)] = "no_load"
    cond[(t > 4.5) & (t < 7.5)] = "L1"
    cond[(t > 8.5) & (t < 12.5)] = "L2"
    return t, w, cond


def render_heatmap(path):
    measured, simulated, rmse, title = heatmap_inputs()
    fig = heatmap_figure(measured, simulated, row_labels=("A", "B", "C"), n_angles=7,
                         title=title, rmse=rmse)
    return save_figure(fig, path, 100)


def render_wrench(path):
    t, w, cond = wrench_inputs()
    fig = wrench_figure(t, w, cond, title="I-Act horizontal, trial 1: load-cell wrench")
    return save_figure(fig, path, 100)


@pytest.mark.parametrize("name, render", [("heatmap", render_heatmap),
                                          ("wrench", render_wrench)])
def test_rendering_matches_reference(tmp_path, name, render):
    out = render(tmp_path / f"{name}.png")
    ref = DATA / f"{name}_reference.png"
    assert ref.is_file()
    diff = compare_images(str(ref), str(out), tol=TOL)
    assert diff is None, diff


def test_reference_comparison_can_fail(tmp_path):
    # the comparison sees a change of one panel's values (the test can fail)
    measured, simulated, rmse, title = heatmap_inputs()
    simulated = dict(simulated, rigid=-simulated["rigid"])
    fig = heatmap_figure(measured, simulated, row_labels=("A", "B", "C"), n_angles=7,
                         title=title, rmse=rmse)
    out = save_figure(fig, tmp_path / "changed.png", 100)
    assert compare_images(str(DATA / "heatmap_reference.png"), str(out), tol=TOL) is not None


if __name__ == "__main__":  # regenerate the references (only from the reference code)
    DATA.mkdir(exist_ok=True)
    render_heatmap(DATA / "heatmap_reference.png")
    render_wrench(DATA / "wrench_reference.png")


# --------------------------------------------------------------------------- fast rendering
def _scaled_inputs(k):
    measured, simulated, rmse, title = heatmap_inputs()
    scale = (1.0, 2.0, 0.37, 11.0, 0.5, 2.0)[k]
    return (measured * scale, {a: v * scale for a, v in simulated.items()},
            {a: v * scale for a, v in rmse.items()}, title.replace("L2", f"L{k}"))


def test_reused_renderer_draws_what_a_new_figure_draws(tmp_path):
    from phri_spring.reports.compare.figures import HeatmapRenderer

    r = HeatmapRenderer(3, row_labels=("A", "B", "C"), n_angles=7)
    for k in range(6):          # colour scales of several widths, one met twice
        m, s, e, t = _scaled_inputs(k)
        r.fill(m, s, title=t, rmse=e)
        got = r.save(tmp_path / f"reused{k}.png", 60)
        fresh = save_figure(heatmap_figure(m, s, row_labels=("A", "B", "C"), n_angles=7,
                                           title=t, rmse=e), tmp_path / f"fresh{k}.png", 60)
        # the unchanging parts are laid over the rest: the same pixels up to rounding
        assert compare_images(str(fresh), str(got), tol=0.5) is None, k


def test_rendering_does_not_depend_on_what_came_before(tmp_path):
    from phri_spring.reports.compare.figures import HeatmapRenderer

    def run(order, folder):
        folder.mkdir()
        r = HeatmapRenderer(3, row_labels=("A", "B", "C"), n_angles=7)
        for k in order:
            m, s, e, t = _scaled_inputs(k)
            r.fill(m, s, title=t, rmse=e)
            r.save(folder / f"{k}.png", 60)

    run(range(6), tmp_path / "a")
    run(reversed(range(6)), tmp_path / "b")
    for k in range(6):
        assert (tmp_path / "a" / f"{k}.png").read_bytes() == \
            (tmp_path / "b" / f"{k}.png").read_bytes(), k


def test_reused_wrench_renderer_draws_what_a_new_figure_draws(tmp_path):
    from phri_spring.reports.compare.figures import WrenchRenderer

    t, w, cond = wrench_inputs()
    r = WrenchRenderer()
    for k, scale in enumerate((1.0, 40.0, 0.02, 1.0)):     # tick labels of several widths
        c = cond.copy()
        if k % 2:
            c[(t > 8.5)] = ""                                 # fewer windows
        r.fill(t, w * scale, c, title=f"trial {k}")
        got = r.save(tmp_path / f"reused{k}.png", 60)
        fresh = save_figure(wrench_figure(t, w * scale, c, title=f"trial {k}"),
                            tmp_path / f"fresh{k}.png", 60)
        assert compare_images(str(fresh), str(got), tol=0.5) is None, k


@pytest.mark.parametrize("opaque", [True, False])
def test_png_writer_keeps_every_pixel(tmp_path, opaque):
    from PIL import Image

    from phri_spring.reports.compare.figures import write_png

    rng = np.random.default_rng(7)
    rgba = rng.integers(0, 256, (31, 47, 4), dtype=np.uint8)
    if opaque:
        rgba[..., 3] = 255
    write_png(tmp_path / "x.png", rgba, 170)
    with Image.open(tmp_path / "x.png") as im:          # another decoder reads it back
        assert im.mode == ("RGB" if opaque else "RGBA")
        back = np.asarray(im)
        assert round(im.info["dpi"][0]) == 170
    np.testing.assert_array_equal(back, rgba[..., :3] if opaque else rgba)


def test_cell_values_draw_what_plain_texts_draw():
    # the heat-map cells keep their strings' layouts: the same pixels as matplotlib's Text,
    # on the first draw and on later ones (from the kept layouts), at several resolutions
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from phri_spring.reports.compare.heatmap import _CellText

    rng = np.random.default_rng(3)
    values = [f"{v:.1f}" for v in rng.normal(0, 20, 40)] + ["0.0", "-0.1", "123.4", ""]
    xy = rng.uniform(0, 1, (len(values), 2))

    def draw(cls, dpi):
        fig = Figure(figsize=(3, 2), dpi=dpi)
        ax = fig.add_subplot()
        for (x, y), s in zip(xy, values):
            t = cls(x, y, s, ha="center", va="center", fontsize=7, color="0.1")
            ax.add_artist(t)
        canvas = FigureCanvasAgg(fig)
        canvas.draw()
        first = np.array(canvas.buffer_rgba())
        canvas.draw()
        np.testing.assert_array_equal(first, np.asarray(canvas.buffer_rgba()))
        return first

    from matplotlib.text import Text

    for dpi in (60, 100, 170):
        np.testing.assert_array_equal(draw(_CellText, dpi), draw(Text, dpi))


def _png_pixels(path):
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGBA"))


@pytest.mark.parametrize("kind", ["heatmap", "wrench", "bars", "plain", "tight"])
def test_save_figure_writes_the_pixels_of_savefig(tmp_path, kind):
    # save_figure draws PNGs once on the text-caching canvas: the pixels Figure.savefig writes
    import pandas as pd
    from matplotlib.figure import Figure

    from phri_spring.reports.compare.figures import rmse_bars_figure

    def make():
        if kind == "heatmap":
            m, s, e, t = heatmap_inputs()
            return heatmap_figure(m, s, row_labels=("A", "B", "C"), n_angles=7, title=t, rmse=e)
        if kind == "wrench":
            return wrench_figure(*wrench_inputs(), title="trial 1")
        if kind == "bars":
            summary = pd.DataFrame({"experiment": ["E"] * 4, "direction": ["h"] * 4,
                                    "condition": ["L1", "L1", "L2", "L2"],
                                    "arm": ["rigid", "compliant"] * 2,
                                    "mean_rmse_N": [1.0, 0.5, 2.0, 0.8],
                                    "se_rmse_N": [0.1, 0.05, 0.2, 0.1], "n_trials": [3] * 4,
                                    "load_N": [10.0, 10.0, 20.0, 20.0]})
            return rmse_bars_figure(summary)
        fig = Figure(figsize=(3, 2), layout="tight" if kind == "tight" else None)
        ax = fig.add_subplot()
        ax.plot([0, 1, 4], [2, -1, 3], label="a line")
        ax.set_title("title [N·m]")
        ax.legend()
        return fig

    ours = save_figure(make(), tmp_path / "ours.png", 83)
    theirs = tmp_path / "theirs.png"
    from phri_spring.reports.figure_base import figure_style

    fig = make()                     # made outside the style, as ours; saved inside it, as ours
    with figure_style():
        fig.savefig(theirs, dpi=83)
    np.testing.assert_array_equal(_png_pixels(ours), _png_pixels(theirs))


@pytest.mark.parametrize("rc", [{"savefig.bbox": "tight"}, {"savefig.transparent": True},
                                {"savefig.facecolor": "0.9"}])
def test_save_figure_honours_the_users_savefig_settings(tmp_path, rc):
    # a matplotlibrc asking savefig for a tight box or another background is obeyed
    import matplotlib

    from phri_spring.reports.compare.figures import HeatmapRenderer

    m, s, e, t = heatmap_inputs()
    with matplotlib.rc_context(rc):
        ours = save_figure(wrench_figure(*wrench_inputs(), title="x"), tmp_path / "w.png", 50)
        fig = wrench_figure(*wrench_inputs(), title="x")
        from phri_spring.reports.figure_base import figure_style

        with figure_style():
            fig.savefig(tmp_path / "ref.png", dpi=50)
        r = HeatmapRenderer(3, row_labels=("A", "B", "C"), n_angles=7)
        r.fill(m, s, title=t, rmse=e)
        reused = r.save(tmp_path / "h.png", 50)
        fresh = save_figure(heatmap_figure(m, s, row_labels=("A", "B", "C"), n_angles=7,
                                           title=t, rmse=e), tmp_path / "hf.png", 50)
    np.testing.assert_array_equal(_png_pixels(ours), _png_pixels(tmp_path / "ref.png"))
    assert _png_pixels(reused).shape == _png_pixels(fresh).shape
