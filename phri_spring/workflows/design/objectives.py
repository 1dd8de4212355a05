"""Evaluating designs for ``phri design``: the load set, the objectives, Pareto sets.

Every name here is re-exported by :mod:`phri_spring.workflows.design.study`. The
objectives are the records of :data:`phri_spring.objectives.OBJECTIVE_TABLE`
(name, unit, sense, definition and the function reducing a solved load set):
:func:`evaluate_design` solves a design once and loops over that table.
Identical load-cell rows are merged into one weighted row (exact: every
objective is a weighted maximum, percentile or fraction), and an optional
tolerance merges near-identical rows (approximate).
"""

from __future__ import annotations

import hashlib
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from ...errors import DataError
from ...io.config import Config
from ...io.logs import read_wrench_log
from ...objectives import OBJECTIVE_TABLE, OBJECTIVES, SolvedLoadSet, weighted_percentile
from ...physics.contact.solver import solve
from ...physics.response.stiffness import interface_stiffness, principal_stiffness, stiffness_at_loadcell
from ..common import cuff_wrench, model_from_config

__all__ = ["LoadSet", "load_set", "evaluate_batch", "evaluate_design", "pareto_mask",
           "weighted_percentile"]


# --------------------------------------------------------------------------- load set
@dataclass
class LoadSet:
    """The distinct load-cell rows of a study's logs, with how often each occurs.

    Attributes
    ----------
    wrench_lc : ndarray, shape (k, 6)
        Distinct rows, in the order of their first occurrence [log units].
    weights : ndarray, shape (k,)
        How many samples each row stands for (sum = ``n_samples``).
    n_samples : int
        Samples in the logs.
    files : tuple of Path
    tolerance : tuple of float
        (force [N], moment [N*m]) merge tolerance; (0, 0) for exact merging.
    seconds : ndarray, shape (k,), or None
        Time each row stands for [s]: the sum of its samples' steps t_n - t_(n-1) (0 for
        the first sample of each log and for steps backwards), for the dose objective.
    """

    wrench_lc: np.ndarray
    weights: np.ndarray
    n_samples: int
    files: tuple = ()
    tolerance: tuple = (0.0, 0.0)
    seconds: Optional[np.ndarray] = None

    def digest(self) -> str:
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.wrench_lc).tobytes())
        h.update(np.ascontiguousarray(self.weights).tobytes())
        return h.hexdigest()


def _merge_rows(w: np.ndarray, dt: Optional[np.ndarray] = None):
    """(distinct rows in first-occurrence order, counts, summed dt or None) of an (m, 6)
    array and its samples' steps (m,)."""
    view = np.ascontiguousarray(w).view(np.dtype((np.void, w.dtype.itemsize * w.shape[1])))
    _, first, inverse, counts = np.unique(view.ravel(), return_index=True,
                                          return_inverse=True, return_counts=True)
    order = np.argsort(first, kind="stable")
    seconds = None if dt is None else \
        np.bincount(inverse.ravel(), weights=dt, minlength=len(first))[order]
    return w[first[order]], counts[order].astype(float), seconds


def _steps(t: np.ndarray) -> np.ndarray:
    """Each sample's step t_n - t_(n-1) [s] of one log: 0 first, 0 backwards or NaN."""
    dt = np.zeros(len(t))
    dt[1:] = np.diff(np.asarray(t, dtype=float))
    return np.where(dt > 0, dt, 0.0)


def load_set(files, columns: Optional[dict] = None, *, force_tol: float = 0.0,
             moment_tol: float = 0.0, group: Optional[str] = None) -> LoadSet:
    """Read wrench logs and merge identical (or, with tolerances, near-identical) rows.

    Parameters
    ----------
    files : sequence of path
        Wrench logs (CSV or Parquet, docs/model.md section 7), in the config's units.
    columns : dict, optional
        Column map (the config's ``load_cell.columns``).
    group : str, optional
        TDMS group or MAT struct of lab-file logs (the config's ``load_cell.group``).
    force_tol, moment_tol : float
        0 (default): merge identical rows only (exact). Otherwise rows are
        snapped to a grid of this spacing [N], [N*m] (in the log's units) and
        rows in the same cell merged: each component moves by at most half
        the spacing.

    Raises
    ------
    DataError
        A log cannot be read, or the load set is empty.
    """
    files = tuple(Path(f) for f in files)
    if not files:
        raise DataError("expected at least one wrench log", key="loads")
    logs = [read_wrench_log(f, columns, group=group) for f in files]
    parts = [w for _, w in logs]
    dt = np.concatenate([_steps(t) for t, _ in logs])
    w = np.concatenate(parts) if len(parts) > 1 else parts[0]
    if len(w) == 0:
        raise DataError("the load set is empty; expected at least one sample", key="loads")
    if force_tol > 0 or moment_tol > 0:
        step = np.array([force_tol] * 3 + [moment_tol] * 3, dtype=float)
        snap = w.copy()
        on = step > 0
        snap[:, on] = np.round(w[:, on] / step[on]) * step[on]
        w = snap
    rows, counts, seconds = _merge_rows(np.asarray(w, dtype=float), dt)
    return LoadSet(rows, counts, int(len(w)), files, (float(force_tol), float(moment_tol)),
                   seconds)


