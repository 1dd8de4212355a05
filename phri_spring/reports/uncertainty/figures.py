"""Uncertainty bands of model predictions, as matplotlib ``Figure`` objects (never pyplot).

- :func:`bands_figure`  per condition: measured zeroed loads of every element (dots) and
  each arm model's median with its 5-95 % Monte Carlo band.
"""

from __future__ import annotations

from typing import Optional, Sequence

import numpy as np
from matplotlib.figure import Figure

from ..figure_base import ARM_COLORS, ARM_NAMES, figure_style

__all__ = ["bands_figure"]


def bands_figure(measured, bands: dict, *, conditions: Sequence[str], labels: Sequence[str],
                 baseline_index: Optional[int] = None, title: str = "") -> Figure:
    """Measured loads against the model's Monte Carlo bands, one panel per condition.

    Parameters
    ----------
    measured : array_like, shape (c, n)
        Zeroed measured loads [N] per condition and element.
    bands : dict of str -> array_like, shape (3, c, n)
        Per arm model, the 5th, 50th and 95th percentiles of the zeroed simulated loads [N].
    conditions : sequence of str
        Condition names (c).
    labels : sequence of str
        Element labels (n): the x axis.
    baseline_index : int, optional
        Condition left out (all zeros by construction).
    title : str

    Returns
    -------
    matplotlib.figure.Figure
        One axes per drawn condition; y label ``zeroed load [N]``.
    """
    meas = np.asarray(measured, dtype=float)
    keep = [i for i in range(len(conditions)) if i != baseline_index]
    n = len(labels)
    x = np.arange(n)
    with figure_style():
        fig = Figure(figsize=(max(6.0, 0.32 * n + 1.5), 1.9 * max(len(keep), 1) + 0.8),
                     layout="constrained")
        axes = fig.subplots(max(len(keep), 1), 1, squeeze=False)[:, 0]
        for ax, i in zip(axes, keep):
            for arm, P in bands.items():
                P = np.asarray(P, dtype=float)
                color = ARM_COLORS.get(arm, "0.4")
                ax.fill_between(x, P[0, i], P[2, i], color=color, alpha=0.25, lw=0,
                                step=None, label=f"{ARM_NAMES.get(arm, arm)} 5-95 %")
                ax.plot(x, P[1, i], "-", color=color, lw=1.2,
                        label=f"{ARM_NAMES.get(arm, arm)} median")
            ax.plot(x, meas[i], "o", color="black", ms=3.5, label="measured")
            ax.axhline(0.0, color="0.6", lw=0.6)
            ax.set_title(str(conditions[i]), fontsize=9, loc="left")
            ax.set_xticks(x, list(labels), fontsize=7)
            ax.set_ylabel("zeroed load [N]")
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize=7, ncol=3, loc="best")
        if title:
            fig.suptitle(title, fontsize=9.5)
    return fig
