"""Figures of a free element layout (``cuff.patches``, docs/model.md section 14).

A rows x angles heat map does not fit patches placed anywhere: these figures draw the
limb's surface unrolled, angle theta [deg] across and axial position x [mm] down, each
patch as a rectangle of its angular and axial size coloured by its value. Only
:class:`matplotlib.figure.Figure` is used, never pyplot.
"""

from __future__ import annotations

import math
from typing import Optional, Sequence

import numpy as np
from matplotlib.collections import PatchCollection
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from .figure_base import ARM_NAMES, figure_style

__all__ = ["unrolled_theta_deg", "draw_unrolled", "layout_figure", "layout_compare_figure"]


def unrolled_theta_deg(theta) -> np.ndarray:
    """Angles [rad] -> degrees unwrapped about the layout's mean direction, so that a cuff
    opening across 180 deg or 0 deg is drawn in one piece."""
    theta = np.asarray(theta, dtype=float)
    mid = math.atan2(np.sin(theta).mean(), np.cos(theta).mean())
    return np.degrees(mid + (theta - mid + math.pi) % (2 * math.pi) - math.pi)


def draw_unrolled(ax, x, theta, width, length, values, *, cmap="viridis", vmin=None,
                  vmax=None, labels: Optional[Sequence[str]] = None) -> PatchCollection:
    """Draw patches on an axes of the unrolled surface; returns their collection (the
    mappable for a colour bar).

    x, length [m]; theta, width [rad]; values (n,) in any unit (NaN drawn grey).
    """
    th = unrolled_theta_deg(theta)
    wd = np.degrees(np.asarray(width, float))
    xm, lm = 1000.0 * np.asarray(x, float), 1000.0 * np.asarray(length, float)
    rects = [Rectangle((t - w / 2, a - b / 2), w, b) for t, w, a, b in zip(th, wd, xm, lm)]
    import matplotlib

    cm = (matplotlib.colormaps[cmap] if isinstance(cmap, str) else cmap).with_extremes(bad="0.85")
    coll = PatchCollection(rects, cmap=cm, edgecolor="0.3", linewidth=0.4)
    coll.set_array(np.ma.masked_invalid(np.asarray(values, float)))
    coll.set_clim(vmin, vmax)
    ax.add_collection(coll)
    ax.set_xlim(float(np.min(th - wd / 2)), float(np.max(th + wd / 2)))
    ax.set_ylim(float(np.max(xm + lm / 2)), float(np.min(xm - lm / 2)))   # proximal on top
    ax.set_xlabel("angle around the limb theta [deg]")
    ax.set_ylabel("axial position x [mm]")
    if labels is not None and len(labels) <= 48:
        for t, a, lab in zip(th, xm, labels):
            ax.text(t, a, lab, ha="center", va="center", fontsize=6, color="0.15")
    return coll


def layout_figure(x, theta, width, length, values, *, labels=None, title: str = "",
                  value_label: str = "largest normal force [N]") -> Figure:
    """One panel: the patches on the unrolled surface coloured by ``values``."""
    with figure_style():
        fig = Figure(figsize=(7.5, 4.8), layout="constrained")
        ax = fig.subplots()
        v = np.asarray(values, float)
        top = float(np.nanmax(v)) if np.isfinite(v).any() else 1.0
        coll = draw_unrolled(ax, x, theta, width, length, v, vmin=min(0.0, float(np.nanmin(v))
                             if np.isfinite(v).any() else 0.0), vmax=top if top > 0 else 1.0,
                             labels=labels)
        fig.colorbar(coll, ax=ax, pad=0.01).set_label(value_label)
        if title:
            ax.set_title(title, fontsize=9.5)
    return fig


def layout_compare_figure(x, theta, width, length, measured, simulated: dict, *, labels=None,
                          title: str = "", rmse: Optional[dict] = None) -> Figure:
    """``phri compare``'s figure for a free layout: zeroed loads measured | each arm on the
    unrolled surface, one colour scale symmetric about 0 shared by every panel."""
    panels = {"Measured": np.asarray(measured, float)}
    for arm, v in simulated.items():
        name = ARM_NAMES.get(arm, arm)
        extra = f" (RMSE {rmse[arm]:.2f} N)" if rmse and arm in rmse else ""
        panels[f"{name}{extra}"] = np.asarray(v, float)
    allv = np.concatenate([p[np.isfinite(p)] for p in panels.values()] or [np.zeros(1)])
    lim = float(np.max(np.abs(allv))) if allv.size else 1.0
    lim = lim if lim > 0 else 1.0
    with figure_style():
        fig = Figure(figsize=(4.2 * len(panels) + 1.2, 4.4), layout="constrained")
        axes = np.atleast_1d(fig.subplots(1, len(panels), sharey=True))
        coll = None
        for ax, (name, v) in zip(axes, panels.items()):
            coll = draw_unrolled(ax, x, theta, width, length, v, cmap="RdBu_r", vmin=-lim,
                                 vmax=lim, labels=labels)
            ax.set_title(name, fontsize=9)
        for ax in axes[1:]:
            ax.set_ylabel("")
        fig.colorbar(coll, ax=list(axes), pad=0.01).set_label("zeroed load [N]")
        if title:
            fig.suptitle(title, fontsize=9.5)
    return fig
