"""The pressure around the limb, section by section (``phri simulate --plot``'s second figure).

One panel per row of a grid (or per axial band of a free layout's patches): the limb's
skin outline in the cuff's y-z plane as it really is (circle, ellipse, outline spline, a
scan's cut), each element drawn along the outline as a thick arc, and the element's
contact pressure as a band standing outward from its arc, along the element's outward
normal, of length proportional to the pressure (one scale for every panel, shown by a
scale bar) and coloured by it (colour bar in kPa). A dashed line at the pain threshold's
length around the outline shows which bands reach it; the load cell and the limb's axis
are marked. Pure: arrays in, a :class:`matplotlib.figure.Figure` out (no pyplot, no file).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure

from .figure_base import figure_style

__all__ = ["SectionPanel", "section_figure", "element_arc", "offset_outline", "BAND_GID",
           "ARC_GID", "OUTLINE_GID", "MAX_PANELS"]

#: gid of the artists a test or a caller can find: the outline, an element's arc, its band
OUTLINE_GID, ARC_GID, BAND_GID = "section-outline", "section-arc", "section-band"
#: at most this many panels (the rows, or bands, with the highest peaks; the rest left out)
MAX_PANELS = 12
#: the largest band is this share of the largest distance of an outline from the axis
_BAND_SHARE = 0.45
#: the pain threshold's line is drawn when it is within this multiple of the largest band
_THRESHOLD_REACH = 1.6
_ARC_COLOR, _OUTLINE_COLOR, _THRESHOLD_COLOR, _OVER_COLOR = "#222222", "#8c8c8c", "#C0392B", \
    "#C0392B"


@dataclass
class SectionPanel:
    """One panel: a row's (or a band's) outline and its elements.

    Attributes
    ----------
    title : str
        E.g. ``"Row A, x = -25 mm"``.
    outline : ndarray, shape (k, 2)
        The skin outline's (y, z) [m], in order around the axis (not repeating the first).
    labels : sequence of str
        The elements' labels (m,).
    points : ndarray, shape (m, 2)
        Each element's point on the outline (y, z) [m].
    normals : ndarray, shape (m, 2)
        Each element's inward normal's (y, z) part (any length; the band points the other way).
    theta, span : ndarray, shape (m,)
        Each element's angle and angular width [rad]: its arc runs along the outline between
        the rays at theta -/+ span / 2.
    pressures : ndarray, shape (m,)
        Contact pressure [kPa] (0 where the element lifted off; NaN: not drawn).
    """

    title: str
    outline: np.ndarray
    labels: tuple
    points: np.ndarray
    normals: np.ndarray
    theta: np.ndarray
    span: np.ndarray
    pressures: np.ndarray


def element_arc(outline, theta: float, span: float, n: int = 24) -> np.ndarray:
    """(n, 2) points of the outline between the rays at theta -/+ span / 2 [m]: its distance
    from the axis interpolated (periodically) in the angle between the outline's vertices."""
    yz = np.asarray(outline, dtype=float)
    phi = np.mod(np.arctan2(yz[:, 1], yz[:, 0]), 2 * math.pi)
    rho = np.hypot(yz[:, 0], yz[:, 1])
    order = np.argsort(phi)
    a = np.linspace(theta - span / 2, theta + span / 2, n)
    r = np.interp(np.mod(a, 2 * math.pi), phi[order], rho[order], period=2 * math.pi)
    return np.column_stack([r * np.cos(a), r * np.sin(a)])


def _nice(v: float) -> float:
    """The largest 1, 2, 2.5 or 5 x 10^k not above v (v > 0)."""
    e = 10.0 ** math.floor(math.log10(v))
    return max(m * e for m in (1, 2, 2.5, 5, 10) if m * e <= v * (1 + 1e-12))


def offset_outline(outline: np.ndarray, d: float) -> np.ndarray:
    """The closed outline moved outward by d [same unit] along its vertex normals."""
    nxt, prv = np.roll(outline, -1, axis=0), np.roll(outline, 1, axis=0)
    t = nxt - prv
    nrm = np.column_stack([t[:, 1], -t[:, 0]])
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
    # the outline runs counter-clockwise (increasing angle): (t_z, -t_y) points outward
    return outline + d * nrm


