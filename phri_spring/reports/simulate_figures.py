"""Figure of ``phri simulate --plot``: a whole log at a glance, as a matplotlib ``Figure``.

Only :class:`matplotlib.figure.Figure` is used (never pyplot).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
from matplotlib.figure import Figure

__all__ = ["simulate_figure"]


def simulate_figure(pooled, *, labels: Sequence[str], pain_threshold_kpa: float,
                    title: str = "", max_columns: int = 1000, layout=None) -> Figure:
    """Peak pressure and element forces against time, max-pooled (no peak lost).

    Parameters
    ----------
    pooled : phri_spring.workflows.plots.maxpool.PooledLog
        The log, max-pooled into k groups of consecutive samples.
    labels : sequence of str, length n
        Element labels (A0 ... C6), the heat map's rows, top to bottom.
    pain_threshold_kpa : float
        Pressure pain threshold [kPa], drawn as a dashed line.
    title : str
        Figure title.
    max_columns : int
        Most columns of the heat map: groups are merged further (by the
        maximum) down to this, about the heat map's width in pixels, so that
        drawing does not drop a column.
    layout : tuple of 4 array_like (x [m], theta [rad], width [rad], length [m]), optional
        A free layout's patches (``cuff.patches``): a third axes draws them on the
        unrolled limb surface, each coloured by its largest force over the log.

    Returns
    -------
    matplotlib.figure.Figure
        Two axes sharing the time axis [s]: the largest peak pressure of each
        group [kPa] with the pain threshold; the largest force of each element
        in each group [N] as a heat map (elements down, time across) with its
        colour bar.
    """
    t0, t1 = pooled.time_start, pooled.time_end
    k = len(t0)
    forces = np.asarray(pooled.forces, dtype=float)
    g = max(1, -(-k // int(max_columns)))       # groups per heat-map column
    if g > 1:
        kk = -(-k // g)
        padded = np.full((kk * g, forces.shape[1]), np.nan)
        padded[:k] = forces
        forces = np.fmax.reduce(padded.reshape(kk, g, -1), axis=1)
    with _style():
        if layout is None:
            fig = Figure(figsize=(9.0, 6.2), layout="constrained")
            ax_p, ax_f = fig.subplots(2, 1, sharex=True, height_ratios=(1.0, 1.6))
        else:
            fig = Figure(figsize=(9.0, 10.4), layout="constrained")
            top, bottom = fig.subfigures(2, 1, height_ratios=(1.5, 1.0))
            ax_p, ax_f = top.subplots(2, 1, sharex=True, height_ratios=(1.0, 1.6))
            _unrolled_panel(bottom, layout, pooled.forces, labels)
        if k:
            # each group as a step spanning its samples: peaks keep their place in time
            edges = np.r_[t0, t1[-1]]
            ax_p.stairs(pooled.peak_pressure, edges, color="#0072B2", lw=1.0,
                        label="peak contact pressure (max per column)")
        ax_p.axhline(pain_threshold_kpa, color="#D55E00", ls="--", lw=1.2,
                     label=f"pain threshold {pain_threshold_kpa:g} kPa")
        if math.isfinite(pooled.peak_kpa):
            ax_p.plot([pooled.peak_time], [pooled.peak_kpa], "v", color="0.1", ms=6,
                      label=f"peak {pooled.peak_kpa:.1f} kPa at {pooled.peak_time:.2f} s")
        ax_p.set_ylabel("pressure [kPa]")
        ax_p.set_ylim(0, max(pain_threshold_kpa, np.nanmax(pooled.peak_pressure)
                             if np.isfinite(pooled.peak_pressure).any() else 0.0) * 1.1)
        ax_p.legend(loc="center right", frameon=False, fontsize=8)
        ax_p.grid(color="0.9", lw=0.6)
        for side in ("top", "right"):
            ax_p.spines[side].set_visible(False)

        n = len(labels)
        if k:
            vmax = float(np.nanmax(forces)) if np.isfinite(forces).any() else 1.0
            im = ax_f.imshow(forces.T, aspect="auto", interpolation="nearest", cmap="viridis",
                             vmin=0.0, vmax=vmax if vmax > 0 else 1.0,
                             extent=(t0[0], t1[-1] if t1[-1] > t0[0] else t0[0] + 1.0,
                                     n - 0.5, -0.5))
            cbar = fig.colorbar(im, ax=ax_f, pad=0.01, aspect=25)
            cbar.set_label("largest normal force in the column [N]")
        # a mat's hundreds of labels cannot all be read: every step-th one (grids unchanged)
        step = 1 if n <= 48 or layout is None else -(-n // 32)
        ax_f.set_yticks(np.arange(0, n, step), list(labels)[::step])
        ax_f.tick_params(axis="y", labelsize=7)
        ax_f.set_ylabel("element")
        ax_f.set_xlabel("time [s]")
        per = pooled.samples_per_group * g
        note = (f"{pooled.samples:,} samples; each heat-map column is the maximum over "
                f"{per:,} consecutive sample{'s' if per != 1 else ''}")
        fig.suptitle(f"{title}\n{note}" if title else note, fontsize=9.5)
    return fig


def _unrolled_panel(fig, layout, forces, labels) -> None:
    """The patches on the unrolled surface, coloured by each one's largest force."""
    from .layout_figures import draw_unrolled

    ax = fig.subplots()
    f = np.asarray(forces, dtype=float)
    peak = np.full(f.shape[1], np.nan)
    seen = np.isfinite(f).any(axis=0)
    peak[seen] = np.nanmax(f[:, seen], axis=0)
    top = float(np.nanmax(peak)) if seen.any() else 1.0
    coll = draw_unrolled(ax, *layout, peak, vmin=0.0, vmax=top if top > 0 else 1.0,
                         labels=labels)
    fig.colorbar(coll, ax=ax, pad=0.01).set_label("largest normal force over the log [N]")
    ax.set_title("patches on the unrolled limb surface", fontsize=9)


def _style():
    from .figure_base import figure_style as style

    return style()
