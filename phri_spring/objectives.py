"""The objectives of ``phri design``: one table of name, unit, sense, description and function.

Every objective a study can minimise, maximise or constrain is one
:class:`Objective` record in :data:`OBJECTIVE_TABLE`. Everything else reads
this table: the study file's validation (:mod:`phri_spring.io.config.study`), the
evaluation of a design (:func:`phri_spring.workflows.design.objectives.evaluate_design`
loops over it), the footnote of ``report.md`` and the objectives table of
docs/design.md (:func:`objectives_markdown`; a test keeps the docs equal to it).
Adding an objective is adding one record here.

The functions reduce a :class:`SolvedLoadSet`: one design already solved over
the distinct rows of a load set, with the weight of each row, so every
reduction is a weighted maximum, percentile or fraction and merging identical
rows is exact. This module imports nothing from the rest of the package, so
any layer may read the table.

>>> [o.name for o in OBJECTIVE_TABLE][:2]
['peak_pressure_to_pain_threshold', 'peak_pressure_to_pain_threshold_p99']
>>> OBJECTIVE_BY_NAME["stiffness_translational_N_per_mm"].unit
'N/mm'
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Callable, Optional

import numpy as np

__all__ = ["Objective", "SolvedLoadSet", "OBJECTIVE_TABLE", "OBJECTIVE_BY_NAME", "OBJECTIVES",
           "objectives_markdown", "objectives_footnote", "weighted_percentile",
           "max_displacement_m"]

_P99 = 99.0


# --------------------------------------------------------------------------- solved load set
@dataclass
class SolvedLoadSet:
    """One design solved over the distinct rows of a load set.

    Attributes
    ----------
    pressure_kpa : ndarray, shape (k, n)
        Element pressure of each distinct row [kPa].
    contact : ndarray of bool, shape (k, n)
        The solver's contact set (a pressing coupled patch can report 0 N).
    u : ndarray, shape (k, 6)
        Cuff displacement (translation t [m], rotation w [rad]) of each row.
    points : ndarray, shape (n, 3)
        Element points of the cuff [m].
    weights : ndarray, shape (k,)
        How many samples each row stands for (sum = ``n_samples``).
    n_samples : int
    pain_threshold_kpa : float
    principal_stiffness : (ndarray, ndarray) or None
        Ascending principal values of the translational [N/m] and rotational
        [N*m/rad] blocks of the interface stiffness at the preloaded state,
        expressed at the load cell; None when they could not be computed.
    seconds : ndarray, shape (k,), or None
        Time each row stands for [s]: the sum of the steps ``t_n - t_(n-1)`` of its
        samples (docs/tolerance.md).
    tolerance : object or None
        The config's pressure-time curve: anything with ``rate(pressure_kpa)`` [1/s]
        (physics.tolerance.ToleranceCurve); None without one.
    """

    pressure_kpa: np.ndarray
    contact: np.ndarray
    u: np.ndarray
    points: np.ndarray
    weights: np.ndarray
    n_samples: int
    pain_threshold_kpa: float
    principal_stiffness: Optional[tuple] = None
    seconds: Optional[np.ndarray] = None
    tolerance: Optional[object] = None

    @cached_property
    def peak_ratio(self) -> np.ndarray:
        """(k,) each row's peak element pressure / pain threshold [-]."""
        return self.pressure_kpa.max(axis=1) / self.pain_threshold_kpa


@dataclass(frozen=True)
class Objective:
    """One objective of a design study.

    Attributes
    ----------
    name : str
        As in the study file and the columns of designs.csv.
    unit : str
        ``-`` when dimensionless.
    sense : {'min', 'max'}
        The direction a better cuff moves it (a study still says which
        objectives it minimises and which it maximises).
    description : str
        Its definition, one sentence (report.md and docs/design.md).
    compute : callable(SolvedLoadSet) -> float
    uses_loads : bool
        Depends on the solved load set: NaN when a sample did not converge.
        False for properties of the preloaded interface alone.
    needs_tolerance : bool
        Defined only with a tolerance curve in the config (``tolerance.curve``): no
        column without one.
    """

    name: str
    unit: str
    sense: str
    description: str
    compute: Callable[[SolvedLoadSet], float]
    uses_loads: bool = True
    needs_tolerance: bool = False


# --------------------------------------------------------------------------- reductions
def weighted_percentile(values, weights, q: float) -> float:
    """numpy's default (linear) percentile of ``values`` repeated ``weights`` times.

    Equal to ``np.percentile(np.repeat(values, weights), q)`` for integer
    weights, without building the repeated array; fractional weights
    interpolate the same way on the cumulative weights.
    """
    v = np.asarray(values, dtype=float)
    w = np.asarray(weights, dtype=float)
    if np.all(w == 1.0):
        return float(np.percentile(v, q))
    order = np.argsort(v, kind="stable")
    v, w = v[order], w[order]
    cum = np.cumsum(w)                      # rows 0 .. cum[i]-1 hold v[i]
    n = cum[-1]
    h = (n - 1) * q / 100.0
    lo = math.floor(h)
    frac = h - lo
    i_lo = int(np.searchsorted(cum, lo, side="right"))
    i_hi = int(np.searchsorted(cum, min(lo + 1, n - 1), side="right"))
    a, b = v[min(i_lo, len(v) - 1)], v[min(i_hi, len(v) - 1)]
    if frac == 0.0 or a == b:
        return float(a)
    # numpy's _lerp, including its choice of form for t >= 0.5
    return float(b - (b - a) * (1 - frac)) if frac >= 0.5 else float(a + (b - a) * frac)