def section_figure(panels, *, pain_threshold_kpa: float, loadcell_yz=None, title: str = "",
                   pressure_name: str = "Contact pressure") -> Figure:
    """Draw the pressure around the limb, one panel per :class:`SectionPanel`.

    Parameters
    ----------
    panels : sequence of SectionPanel
        At most :data:`MAX_PANELS` are drawn: those with the highest peak pressures, in their
        given order; the title says how many were left out.
    pain_threshold_kpa : float
        Drawn as a dashed line around each outline (when within reach of the bands) and on
        the colour bar.
    loadcell_yz : array_like (2,), optional
        The load cell's (y, z) in the cuff frame [m].
    title : str
        The figure's title.

    Returns
    -------
    Figure
        Each band is a patch with gid :data:`BAND_GID` and ``label`` its element's; its
        vertices are the arc's (first half) and the arc's moved outward (second half).
    """
    from matplotlib import colors
    from matplotlib.cm import ScalarMappable
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Polygon

    panels = list(panels)
    if not panels:
        raise ValueError("section_figure: no panel to draw")
    left_out = 0
    if len(panels) > MAX_PANELS:
        peaks = np.array([np.nanmax(p.pressures, initial=-np.inf) for p in panels])
        keep = np.sort(np.argsort(-peaks, kind="stable")[:MAX_PANELS])
        left_out = len(panels) - MAX_PANELS
        panels = [panels[i] for i in keep]
    allp = np.concatenate([np.asarray(p.pressures, float) for p in panels])
    finite = allp[np.isfinite(allp)]
    pmax = float(finite.max()) if finite.size and finite.max() > 0 else 0.0
    rmax = max(float(np.hypot(*np.asarray(p.outline, float).T).max()) for p in panels) * 1e3
    # one scale for every panel [mm per kPa]: the largest pressure (or the threshold, when
    # nothing presses) reaches _BAND_SHARE of the largest outline
    ref = pmax if pmax > 0 else float(pain_threshold_kpa)
    scale = _BAND_SHARE * rmax / ref
    threshold = float(pain_threshold_kpa)
    draw_threshold = threshold * scale <= _THRESHOLD_REACH * _BAND_SHARE * rmax
    vmax = max(pmax, threshold) if draw_threshold else max(pmax, 1e-9)
    norm = colors.Normalize(0.0, vmax)
    import matplotlib

    cmap = matplotlib.colormaps["YlOrRd"]

    n = len(panels)
    ncols = min(n, 3 if n != 4 else 2)
    nrows = math.ceil(n / ncols)
    with figure_style():
        fig = Figure(figsize=(2.9 * ncols + 1.1, 3.1 * nrows + 1.3), layout="constrained")
        axes = fig.subplots(nrows, ncols, squeeze=False, sharex=True, sharey=True)
        for ax in axes.flat[n:]:
            ax.set_visible(False)
        drawn = []    # every point drawn [mm]: the panels' common limits
        for ax, p in zip(axes.flat, panels):
            out = np.asarray(p.outline, float) * 1e3
            drawn.append(out)
            closed = np.vstack([out, out[:1]])
            ax.plot(closed[:, 0], closed[:, 1], color=_OUTLINE_COLOR, lw=1.0, zorder=2,
                    gid=OUTLINE_GID)
            if draw_threshold:
                ring = offset_outline(out, threshold * scale)
                ring = np.vstack([ring, ring[:1]])
                drawn.append(ring)
                ax.plot(ring[:, 0], ring[:, 1], color=_THRESHOLD_COLOR, lw=0.9, ls=(0, (4, 3)),
                        zorder=1)
            nrm = np.asarray(p.normals, float)
            nrm = nrm / np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
            many = len(p.labels) > 12    # labels would overlap
            for e, label in enumerate(p.labels):
                arc = element_arc(out, float(p.theta[e]), float(p.span[e]))
                ax.plot(arc[:, 0], arc[:, 1], color=_ARC_COLOR, lw=2.4,
                        solid_capstyle="butt", zorder=4, gid=ARC_GID, label=str(label))
                pe = float(p.pressures[e])
                if math.isfinite(pe) and pe > 0:
                    tip = arc - pe * scale * nrm[e]
                    drawn.append(tip)
                    over = pe >= threshold
                    ax.add_patch(Polygon(np.vstack([arc, tip[::-1]]), closed=True,
                                         facecolor=cmap(norm(pe)),
                                         edgecolor=_OVER_COLOR if over else "#5a5a5a",
                                         lw=1.1 if over else 0.4, zorder=3, gid=BAND_GID,
                                         label=str(label)))
                if not many:
                    c = np.asarray(p.points[e], float) * 1e3
                    inward = c + 0.13 * rmax * nrm[e]
                    ax.text(inward[0], inward[1], str(label), ha="center", va="center",
                            fontsize=6.5, color="#444444", zorder=5)
            ax.plot([0], [0], marker="+", color="#444444", ms=7, mew=1.0, zorder=5)
            if loadcell_yz is not None:
                lc = np.asarray(loadcell_yz, float) * 1e3
                drawn.append(lc[None, :])
                ax.plot([lc[0]], [lc[1]], marker="s", ms=6, mfc="white", mec="black",
                        mew=1.2, zorder=6)
            fin = np.asarray(p.pressures, float)
            fin = fin[np.isfinite(fin)]
            peak = f"; peak {fin.max():.3g} kPa" if fin.size else ""
            ax.set_title(p.title + peak)
            ax.set_aspect("equal", adjustable="box")
            ax.tick_params(direction="out", length=3)
            for side in ("top", "right"):
                ax.spines[side].set_visible(False)
        for ax in axes[-1, :]:
            ax.set_xlabel("y [mm]")
        for ax in axes[:, 0]:
            ax.set_ylabel("z [mm]")
        pts = np.vstack(drawn)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        pad = 0.06 * float(np.max(hi - lo))
        lo, hi = lo - pad, hi + pad
        lo[1] -= 0.08 * float(np.max(hi - lo))      # room for the scale bar
        axes.flat[0].set_xlim(lo[0], hi[0])
        axes.flat[0].set_ylim(lo[1], hi[1])
        # scale bar: a round pressure's band length, in the first panel's lower right corner
        bar_kpa = _nice(ref)
        length = bar_kpa * scale
        ax0 = axes.flat[0]
        span_y = hi[1] - lo[1]
        x1, y0 = hi[0] - 0.03 * (hi[0] - lo[0]), lo[1] + 0.04 * span_y
        ax0.plot([x1 - length, x1], [y0, y0], color="black", lw=2.0, solid_capstyle="butt",
                 zorder=6)
        ax0.text(x1 - length / 2, y0 + 0.015 * span_y, f"{bar_kpa:g} kPa", ha="center",
                 va="bottom", fontsize=7.5)
        sm = ScalarMappable(norm=norm, cmap=cmap)
        cb = fig.colorbar(sm, ax=axes, shrink=0.8 if nrows > 1 else 0.9, pad=0.02,
                          aspect=25)
        cb.set_label(f"{pressure_name} [kPa]")
        if threshold <= vmax:
            # black: the threshold's own red would vanish in the scale's dark reds
            cb.ax.axhline(threshold, color="black", lw=1.5, ls=(0, (4, 2)), zorder=5)
        handles = [Line2D([], [], color=_OUTLINE_COLOR, lw=1.0, label="skin outline"),
                   Line2D([], [], color=_ARC_COLOR, lw=2.4, label="cuff element"),
                   Patch(facecolor=cmap(0.55), edgecolor="#5a5a5a", lw=0.4,
                         label="pressure (length ∝ kPa)")]
        if draw_threshold:
            handles.append(Line2D([], [], color=_THRESHOLD_COLOR, lw=0.9, ls=(0, (4, 3)),
                                  label=f"pain threshold {threshold:g} kPa"))
        else:
            handles.append(Line2D([], [], color=_THRESHOLD_COLOR, lw=0.9, ls=(0, (4, 3)),
                                  label=f"pain threshold {threshold:g} kPa (off scale)"))
        handles.append(Line2D([], [], ls="none", marker="+", color="#444444", ms=7,
                              label="limb axis"))
        if loadcell_yz is not None:
            handles.append(Line2D([], [], ls="none", marker="s", ms=6, mfc="white",
                                  mec="black", mew=1.2, label="load cell"))
        fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 3),
                   frameon=False)
        head = title
        if left_out:
            head += f"\n({left_out} bands with lower peaks not shown)"
        if head:
            fig.suptitle(head)
    return fig
