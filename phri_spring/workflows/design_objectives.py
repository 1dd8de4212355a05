"""Evaluating designs for ``phri design``: the load set, the objectives, Pareto sets.

Split out of :mod:`phri_spring.workflows.design` (which builds the designs, runs
a study and writes its outputs; every name here is re-exported there). The
objectives are those of :data:`~phri_spring.io.study.OBJECTIVES`, described in
that module's docstring; identical load-cell rows are merged into one weighted
row (exact), and an optional tolerance merges near-identical rows (approximate).
"""

from __future__ import annotations

import hashlib
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from ..errors import DataError
from ..io.config import Config
from ..io.logs import read_wrench_log
from ..io.study import OBJECTIVES
from ..physics.solver import solve
from ..physics.stiffness import interface_stiffness, principal_stiffness, stiffness_at_loadcell
from .common import cuff_wrench, model_from_config

__all__ = ["LoadSet", "load_set", "evaluate_batch", "evaluate_design", "pareto_mask",
           "weighted_percentile"]

_P99 = 99.0


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
    """

    wrench_lc: np.ndarray
    weights: np.ndarray
    n_samples: int
    files: tuple = ()
    tolerance: tuple = (0.0, 0.0)

    def digest(self) -> str:
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.wrench_lc).tobytes())
        h.update(np.ascontiguousarray(self.weights).tobytes())
        return h.hexdigest()


def _merge_rows(w: np.ndarray):
    """(distinct rows in first-occurrence order, counts) of an (m, 6) array."""
    view = np.ascontiguousarray(w).view(np.dtype((np.void, w.dtype.itemsize * w.shape[1])))
    _, first, counts = np.unique(view.ravel(), return_index=True, return_counts=True)
    order = np.argsort(first, kind="stable")
    return w[first[order]], counts[order].astype(float)


def load_set(files, columns: Optional[dict] = None, *, force_tol: float = 0.0,
             moment_tol: float = 0.0) -> LoadSet:
    """Read wrench logs and merge identical (or, with tolerances, near-identical) rows.

    Parameters
    ----------
    files : sequence of path
        Wrench logs (CSV or Parquet, docs/model.md section 7), in the config's units.
    columns : dict, optional
        Column map (the config's ``load_cell.columns``).
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
    parts = [read_wrench_log(f, columns)[1] for f in files]
    w = np.concatenate(parts) if len(parts) > 1 else parts[0]
    if len(w) == 0:
        raise DataError("the load set is empty; expected at least one sample", key="loads")
    if force_tol > 0 or moment_tol > 0:
        step = np.array([force_tol] * 3 + [moment_tol] * 3, dtype=float)
        snap = w.copy()
        on = step > 0
        snap[:, on] = np.round(w[:, on] / step[on]) * step[on]
        w = snap
    rows, counts = _merge_rows(np.asarray(w, dtype=float))
    return LoadSet(rows, counts, int(len(w)), files, (float(force_tol), float(moment_tol)))


# --------------------------------------------------------------------------- objectives
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


def _max_displacement_m(u: np.ndarray, points: np.ndarray) -> float:
    """max over samples and elements of |t + w x p_e| [m] (u = (t, w), shape (m, 6)).

    Exact: |t + w x p_e| <= |t| + |w| max_e |p_e| bounds every sample; only the
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


def evaluate_design(cfg: Config, loads: LoadSet, arm: str) -> dict:
    """Objectives of one design over a load set (see the module docstring).

    Returns
    -------
    dict
        Every name of :data:`OBJECTIVES` -> float, ``not_converged_samples`` -> int,
        ``element_peak_pressure_kPa`` -> (n,) max pressure of each element over samples.
    """
    model = model_from_config(cfg, arm)
    W = cuff_wrench(cfg, loads.wrench_lc)
    sol = solve(model, W, max_iterations=cfg.max_iterations)
    w = loads.weights
    n = model.n
    bad = ~np.asarray(sol.converged, dtype=bool)
    n_bad = int(w[bad].sum())
    inv_area_kpa = 1.0 / (1000.0 * model.areas)
    contact = sol.contact  # the solver's set: a pressing coupled patch can report 0 N
    pressure = np.multiply(sol.forces, inv_area_kpa, out=sol.forces)  # (k, n) kPa, in place
    out = {"not_converged_samples": n_bad}
    if n_bad:
        for name in OBJECTIVES:
            out[name] = math.nan
        out["element_peak_pressure_kPa"] = np.full(n, np.nan)
    else:
        peak = pressure.max(axis=1)
        ratio = peak / model.pain_threshold_kpa
        out["peak_pressure_to_pain_threshold"] = float(ratio.max())
        out["peak_pressure_to_pain_threshold_p99"] = weighted_percentile(ratio, w, _P99)
        if len(w) == loads.n_samples:               # no merged rows: every weight is 1
            in_contact = float(np.count_nonzero(contact))
        else:
            in_contact = float(w @ np.count_nonzero(contact, axis=1))
        out["lift_off_fraction"] = (loads.n_samples * n - in_contact) / (loads.n_samples * n)
        out["peak_cuff_displacement_mm"] = 1000.0 * _max_displacement_m(sol.u,
                                                                         model.geometry.points)
        out["element_peak_pressure_kPa"] = pressure.max(axis=0)
    try:
        K = interface_stiffness(model, max_iterations=cfg.max_iterations)
        Kt, Kr = principal_stiffness(stiffness_at_loadcell(K, cfg.loadcell_rotation,
                                                           cfg.loadcell_position))
        out["stiffness_translational_N_per_mm"] = float(Kt[0]) / 1000.0
        out["stiffness_rotational_Nm_per_deg"] = float(Kr[0]) * math.pi / 180.0
    except RuntimeError:
        out["stiffness_translational_N_per_mm"] = math.nan
        out["stiffness_rotational_Nm_per_deg"] = math.nan
    return out


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
