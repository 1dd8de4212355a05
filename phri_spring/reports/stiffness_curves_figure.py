"""Figure of ``phri stiffness --curves``: the cuff's force-displacement curves at the load cell.

Six panels: the force along each load-cell axis against the translation of the
load-cell point [N vs mm] (top row) and the moment about each axis against the
rotation [N*m vs deg] (bottom row), one curve per arm model given, with the
tangent at zero load and, where the package cites one for the axis's direction on
the arm, the range of linear stiffness measured on people (Schiebl et al. 2025,
Sensors 25(15):4605) drawn as a band of slopes through the origin. Only
:class:`matplotlib.figure.Figure` is used, never pyplot.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from .figure_base import ARM_COLORS, ARM_NAMES, figure_style

__all__ = ["stiffness_curves_figure"]

#: colours of arm models the house palette does not name (Okabe-Ito)
_OTHER_COLORS = ("#CC79A7", "#D55E00", "#56B4E9", "#000000")
_BAND = "0.80"
_ZERO = "0.35"


def _arm_color(arm: str, k: int) -> str:
    return ARM_COLORS.get(arm, _OTHER_COLORS[k % len(_OTHER_COLORS)])


def _branches(curves, i: int):
    """Displacement [mm or deg] and load of axis ``i`` from -max to +max (one line)."""
    d = curves.displacement_people()[i]
    s = curves.load[i]
    # branch 1 (-e_i) reversed, then branch 0 (+e_i) without its repeated zero
    return np.r_[d[1, ::-1], d[0, 1:]], np.r_[s[1, ::-1], s[0, 1:]]


def _limits(values, pad: float = 0.06):
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    top = float(np.max(np.abs(v))) if v.size else 1.0
    top = top if top > 0 else 1.0
    return -top * (1 + pad), top * (1 + pad)


def _where(direction: str, rotation: bool) -> str:
    """A panel's direction for its title: the moments are about the axis, not along it."""
    if not rotation:
        return direction
    return {"along the arm": "about the arm's axis",
            "across the arm": "about an axis across the arm"}.get(direction, direction)


def stiffness_curves_figure(curves, *, title: str | None = None) -> Figure:
    """The force-displacement curves of one or more arm models, with the human data.

    Parameters
    ----------
    curves : StiffnessCurves or sequence of them
        :class:`phri_spring.workflows.stiffness.curves.StiffnessCurves` of one config
        (e.g. one per arm model); the axis directions and human ranges are the first's.
    title : str, optional
        Figure title; default: the config's name and the loads.

    Returns
    -------
    matplotlib.figure.Figure
        2 x 3 axes: Fx, Fy, Fz [N] against the translation of the load-cell point
        along x, y, z [mm]; Mx, My, Mz [N*m] against the rotation about x, y, z [deg].
        Per model a solid curve (gaps where the solver did not converge) and its
        tangent at zero load, 1 / (K^-1)_ii (dotted); a grey band of the measured human
        stiffness range where cited. The axes span the models' curves.
    """
    sets = [curves] if hasattr(curves, "load") else list(curves)
    if not sets:
        raise ValueError("curves: expected at least one set of curves")
    first = sets[0]
    with figure_style():
        fig = Figure(figsize=(10.0, 6.4), layout="constrained")
        axs = fig.subplots(2, 3)
        handles = {}
        for i, ax in enumerate(axs.ravel()):
            du, lu = first.displacement_units[i], first.load_units[i]
            xs, ys = [], []
            for k, c in enumerate(sets):
                x, y = _branches(c, i)
                color = _arm_color(c.arm, k)
                name = ARM_NAMES.get(c.arm, c.arm)
                (line,) = ax.plot(x, y, color=color, lw=1.8, zorder=3)
                handles.setdefault(name, line)
                xs.append(x)
                ys.append(y)
            xlim, ylim = _limits(np.concatenate(xs)), _limits(np.concatenate(ys))
            xx = np.array(xlim)
            for k, c in enumerate(sets):
                slope = c.slope_at_zero_people[i]
                (tan,) = ax.plot(xx, slope * xx, color=_arm_color(c.arm, k), lw=0.9, ls=":",
                                 zorder=2)
                handles.setdefault("tangent at zero load, 1/(K$^{-1}$)$_{ii}$", tan)
            ref = first.references[i]
            notes = [(f"{ARM_NAMES.get(c.arm, c.arm)} {c.slope_at_zero_people[i]:.3g}",
                      _arm_color(c.arm, k)) for k, c in enumerate(sets)]
            if ref is not None:
                xf = np.linspace(*xlim, 3)
                band = ax.fill_between(xf, ref.low * xf, ref.high * xf, color=_BAND, lw=0,
                                       zorder=1)
                handles.setdefault(f"human interfaces, linear fits ({ref.source})", band)
                notes.append((f"human {ref.low:g}-{ref.high:g}", "0.3"))
            notes.insert(0, (f"slope at 0 [{lu}/{du}]", "0.1"))
            # lower right, bottom up: a curve through the origin with a positive slope
            # never goes there
            for row, (text, color) in enumerate(reversed(notes)):
                ax.annotate(text, (0.98, 0.03), xycoords="axes fraction",
                            xytext=(0, 10.5 * row), textcoords="offset points", ha="right",
                            va="bottom", fontsize=7.5, color=color)
            ax.axhline(0.0, color=_ZERO, lw=0.5, zorder=1.5)
            ax.axvline(0.0, color=_ZERO, lw=0.5, zorder=1.5)
            ax.set_xlim(xlim)
            ax.set_ylim(ylim)
            kind = "rotation about" if i >= 3 else "translation along"
            ax.set_xlabel(f"{kind} {first.axes[i].lstrip('r')} [{du}]")
            ax.set_ylabel(f"{first.loads[i]} [{lu}]")
            ax.set_title(f"{first.loads[i]}, {_where(first.directions[i], i >= 3)}")
            ax.grid(color="0.92", lw=0.6)
            for side in ("top", "right"):
                ax.spines[side].set_visible(False)
        fig.legend(list(handles.values()), list(handles.keys()), loc="outside lower center",
                   ncols=min(4, len(handles)), frameon=False)
        if title is None:
            failed = sum(c.failed for c in sets)
            title = (f"{first.name or 'cuff'}\nforce along and moment about each load-cell axis, "
                     f"up to {first.max_force:g} N and {first.max_moment:g} N*m, at the load cell")
            if failed:
                title += f"\n{failed} samples did not converge (gaps)"
        fig.suptitle(title)
    return fig
