"""The exposure figure of ``phri simulate --plot`` with a tolerance curve (docs/tolerance.md).

Every element's pressure against the total time it spent at or above that pressure
(log time axis), with the curve's limit drawn over it: where an element's line passes
above the curve, it was held at that pressure longer, in total, than the curve allows
for one continuous exposure. Only :class:`matplotlib.figure.Figure` is used.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from matplotlib.figure import Figure

__all__ = ["exposure_figure"]


def exposure_figure(edges_kpa, time_at_or_above_s, *, labels: Sequence[str], curve,
                    dose, pain_threshold_kpa: float, title: str = "",
                    highlight: int = 5) -> Figure:
    """Pressure [kPa] against cumulative time at or above it [s], one line per element.

    Parameters
    ----------
    edges_kpa : array_like, shape (b + 1,)
        Pressure bin edges [kPa], increasing.
    time_at_or_above_s : array_like, shape (n, b)
        Time each element spent at or above each bin's lower edge [s].
    labels : sequence of str, length n
    curve : physics.tolerance.ToleranceCurve
        Drawn as its limit against time.
    dose : array_like, shape (n,)
        Each element's dose [-]: the ``highlight`` largest are named in the legend.
    pain_threshold_kpa : float
        Drawn dashed.
    """
    from .figure_base import figure_style

    edges = np.asarray(edges_kpa, dtype=float)
    T = np.asarray(time_at_or_above_s, dtype=float)
    dose = np.asarray(dose, dtype=float)
    with figure_style():
        fig = Figure(figsize=(7.0, 4.6), layout="constrained")
        ax = fig.add_subplot(1, 1, 1)
        n = len(labels)
        cmap = __import__("matplotlib").colormaps["viridis"]
        # named: the largest doses, then (all doses equal) the highest pressures reached
        reached = np.array([edges[:-1][T[j] > 0].max(initial=0.0) for j in range(n)])
        order = np.lexsort((-reached, -np.nan_to_num(dose, nan=-1.0)))
        named = set(order[:highlight].tolist())
        t_max, t_min = 1.0, np.inf
        for j in range(n):
            keep = T[j] > 0
            if not keep.any():
                continue
            t_max = max(t_max, float(T[j][keep].max()))
            t_min = min(t_min, float(T[j][keep].min()))
            ax.plot(T[j][keep], edges[:-1][keep], color=cmap(j / max(n - 1, 1)),
                    lw=1.6 if j in named else 0.7, alpha=1.0 if j in named else 0.55,
                    label=f"{labels[j]} (dose {dose[j]:.3g})" if j in named else None)
        t0 = curve.times_s[0] if curve.times_s[0] > 0 else np.inf
        lo = max(1e-3, min(t_min, t0 / 10, 1.0) / 2)
        hi = max(t_max, curve.times_s[-1]) * 3.0
        tt = np.geomspace(lo, hi, 400)
        ax.plot(tt, curve.limit_kpa(tt), color="black", lw=2.2,
                label=f"{curve.name} ({curve.kind} limit)")
        data_top = max(float(reached.max(initial=0.0)), curve.limits_kpa[0])
        if pain_threshold_kpa <= 2 * data_top:     # else it would squash the rest
            ax.axhline(pain_threshold_kpa, color="#D55E00", ls="--", lw=1.0,
                       label=f"pain threshold {pain_threshold_kpa:g} kPa")
        ax.set_xscale("log")
        ax.set_xlim(lo, hi)
        top = max(data_top, pain_threshold_kpa if pain_threshold_kpa <= 2 * data_top
                  else 0.0) * 1.15
        ax.set_ylim(0.0, top)
        ax.set_xlabel("time at or above the pressure, summed over the log [s]")
        ax.set_ylabel("contact pressure [kPa]")
        ax.grid(True, which="both", alpha=0.25)
        ax.legend(loc="upper right", fontsize=7.5)
        ax.set_title(title or "Exposure of every element against the tolerance curve")
    return fig
