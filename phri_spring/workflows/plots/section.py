"""The section figure of a config and one sample's forces (``phri simulate --plot``'s
``<stem>_section`` file, ``phri compare``'s per-condition ones): the config's outlines and
elements arranged in panels for :func:`phri_spring.reports.section_figures.section_figure`.

A grid gives one panel per row. A free layout (``cuff.patches``) gives one panel per axial
band: patches whose axial extents overlap (directly or through others) share a band, drawn
on the outline at the band's mean position.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...io.outputs.atomic import atomic_file

__all__ = ["section_panels", "patch_bands", "section_path", "write_section_plot",
           "write_compare_sections", "live_section_meta"]


def patch_bands(x, length) -> list:
    """Index arrays of the axial bands of patches at ``x`` of axial size ``length`` [m]:
    connected groups of overlapping extents (touching ones, a mat's rows, stay apart),
    proximal first."""
    x, length = np.asarray(x, float), np.asarray(length, float)
    lo, hi = x - length / 2, x + length / 2
    order = np.argsort(lo, kind="stable")
    bands, cur, end = [], [], -np.inf
    tol = 1e-9
    for i in order:
        if cur and lo[i] < end - tol:
            cur.append(i)
            end = max(end, hi[i])
        else:
            if cur:
                bands.append(np.array(cur))
            cur, end = [i], hi[i]
    bands.append(np.array(cur))
    return bands


def section_panels(cfg, geometry, pressures_kpa) -> list:
    """:class:`~phri_spring.reports.section_figures.SectionPanel` of every row (grid) or band
    (free layout) of a config, with the elements' pressures (n,) [kPa]."""
    from ...io.config.geometry import config_outlines
    from ...reports.section_figures import SectionPanel

    g = geometry
    p = np.asarray(pressures_kpa, float)
    yz, nrm = g.points[:, 1:], g.normals[:, 1:]
    if g.free_layout:
        bands = patch_bands(g.x, g.row_width)
        outlines = config_outlines(cfg, [float(np.mean(g.x[b])) for b in bands])
        groups = [(f"x = {1e3 * np.mean(g.x[b]):.0f} mm", b, o) for b, o in zip(bands, outlines)]
    else:
        outlines = config_outlines(cfg)
        idx = g.row_index
        groups = [(f"Row {r}, x = {1e3 * cfg.row_x[i]:.0f} mm", np.flatnonzero(idx == i),
                   outlines[i]) for i, r in enumerate(g.row_labels)]
    return [SectionPanel(title=t, outline=o, labels=tuple(g.labels[j] for j in b),
                         points=yz[b], normals=nrm[b], theta=g.theta[b], span=g.span[b],
                         pressures=p[b]) for t, b, o in groups]


def section_path(plot_path) -> Path:
    """``<stem>_section<suffix>`` beside a ``--plot`` file."""
    plot_path = Path(plot_path)
    return plot_path.with_name(f"{plot_path.stem}_section{plot_path.suffix}")


def write_section_plot(cfg, forces, path, *, title: str = "", dpi: int = 150) -> Path:
    """Draw the pressures of one sample's absolute forces (n,) [N] around the limb and
    write the figure atomically (PNG, SVG or PDF by the extension)."""
    from ...reports.compare.figures import save_figure
    from ...reports.section_figures import section_figure

    g = cfg.geometry()
    pressures = np.asarray(forces, float) / g.areas / 1e3
    fig = section_figure(section_panels(cfg, g, pressures),
                         pain_threshold_kpa=cfg.pain_threshold_kpa,
                         loadcell_yz=np.asarray(cfg.loadcell_position, float)[1:], title=title)
    path = Path(path)
    with atomic_file(path) as tmp:
        save_figure(fig, tmp, dpi)
    return path


def write_compare_sections(result, tmp: Path, outdir: Path, dpi: int) -> list:
    """``sections/<arm>_peak.png``: per arm model, the pressure around the limb in the
    trial and condition where that arm predicts its highest pressure (one figure per arm,
    whatever the number of trials), for :func:`~.compare.write_compare` (``result``, a
    :class:`~.compare.CompareResult`) writing into ``tmp`` what lands in ``outdir``."""
    from ...reports.figure_base import ARM_NAMES

    cfg = result.config
    inv_area = 1.0 / (1e3 * cfg.geometry().areas)
    out = []
    best = {}
    for tc in result.trials:
        for j, c in enumerate(tc.conditions):
            if j == tc.baseline_index:
                continue
            for a in result.arms:
                p = np.asarray(tc.simulated_abs[a][j], float) * inv_area
                if np.isfinite(p).any() and (a not in best or np.nanmax(p) > best[a][0]):
                    best[a] = (float(np.nanmax(p)), tc, j, c)
    if best:
        (tmp / "sections").mkdir()
    for a in result.arms:
        if a not in best:
            continue
        _, tc, j, c = best[a]
        s = tc.spec
        name = f"{a}_peak.png"          # arm names are file-safe
        write_section_plot(cfg, tc.simulated_abs[a][j], tmp / "sections" / name, dpi=dpi,
                           title=f"{ARM_NAMES.get(a, a)}, its highest pressure: {s.experiment} "
                                 f"{s.direction}, trial {s.trial}, condition {c}")
        out.append(outdir / "sections" / name)
    return out


def live_section_meta(cfg, geometry, max_points: int = 180) -> dict:
    """What ``phri live --dashboard`` draws its view of the pressure around the limb from
    (JSON-able, lengths in mm): per panel (row or band of patches) the outline (at most
    ``max_points`` vertices), the pain threshold's line (the outline moved outward by the
    band length of the threshold) and each element's arc and outward unit normal; per
    element 1 / (1000 A_e) [kPa/N]."""
    from ...reports.section_figures import element_arc, offset_outline

    g = geometry
    panels = section_panels(cfg, g, np.zeros(g.n))
    index = {lab: i for i, lab in enumerate(g.labels)}
    rmax = 1e3 * max(float(np.hypot(*np.asarray(p.outline).T).max()) for p in panels)
    band = 0.3 * rmax                    # the band length of a pressure at the threshold
    out = {"threshold_kpa": float(cfg.pain_threshold_kpa), "band_mm": round(band, 3),
           "loadcell": np.round(1e3 * np.asarray(cfg.loadcell_position, float)[1:],
                                3).tolist(),
           "inv_area_kpa": (1.0 / (1e3 * g.areas)).tolist(), "panels": []}
    for p in panels:
        yz = 1e3 * np.asarray(p.outline, float)
        step = max(1, int(np.ceil(len(yz) / max_points)))
        nrm = -np.asarray(p.normals, float)
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        out["panels"].append({
            "title": p.title, "outline": np.round(yz[::step], 3).tolist(),
            "ring": np.round(offset_outline(yz, band)[::step], 3).tolist(),
            "elements": [{"index": index[lab],
                          "arc": np.round(element_arc(yz, float(p.theta[e]),
                                                      float(p.span[e]), n=9), 3).tolist(),
                          "out": np.round(nrm[e], 5).tolist()}
                         for e, lab in enumerate(p.labels)]})
    return out
