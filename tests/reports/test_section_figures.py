"""The section figure (reports/section_figures.py): one panel per row or band, the outline's
vertices the section's own points, bands along the outward normal with lengths proportional
to the pressures on one scale, and ``phri simulate --plot`` writing it beside the plot."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from support.helpers import HARMONY_CONFIG, REPO, one_line
from phri_cli.main import phri
from phri_spring.physics.cuff.geometry import cuff_geometry, section_geometry
from phri_spring.physics.limb.sections import EllipseSection, OutlineSection, outlines_at
from phri_spring.reports.section_figures import (ARC_GID, BAND_GID, MAX_PANELS, OUTLINE_GID,
                                                 SectionPanel, element_arc, section_figure)
from phri_spring.workflows.plots.section import patch_bands, section_panels, section_path

EXAMPLE = REPO / "examples" / "wrench_log.csv"
K = 256
RAYS = 2 * np.pi * np.arange(K) / K


def panels_of(geom, outlines, pressures):
    idx = geom.row_index
    return [SectionPanel(title=f"row {r}", outline=outlines[i],
                         labels=tuple(np.array(geom.labels)[idx == i]),
                         points=geom.points[idx == i, 1:], normals=geom.normals[idx == i, 1:],
                         theta=geom.theta[idx == i], span=geom.span[idx == i],
                         pressures=pressures[idx == i]) for i, r in enumerate(geom.row_labels)]


def visible_axes(fig):
    # the colour bar's axes has no title; the panels have theirs
    return [a for a in fig.axes if a.get_visible() and a.get_title()]


def bands(fig):
    """{label: (inner arc (m, 2), outer edge (m, 2)) [mm]} of every pressure band."""
    out = {}
    for ax in visible_axes(fig):
        for p in ax.patches:
            if p.get_gid() == BAND_GID:
                xy = p.get_xy()
                xy = xy[:-1] if np.allclose(xy[0], xy[-1]) else xy   # closed: first repeated
                m = len(xy) // 2
                out[p.get_label()] = (xy[:m], xy[m:][::-1])
        # (labels are unique across the panels of these tests)
    return out


def check_bands(fig, geom, pressures):
    """Every pressed element has a band whose outer edge is its arc moved along -n_e (yz part,
    normalised) by c * p_e, with one c for every band of every panel."""
    got = bands(fig)
    pressed = [e for e in range(geom.n) if pressures[e] > 0]
    assert sorted(got) == sorted(geom.labels[e] for e in pressed)
    scales = []
    for e in pressed:
        inner, outer = got[geom.labels[e]]
        out_dir = -geom.normals[e, 1:] / np.linalg.norm(geom.normals[e, 1:])
        d = outer - inner
        length = np.linalg.norm(d, axis=1)
        np.testing.assert_allclose(d / length[:, None], np.tile(out_dir, (len(d), 1)),
                                   atol=1e-9)
        np.testing.assert_allclose(length, length[0], rtol=1e-9)
        scales.append(length[0] / pressures[e])
    np.testing.assert_allclose(scales, scales[0], rtol=1e-9)


def outline_vertices(ax):
    lines = [ln for ln in ax.lines if ln.get_gid() == OUTLINE_GID]
    assert len(lines) == 1
    return lines[0].get_xydata()


def test_circle_rows_panels_and_bands():
    geom = cuff_geometry([-0.02, 0.0, 0.02], [0.045, 0.05, 0.055], 0.02, 75, 35, 7)
    outlines = outlines_at([-0.02, 0.0, 0.02], [-0.02, 0.0, 0.02], radius=[0.045, 0.05, 0.055])
    rng = np.random.default_rng(3)
    p = rng.uniform(0, 40, geom.n)
    p[[2, 9]] = 0.0                                    # lifted off: no band
    fig = section_figure(panels_of(geom, outlines, p), pain_threshold_kpa=50,
                         loadcell_yz=[-0.07, 0.0])
    axes = visible_axes(fig)
    assert len(axes) == 3
    for ax, r in zip(axes, [0.045, 0.05, 0.055]):
        xy = outline_vertices(ax)
        np.testing.assert_allclose(np.hypot(*xy.T), 1e3 * r, rtol=1e-12)   # the circle [mm]
        assert len([ln for ln in ax.lines if ln.get_gid() == ARC_GID]) == 7
        assert ax.get_aspect() == 1.0
        assert ax.get_xlim() == axes[0].get_xlim()                         # one scale
    check_bands(fig, geom, p)
    # the arcs lie on the circle and span the element's angle
    arc = element_arc(outlines[1], math.radians(75), math.radians(35))
    np.testing.assert_allclose(np.hypot(*arc.T), 0.05, rtol=1e-12)
    np.testing.assert_allclose(np.arctan2(arc[[0, -1], 1], arc[[0, -1], 0]),
                               np.radians([57.5, 92.5]), atol=1e-12)


def test_ellipse_with_taper():
    sec = EllipseSection(0.06, 0.045, math.radians(20))
    rows = [-0.025, 0.0, 0.025]
    geom = section_geometry(rows, sec, 0.02, 75, 35, 7, taper_deg=5.0)
    outlines = outlines_at(rows, rows, [sec] * 3)
    p = np.linspace(1, 30, geom.n)
    fig = section_figure(panels_of(geom, outlines, p), pain_threshold_kpa=25)
    axes = visible_axes(fig)
    assert len(axes) == 3
    for ax in axes:
        np.testing.assert_allclose(outline_vertices(ax)[:-1], 1e3 * sec.point(RAYS),
                                   rtol=1e-12, atol=1e-12)
    check_bands(fig, geom, p)
    # the element's point is on its arc (the middle of an odd sampling)
    for e in (0, 10, 20):
        mid = element_arc(outlines[0], geom.theta[e], geom.span[e], n=25)[12]
        np.testing.assert_allclose(mid, geom.points[e, 1:], atol=2e-5)


def test_outline_sections_per_row():
    ang = np.radians(np.arange(0, 360, 30))
    shapes = [np.column_stack([(0.05 + 0.006 * np.cos(2 * ang)) * np.cos(ang),
                               (0.05 + 0.006 * np.cos(2 * ang)) * np.sin(ang) * s])
              for s in (1.0, 0.9)]
    secs = [OutlineSection(s.tolist()) for s in shapes]
    geom = section_geometry([0.0, 0.03], secs, 0.02, 0, 45, 8)
    outlines = outlines_at([0.0, 0.03], [0.0, 0.03], secs)
    p = np.arange(1.0, geom.n + 1)
    fig = section_figure(panels_of(geom, outlines, p), pain_threshold_kpa=120)
    axes = visible_axes(fig)
    assert len(axes) == 2
    for ax, sec in zip(axes, secs):
        np.testing.assert_allclose(outline_vertices(ax)[:-1], 1e3 * sec.point(RAYS), atol=1e-9)
    check_bands(fig, geom, p)
    # the threshold is beyond reach: said in the legend, not drawn as a line
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert any("120 kPa (off scale)" in t for t in texts)


def test_outlines_between_rows_are_interpolated():
    out = outlines_at([0.0, 0.5, 1.0, 2.0], [0.0, 1.0], radius=[0.04, 0.06], k=16)
    np.testing.assert_allclose([np.hypot(*o.T).mean() for o in out], [0.04, 0.05, 0.06, 0.06])


def test_patch_bands():
    # two overlapping, one touching the second (a mat's next row), one far away
    got = patch_bands([0.0, 0.004, 0.009, 0.05], [0.006, 0.006, 0.004, 0.01])
    assert [sorted(b.tolist()) for b in got] == [[0, 1], [2], [3]]


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.1, 0.1), st.floats(0.001, 0.03)), min_size=1,
                max_size=12))
def test_patch_bands_partition(items):
    x, ln = np.array(items).T
    got = patch_bands(x, ln)
    assert sorted(np.concatenate(got).tolist()) == list(range(len(x)))
    lo, hi = x - ln / 2, x + ln / 2
    for a in got:            # no patch of a band overlaps a patch of another band
        for b in got:
            if a is not b:
                assert not np.any((lo[a][:, None] < hi[b][None, :] - 1e-9)
                                  & (lo[b][None, :] < hi[a][:, None] - 1e-9))


def test_free_layout_bands(tmp_path):
    from phri_spring.io.config import load_config

    cfg = load_config(REPO / "examples" / "pressure_mat_16x16.yaml")
    geom = cfg.geometry()
    p = geom.x * 100 + 10.0 + np.cos(geom.theta)        # peaks grow distally
    panels = section_panels(cfg, geom, p)
    assert len(panels) == 16 and all(len(q.labels) == 16 for q in panels)
    for q in panels:
        np.testing.assert_allclose(np.hypot(*q.outline.T), 0.045, rtol=1e-12)
    fig = section_figure(panels, pain_threshold_kpa=cfg.pain_threshold_kpa)
    axes = visible_axes(fig)
    assert len(axes) == MAX_PANELS                   # bounded: the 12 distal bands (highest)
    drawn = set(bands(fig))
    assert {lab for q in panels[-MAX_PANELS:] for lab in q.labels} == drawn
    assert "4 bands" in fig._suptitle.get_text()


def test_scan_geometry():
    from phri_spring.io.config import load_config
    from phri_spring.io.config.geometry import config_outlines

    cfg = load_config(REPO / "examples" / "scan" / "upper_arm_scan.yaml")
    geom = cfg.geometry()
    outlines = config_outlines(cfg)
    assert len(outlines) == cfg.n_rows
    p = np.linspace(2, 20, geom.n)
    panels = section_panels(cfg, geom, p)
    fig = section_figure(panels, pain_threshold_kpa=cfg.pain_threshold_kpa)
    axes = visible_axes(fig)
    assert len(axes) == cfg.n_rows
    for ax, yz in zip(axes, cfg.scan.elements.outlines):
        np.testing.assert_allclose(outline_vertices(ax)[:-1], 1e3 * np.asarray(yz), atol=1e-9)
    check_bands(fig, geom, p)


def invoke(*args):
    return CliRunner().invoke(phri, ["simulate", *map(str, args)], catch_exceptions=False)


def test_cli_writes_the_section_and_nothing_else_changes(tmp_path):
    log = tmp_path / "log.csv"
    df = pd.read_csv(EXAMPLE, comment="#")
    df.iloc[::40].to_csv(log, index=False)
    res = invoke(HARMONY_CONFIG, log, "-o", tmp_path / "a.csv")
    assert res.exit_code == 0, res.stderr
    res2 = invoke(HARMONY_CONFIG, log, "-o", tmp_path / "b.csv", "--plot", tmp_path / "p.png")
    assert res2.exit_code == 0, res2.stderr
    assert (tmp_path / "p_section.png").read_bytes().startswith(b"\x89PNG")
    assert section_path(tmp_path / "p.png") == tmp_path / "p_section.png"
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()
    assert res2.stderr.replace(str(tmp_path / "b.csv"), "A").replace(
        f"; plot {tmp_path / 'p.png'}", "") == res.stderr.replace(str(tmp_path / "a.csv"), "A")


def test_cli_refuses_a_section_path_over_an_input(tmp_path):
    log = tmp_path / "p_section.png"          # the section file would overwrite the log
    log.write_text("time,Fx,Fy,Fz,Mx,My,Mz\n0,1,2,3,0,0,0\n")
    res = invoke(HARMONY_CONFIG, log, "-o", tmp_path / "f.csv", "--plot", tmp_path / "p.png")
    assert res.exit_code == 2 and one_line(res.stderr)
    assert sorted(q.name for q in tmp_path.iterdir()) == ["p_section.png"]


def test_maxpool_keeps_the_peak_samples_forces(tmp_path):
    from phri_spring.io.config import load_config
    from phri_spring.workflows.plots.maxpool import MaxPool
    from phri_spring.workflows.simulate import simulate_file

    log = tmp_path / "log.csv"
    pd.read_csv(EXAMPLE, comment="#").iloc[::20].to_csv(log, index=False)
    cfg = load_config(HARMONY_CONFIG)
    pool = MaxPool(21, bins=10)
    simulate_file(cfg, log, tmp_path / "f.parquet", on_chunk=pool, chunk_rows=50)
    df = pd.read_parquet(tmp_path / "f.parquet")
    i = int(np.argmax(df["peak_pressure_kPa"].to_numpy()))
    labels = list(cfg.labels)
    np.testing.assert_allclose(pool.result().peak_forces, df[labels].iloc[i].to_numpy(),
                               rtol=1e-12, atol=1e-12)


def test_no_pressure_and_missing_values():
    """Nothing pressed (all lifted off) and NaN (no answer): no band, the panels still drawn,
    the scale taken from the pain threshold."""
    geom = cuff_geometry([0.0], 0.05, 0.02, 0, 90, 4)
    outlines = outlines_at([0.0], [0.0], radius=[0.05])
    for p in (np.zeros(4), np.array([np.nan, 0.0, np.nan, 0.0])):
        fig = section_figure(panels_of(geom, outlines, p), pain_threshold_kpa=100)
        assert len(visible_axes(fig)) == 1 and bands(fig) == {}
        texts = [t.get_text() for t in fig.legends[0].get_texts()]
        assert "pain threshold 100 kPa" in texts
    with pytest.raises(ValueError):
        section_figure([], pain_threshold_kpa=100)


NODE = __import__("shutil").which("node")

_DOM_STUB = """
const calls = {};
function element(id) {
  const rec = {fills: [], path: []};
  calls[id] = rec;
  const ctx = new Proxy({}, {get(t, name) {
    if (name in t) return t[name];
    if (name === "beginPath") return () => { rec.path = []; };
    if (name === "moveTo" || name === "lineTo") return (x, y) => { rec.path.push([x, y]); };
    if (name === "fill") return () => { rec.fills.push({path: rec.path.slice(),
                                                         style: t.fillStyle}); };
    return () => {};
  }, set(t, name, v) { t[name] = v; return true; }});
  return {width: 520, height: 360, getContext: () => ctx, setAttribute() {},
          querySelectorAll: () => [], innerHTML: "", textContent: "", className: "",
          style: {}};
}
const els = {};
const document = {getElementById: id => (els[id] = els[id] || element(id)),
                  querySelectorAll: () => [], querySelector: () => element("q")};