def max_displacement_m(u: np.ndarray, points: np.ndarray) -> float:
    """max over samples and elements of ``|t + w x p_e|`` [m] (u = (t, w), shape (m, 6)).

    Exact: ``|t + w x p_e| <= |t| + |w| max_e |p_e|`` bounds every sample; only the
    samples whose bound reaches the largest exact value among the 64 highest
    bounds are evaluated element by element.
    """
    t, w = u[:, :3], u[:, 3:]
    rmax = float(np.max(np.linalg.norm(points, axis=1)))
    ub = np.sqrt(np.einsum("ij,ij->i", t, t)) + np.sqrt(np.einsum("ij,ij->i", w, w)) * rmax

    def exact(idx):
        d = t[idx, None, :] + np.cross(w[idx, None, :], points[None, :, :])
        return np.sqrt(np.einsum("ijk,ijk->ij", d, d)).max()

    top = np.argpartition(ub, -64)[-64:] if len(ub) > 64 else np.arange(len(ub))
    low = exact(top)
    cand = np.flatnonzero(ub >= low)
    best = low
    for s in range(0, len(cand), 65536):
        best = max(best, exact(cand[s:s + 65536]))
    return float(best)


def _peak_ratio(s: SolvedLoadSet) -> float:
    return float(s.peak_ratio.max())


def _peak_ratio_p99(s: SolvedLoadSet) -> float:
    return weighted_percentile(s.peak_ratio, s.weights, _P99)


def _lift_off_fraction(s: SolvedLoadSet) -> float:
    n = s.contact.shape[1]
    if len(s.weights) == s.n_samples:               # no merged rows: every weight is 1
        in_contact = float(np.count_nonzero(s.contact))
    else:
        in_contact = float(s.weights @ np.count_nonzero(s.contact, axis=1))
    return (s.n_samples * n - in_contact) / (s.n_samples * n)


def _stiffness_translational(s: SolvedLoadSet) -> float:
    if s.principal_stiffness is None:
        return math.nan
    return float(s.principal_stiffness[0][0]) / 1000.0


def _stiffness_rotational(s: SolvedLoadSet) -> float:
    if s.principal_stiffness is None:
        return math.nan
    return float(s.principal_stiffness[1][0]) * math.pi / 180.0


def _peak_cuff_displacement(s: SolvedLoadSet) -> float:
    return 1000.0 * max_displacement_m(s.u, s.points)


def _dose_max(s: SolvedLoadSet) -> float:
    if s.tolerance is None or s.seconds is None:
        return math.nan
    held = np.asarray(s.seconds, dtype=float)[:, None]
    with np.errstate(invalid="ignore"):     # inf * 0: a row that lasts no time adds nothing
        dose = np.where(held > 0, s.tolerance.rate(s.pressure_kpa) * held, 0.0)
    return float(dose.sum(axis=0).max())


# --------------------------------------------------------------------------- the table
_AT_LOADCELL = ("of the interface stiffness at the preloaded state (zero wrench), expressed at "
                "the load cell (docs/model.md, sections 4 and 5)")

#: every objective, in the order of designs.csv's columns after the study's own
OBJECTIVE_TABLE: tuple = (
    Objective("peak_pressure_to_pain_threshold", "-", "min",
              "max over samples of the per-sample peak element pressure / pain threshold: "
              "the maximum of the column of that name `phri simulate` writes",
              _peak_ratio),
    Objective("peak_pressure_to_pain_threshold_p99", "-", "min",
              "the 99th percentile over samples of the same column, numpy's default (linear) "
              "interpolation",
              _peak_ratio_p99),
    Objective("lift_off_fraction", "-", "min",
              "(samples x elements out of contact) / (samples x elements): a cuff that slips",
              _lift_off_fraction),
    Objective("stiffness_translational_N_per_mm", "N/mm", "max",
              "smallest eigenvalue of the force-per-translation block " + _AT_LOADCELL,
              _stiffness_translational, uses_loads=False),
    Objective("stiffness_rotational_Nm_per_deg", "N*m/deg", "max",
              "smallest eigenvalue of the moment-per-rotation block " + _AT_LOADCELL,
              _stiffness_rotational, uses_loads=False),
    Objective("peak_cuff_displacement_mm", "mm", "min",
              "max over samples of the largest displacement of an element point of the cuff, "
              "|t + w x p_e|",
              _peak_cuff_displacement),
    Objective("dose_max", "-", "min",
              "max over elements of the cumulative dose sum_n dt_n / t_allowed(p_e,n) against "
              "the config's tolerance.curve over the whole load set (1 = the curve's limit; "
              "docs/tolerance.md); only with a curve",
              _dose_max, needs_tolerance=True),
)

OBJECTIVE_BY_NAME: dict = {o.name: o for o in OBJECTIVE_TABLE}

#: the names, in the table's order (what a study may name)
OBJECTIVES: tuple = tuple(OBJECTIVE_BY_NAME)

_BETTER = {"min": "lower", "max": "higher"}


def objectives_markdown() -> str:
    """The objectives as a markdown table (the one in docs/design.md).

    >>> print(objectives_markdown().splitlines()[0])
    | objective | unit | better | definition |
    """
    lines = ["| objective | unit | better | definition |", "|---|---|---|---|"]
    for o in OBJECTIVE_TABLE:
        cell = o.description.replace("|", "\\|")     # a literal | inside a table cell
        lines.append(f"| `{o.name}` | {o.unit} | {_BETTER[o.sense]} | {cell} |")
    return "\n".join(lines)


def objectives_footnote() -> str:
    """One paragraph defining every objective, with its unit (the footnote of report.md)."""
    return "Objectives: " + "; ".join(f"{o.name} [{o.unit}] = {o.description}"
                                      for o in OBJECTIVE_TABLE) + "."


if __name__ == "__main__":   # python -m phri_spring.objectives: the table for docs/design.md
    print(objectives_markdown())