# --------------------------------------------------------------------------- objectives
def evaluate_design(cfg: Config, loads: LoadSet, arm: str) -> dict:
    """Objectives of one design over a load set: every record of :data:`OBJECTIVE_TABLE`.

    The design is solved over the load set once; each objective then reduces
    the solved set. With samples the solver did not converge on, the
    objectives that use the loads are NaN.

    Returns
    -------
    dict
        ``not_converged_samples`` -> int, every objective's name -> float,
        ``element_peak_pressure_kPa`` -> (n,) max pressure of each element over samples.
    """
    model = model_from_config(cfg, arm)
    W = cuff_wrench(cfg, loads.wrench_lc)
    sol = solve(model, W, max_iterations=cfg.max_iterations)
    w = loads.weights
    bad = ~np.asarray(sol.converged, dtype=bool)
    n_bad = int(w[bad].sum())
    pressure = np.multiply(sol.forces, model.inv_area_kpa, out=sol.forces)  # (k, n) kPa, in place
    solved = SolvedLoadSet(pressure, sol.contact, sol.u, model.geometry.points, w,
                           loads.n_samples, model.pain_threshold_kpa,
                           _principal_stiffness(model, cfg), loads.seconds, cfg.tolerance)
    out = {"not_converged_samples": n_bad}
    for obj in OBJECTIVE_TABLE:
        if obj.needs_tolerance and cfg.tolerance is None:
            continue       # no curve, no column (docs/tolerance.md)
        out[obj.name] = math.nan if n_bad and obj.uses_loads else obj.compute(solved)
    out["element_peak_pressure_kPa"] = np.full(model.n, np.nan) if n_bad else \
        pressure.max(axis=0)
    return out


def _principal_stiffness(model, cfg: Config) -> Optional[tuple]:
    """(translational [N/m], rotational [N*m/rad]) ascending principal stiffness at the
    load cell at the preloaded state, or None when the preload does not converge."""
    try:
        K = interface_stiffness(model, max_iterations=cfg.max_iterations)
        return principal_stiffness(stiffness_at_loadcell(K, cfg.loadcell_rotation,
                                                         cfg.loadcell_position))
    except RuntimeError:
        return None


def evaluate_batch(batch, shared) -> dict:
    """Evaluate a batch of designs over the shared load set (runs in a worker).

    Parameters
    ----------
    batch : list of (int, Config)
        Design ids and their configs.
    shared : (LoadSet, str)
        The load set and the arm model.

    Returns
    -------
    dict
        ``design`` (b,) ids, each objective (b,), ``not_converged_samples`` (b,),
        ``element_peak_pressure_kPa`` (b, n), ``seconds`` the compute time [s].
    """
    t0 = time.perf_counter()
    loads, arm = shared
    rows = [evaluate_design(cfg, loads, arm) for _, cfg in batch]
    out = {"design": np.array([i for i, _ in batch], dtype=np.int64)}
    for name in OBJECTIVES:
        if all(name in r for r in rows):
            out[name] = np.array([r[name] for r in rows], dtype=float)
    out["not_converged_samples"] = np.array([r["not_converged_samples"] for r in rows],
                                            dtype=np.int64)
    out["element_peak_pressure_kPa"] = np.array([r["element_peak_pressure_kPa"]
                                                 for r in rows], dtype=float)
    out["seconds"] = np.array(time.perf_counter() - t0)
    return out


# --------------------------------------------------------------------------- Pareto
def pareto_mask(F, feasible=None) -> np.ndarray:
    """Non-dominated rows among the feasible ones (every column minimised).

    Row a dominates row b when a <= b in every column and a < b in at least one.
    Rows with a NaN and infeasible rows are never in the set (and dominate nothing).

    Parameters
    ----------
    F : array_like, shape (d, k)
        Objective values, each to be minimised (negate a maximised one).
    feasible : array_like of bool, shape (d,), optional

    Returns
    -------
    ndarray of bool, shape (d,)
    """
    F = np.asarray(F, dtype=float)
    if F.ndim == 1:
        F = F[:, None]
    d = len(F)
    ok = np.all(np.isfinite(F), axis=1)
    if feasible is not None:
        ok &= np.asarray(feasible, dtype=bool)
    idx = np.flatnonzero(ok)
    G = F[idx]
    keep = np.ones(len(idx), dtype=bool)
    step = max(1, (1 << 22) // max(len(idx) * F.shape[1], 1))
    for s in range(0, len(idx), step):
        b = G[s:s + step]                                    # candidates (c, k)
        le = np.all(G[None, :, :] <= b[:, None, :], axis=2)  # (c, d): row j <= candidate
        lt = np.any(G[None, :, :] < b[:, None, :], axis=2)
        keep[s:s + step] = ~np.any(le & lt, axis=1)
    out = np.zeros(d, dtype=bool)
    out[idx[keep]] = True
    return out
