"""The one pipeline of ``simulate``, ``simulate --uncertainty`` and ``live``: load-cell
readings -> forces and the extra columns of the forces table.

Everything that turns readings into a row of the table lives here, once:

- the baseline (:func:`parse_baseline`, :func:`baseline_forces`): the forces
  subtracted by ``--baseline``; a model with a tissue history takes its rested
  answer (:meth:`~phri_spring.physics.history.model.HistoryModel.rested_forces`);
- the chunked solve (:func:`solve_chunk` -> :class:`SolvedChunk`): a chunk of cuff
  wrenches to forces, through ``model.solve_log`` for a model with a tissue history;
- the per-sample extra columns (:func:`per_sample_extras`, the shear and no-answer
  columns of :mod:`~phri_spring.workflows.columns`) and their Arrow column types
  (:func:`extra_arrow_types`, :data:`EXTRA_COLUMN_TYPES`).

A new extra column is added here (its name and type) and computed in
:meth:`SolvedChunk.extras` (docs/development.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Union

import numpy as np

from ..errors import ConvergenceError, UsageError
from ..io.config import Config, load_config
from ..physics.springs.model import SpringModel
from ..physics.contact.solver import FactorCache, solve
from .common import cuff_wrench
from .columns.band import BAND_COLUMN_TYPES, band_extras
from .columns.no_answer import NO_EQUILIBRIUM_COLUMN_TYPES, no_equilibrium_extras
from .columns.shear import shear_columns, shear_extras

__all__ = ["EXTRA_COLUMNS", "EXTRA_COLUMN_TYPES", "Baseline", "parse_baseline", "window_mask",
           "baseline_forces", "check_activation", "as_config", "per_sample_extras",
           "SolvedChunk", "solve_chunk", "ForcesRing", "extra_arrow_types"]

#: extra per-sample columns of the forces table, after the element labels, with their types
#: (docs/model.md section 7): counts, kPa, an element label, a ratio, a count, a flag
EXTRA_COLUMN_TYPES = (("contacts_in_touch", "int64"), ("peak_pressure_kPa", "float64"),
                      ("peak_pressure_element", "label"),
                      ("peak_pressure_to_pain_threshold", "float64"),
                      ("solver_iterations", "int64"), ("converged", "bool"))
EXTRA_COLUMNS = tuple(name for name, _ in EXTRA_COLUMN_TYPES)
#: values of the (samples x elements) pressures :func:`per_sample_extras` holds at a time
_PRESSURE_BLOCK_VALUES = 1 << 16


@dataclass(frozen=True)
class Baseline:
    """How forces are zeroed: ``none``, ``zero``, or the mean wrench over a time window.

    ``first`` uses [t_first, t_first + seconds]; ``window`` uses [t0, t1] (inclusive).
    """

    kind: str
    t0: float = 0.0
    t1: float = 0.0

    def __str__(self):
        if self.kind == "first":
            return f"first:{self.t1:g}"
        if self.kind == "window":
            return f"window:{self.t0:g}:{self.t1:g}"
        return self.kind


def parse_baseline(text: Union[str, Baseline, None]) -> Baseline:
    """Parse ``none | zero | first:SECONDS | window:T0:T1`` (docs/model.md section 8).

    Raises
    ------
    UsageError
        For anything else, or an empty or reversed window.
    """
    if text is None:
        return Baseline("none")
    if isinstance(text, Baseline):
        return text
    s = str(text).strip()
    parts = s.split(":")
    try:
        if parts == ["none"] or parts == ["zero"]:
            return Baseline(parts[0])
        if parts[0] == "first" and len(parts) == 2:
            sec = float(parts[1])
            if not (math.isfinite(sec) and sec > 0):
                raise UsageError(f"first:SECONDS needs SECONDS > 0, got {parts[1]!r}",
                                 key="--baseline")
            return Baseline("first", 0.0, sec)
        if parts[0] == "window" and len(parts) == 3:
            t0, t1 = float(parts[1]), float(parts[2])
            if not (math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
                raise UsageError(f"window:T0:T1 needs finite T0 < T1 [s], got {s!r}",
                                 key="--baseline")
            return Baseline("window", t0, t1)
    except UsageError:
        raise
    except ValueError:
        pass
    raise UsageError(f"expected none, zero, first:SECONDS or window:T0:T1, got {s!r}",
                     key="--baseline")


def per_sample_extras(model: SpringModel, absolute_forces, contact, iterations, converged):
    """The extra columns of the forces table, from absolute (un-zeroed) forces.

    The peak pressure [kPa] of a sample is its largest force over its element's
    area (``model.inv_area_kpa``), and its ratio to ``model.pain_threshold_kpa``
    [-]; both are NaN where the sample did not converge.

    Returns ``(extras, peak_index)``; ``extras["peak_pressure_element"]`` is
    ``(indices, labels)`` (dictionary-encoded).
    """
    forces = np.atleast_2d(absolute_forces)
    converged = np.asarray(converged, dtype=bool)
    m = len(forces)
    idx = np.empty(m, dtype=np.intp)
    peak = np.empty(m)
    # block by block: the pressures of a whole chunk would be a fresh chunk-sized array
    step = max(1, _PRESSURE_BLOCK_VALUES // max(1, forces.shape[1]))
    for lo in range(0, m, step):
        hi = min(m, lo + step)
        pressure = forces[lo:hi] * model.inv_area_kpa                               # kPa
        if not converged[lo:hi].all():  # NaN rows: keep argmax away from them
            pressure[np.isnan(pressure)] = -np.inf
        idx[lo:hi] = np.argmax(pressure, axis=1)
        peak[lo:hi] = pressure[np.arange(hi - lo), idx[lo:hi]]
    peak[~converged] = np.nan
    return {
        "contacts_in_touch": np.count_nonzero(contact, axis=1).astype(np.int64),
        "peak_pressure_kPa": peak,
        "peak_pressure_element": (idx, tuple(model.labels)),
        "peak_pressure_to_pain_threshold": peak / model.pain_threshold_kpa,
        "solver_iterations": np.asarray(iterations, dtype=np.int64),
        "converged": converged,
    }, idx


def window_mask(time: np.ndarray, baseline: Baseline, t_first: float) -> np.ndarray:
    """Which samples at ``time`` [s] fall in a ``first:`` or ``window:`` baseline's window
    (``t_first``: the log's first time [s])."""
    if baseline.kind == "first":
        return time <= t_first + baseline.t1
    return (time >= baseline.t0) & (time <= baseline.t1)


def baseline_forces(model: SpringModel, cfg: Config, baseline: Baseline, mean_wrench_lc,
                    max_iterations: int) -> Optional[np.ndarray]:
    """The forces (n,) [N] a baseline subtracts, or None for ``none``.

    ``mean_wrench_lc`` is the mean load-cell reading over the window (``first:`` and
    ``window:``); a model with a tissue history gives its rested answer.

    Raises
    ------
    ConvergenceError
        The solver found no answer at the baseline wrench.
    """
    if baseline.kind == "none":
        return None
    W = np.zeros(6) if baseline.kind == "zero" else cuff_wrench(cfg, mean_wrench_lc)
    if getattr(model, "has_history", False):   # the tissue rested long under W, relaxed
        f = model.rested_forces(W, max_iterations=max_iterations)
        if not np.isfinite(f).all():
            raise ConvergenceError(f"the solver did not converge at the baseline wrench "
                                   f"{W.tolist()}")
        return f
    sol = solve(model, W, max_iterations=max_iterations)
    if not sol.converged:
        raise ConvergenceError(f"the solver did not converge at the baseline wrench {W.tolist()}")
    return sol.forces


def check_activation(activation, m: int) -> np.ndarray:
    """An in-memory activation (m,) within 0..1, or a one-line UsageError."""
    a = np.asarray(activation, dtype=float)
    if a.shape != (m,) or not (np.isfinite(a).all() and (a >= 0).all() and (a <= 1).all()):
        raise UsageError(f"activation: expected {m} values from 0 to 1", key="activation")
    return a


def as_config(config) -> Config:
    """A loaded config as it is, or the config loaded from a path."""
    return config if isinstance(config, Config) else load_config(config)


class SolvedChunk:
    """One solved chunk: its solution, its (baseline-zeroed) forces and, on demand, its extras."""

    __slots__ = ("model", "solution", "forces", "shear", "_extras", "wrench")

    def __init__(self, model, solution, forces, shear: bool, wrench=None):
        self.model, self.solution, self.forces, self.shear = model, solution, forces, shear
        self._extras = None
        self.wrench = wrench      # the cuff wrenches solved (for the no-answer columns)

    def extras(self):
        """``(extras, peak_index)`` of :func:`per_sample_extras` (and the shear columns)."""
        if self._extras is None:
            sol = self.solution
            extras, idx = per_sample_extras(self.model, sol.forces, sol.contact, sol.iterations,
                                            sol.converged)
            if self.shear:
                extras.update(shear_extras(self.model, sol))
            if self.wrench is not None and self.model.friction_coefficient is not None:
                extras.update(no_equilibrium_extras(self.model, self.wrench, sol))
            extras.update(band_extras(self.model, sol))
            self._extras = extras, idx
        return self._extras


class ForcesRing:
    """``size`` arrays for the forces of consecutive chunks (n columns), used in turn: the
    array of a chunk is handed out again ``size`` chunks later, so it must no longer be
    read by then (``size``: one more than the chunks a writer may still hold)."""

    def __init__(self, size: int, n: int):
        self.n = int(n)
        self._flat = [np.empty(0) for _ in range(max(1, int(size)))]
        self._turn = 0

    def next(self, m: int) -> np.ndarray:
        """The next array, (m, n) float64, C-contiguous (its values are left over)."""
        i = self._turn
        self._turn = (i + 1) % len(self._flat)
        if self._flat[i].size < m * self.n:
            self._flat[i] = np.empty(m * self.n)
        return self._flat[i][:m * self.n].reshape(m, self.n)


def solve_chunk(model, W, f_base, max_iterations: int, cache: FactorCache,
                shear: bool = False, time=None, activation=None,
                out: Optional[np.ndarray] = None) -> SolvedChunk:
    """Solve cuff wrenches W (m, 6) and zero the forces by the baseline f_base (n,) or None.

    A model with a tissue history solves the samples in order at their times [s] and
    activations (0..1, None: 0), continuing from the chunk before. ``out``: an array
    (m, n) the solver may write the forces into (see :func:`~phri_spring.physics.contact.
    solver.solve`; the paths that do not take one ignore it)."""
    if getattr(model, "has_history", False):
        sol = model.solve_log(W, time, activation, max_iterations=max_iterations)
    else:
        sol = solve(model, W, max_iterations=max_iterations, cache=cache, out=out)
    forces = sol.forces if f_base is None else sol.forces - f_base
    return SolvedChunk(model, sol, forces, shear, W)


def extra_arrow_types(shear_labels=(), moments: bool = False, friction: bool = False,
                      tolerance: bool = False, band: bool = False) -> dict:
    """Column name -> Arrow type of the extra columns of a forces table: always
    :data:`EXTRA_COLUMN_TYPES`, then the shear columns of ``shear_labels`` (and the
    patch moments), the no-answer columns with friction, the dose with a tolerance curve."""
    import pyarrow as pa

    types = {"int64": pa.int64(), "float64": pa.float64(), "bool": pa.bool_(),
             "label": pa.dictionary(pa.int32(), pa.string())}
    out = {name: types[kind] for name, kind in EXTRA_COLUMN_TYPES}
    out.update({name: pa.float64() for name in shear_columns(shear_labels, moments)})
    if friction:   # why a sample has no answer (physics/no_equilibrium.py)
        out.update({name: types[kind] for name, kind in NO_EQUILIBRIUM_COLUMN_TYPES})
    if tolerance:  # the dose against a tolerance curve (docs/tolerance.md), loaded on demand
        from .columns.tolerance import TOLERANCE_COLUMN_TYPES

        out.update({name: types[kind] for name, kind in TOLERANCE_COLUMN_TYPES})
    if band:       # the elastic band strap's tension (docs/model.md section 3.1)
        out.update({name: types[kind] for name, kind in BAND_COLUMN_TYPES})
    return out