const window = {};
"""


@pytest.mark.skipif(NODE is None, reason="node is not installed (the page's script is run in it)")
def test_dashboard_section_view(tmp_path):
    """The live page's view of the pressure around the limb draws, in the panel of the
    peak's row, one band per pressed element, its length proportional to the pressure."""
    import json
    import re
    import subprocess

    from phri_spring.io.config import load_config
    from phri_spring.io.live.dashboard import page_text
    from phri_spring.workflows.plots.section import live_section_meta

    cfg = load_config(HARMONY_CONFIG)
    geom = cfg.geometry()
    kpa = np.linspace(5.0, 60.0, geom.n)          # below the threshold: no band capped
    kpa[geom.row_index == 2] *= 0.5               # the peak in row B (the last of B)
    kpa[8] = 0.0                                  # B1 lifted off
    assert cfg.pain_threshold_kpa > kpa.max()
    peak = int(np.argmax(kpa))
    assert geom.labels[peak] == "B6"
    meta = {"labels": list(geom.labels), "row_labels": list(geom.row_labels), "n_angles": 7,
            "alarm": None, "title": "t", "section": live_section_meta(cfg, geom)}
    snap = {"sample": 1, "time": 0.0, "forces": [0.0] * geom.n,
            "absolute_forces": (kpa * 1e3 * geom.areas).tolist(), "wrench": [0.0] * 6,
            "peak_pressure_kPa": float(kpa[peak]), "peak_element": "B6", "ratio": 0.5,
            "contacts_in_touch": 20, "converged": True, "alarm": False,
            "health": {"samples": 1, "lost": 0, "malformed": 0, "gaps": 0, "rate_hz": None,
                       "processing_ms": None, "age_ms": None}}
    script = re.search(r"<script>(.*)</script>", page_text(), re.S).group(1)
    script = script.replace("/*PHRI_INIT*/null", json.dumps({"meta": meta, "snapshot": snap}))
    (tmp_path / "page.js").write_text(_DOM_STUB + script +
                                      "\nconsole.log(JSON.stringify(calls.section.fills));\n")
    res = subprocess.run([NODE, str(tmp_path / "page.js")], capture_output=True, text=True,
                         timeout=60)
    assert res.returncode == 0, res.stderr
    fills = json.loads(res.stdout)
    row_b = [e for e in range(7, 14) if kpa[e] > 0]
    assert len(fills) == len(row_b)               # the panel of row B, B1 without a band
    # a band: the arc's 9 points, then its tip's in reverse; first to last = the length
    lengths = [math.dist(f["path"][0], f["path"][-1]) for f in fills]
    np.testing.assert_allclose(np.array(lengths) / kpa[row_b],
                               lengths[0] / kpa[row_b[0]], rtol=2e-3)


@pytest.mark.parametrize("name", ["examples/pressure_mat_16x16.yaml",
                                  "examples/scan/upper_arm_scan.yaml"])
def test_live_section_meta(name):
    """The dashboard's section data for a free layout and a scan: JSON as sent, every element
    in exactly one panel, outlines bounded in size and on the geometry's outlines."""
    import json

    from phri_spring.io.config import load_config
    from phri_spring.io.config.geometry import config_outlines
    from phri_spring.workflows.plots.section import live_section_meta

    cfg = load_config(REPO / name)
    geom = cfg.geometry()
    meta = json.loads(json.dumps(live_section_meta(cfg, geom), allow_nan=False))
    idx = sorted(e["index"] for p in meta["panels"] for e in p["elements"])
    assert idx == list(range(geom.n))
    assert all(len(p["outline"]) <= 180 for p in meta["panels"])
    np.testing.assert_allclose(meta["inv_area_kpa"], 1 / (1e3 * geom.areas), rtol=1e-12)
    if cfg.scan is not None:
        for p, yz in zip(meta["panels"], config_outlines(cfg)):
            step = math.ceil(len(yz) / 180)
            np.testing.assert_allclose(p["outline"], 1e3 * np.asarray(yz)[::step], atol=1e-3)
