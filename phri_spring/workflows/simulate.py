"""``phri simulate`` as library calls: wrench log -> contact force of every element.

- :func:`simulate` works on arrays in memory.
- :func:`simulate_file` streams a CSV/Parquet log to a CSV/Parquet output in
  chunks (bounded memory), writing atomically.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional, Union

import numpy as np

from ..errors import ConvergenceError, DataError, UsageError
from ..io.atomic import atomic_file, check_output_path
from ..io.config import Config, load_config
from ..io.logs import ForcesWriter, count_rows, iter_wrench_log, prefetch, table_format
from ..physics.model import SpringModel
from ..physics.solver import solve
from .common import cuff_wrench, model_from_config

__all__ = ["Baseline", "parse_baseline", "simulate", "simulate_file", "SimulationResult",
           "SimulateSummary", "EXTRA_COLUMNS", "per_sample_extras"]

#: extra per-sample columns of the forces table, after the element labels
EXTRA_COLUMNS = ("contacts_in_touch", "peak_pressure_kPa", "peak_pressure_element",
                 "peak_pressure_to_pain_threshold", "solver_iterations", "converged")


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
    """Parse ``none | zero | first:SECONDS | window:T0:T1`` (SPEC section 8).

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


@dataclass
class SimulationResult:
    """Per-sample outputs of :func:`simulate` (m samples, n elements)."""

    time: np.ndarray                 # (m,) [s]
    labels: tuple                    # element labels
    forces: np.ndarray               # (m, n) [N], zeroed by the baseline if one was given
    absolute_forces: np.ndarray      # (m, n) [N], preload included
    baseline_forces: Optional[np.ndarray]  # (n,) [N] subtracted, or None
    contact: np.ndarray              # (m, n) bool
    iterations: np.ndarray           # (m,)
    converged: np.ndarray            # (m,) bool
    peak_pressure_kpa: np.ndarray    # (m,) [kPa] from absolute forces
    peak_element: np.ndarray         # (m,) element index of the peak
    pain_ratio: np.ndarray           # (m,) peak pressure / pain threshold [-]
    extras: dict = field(default_factory=dict, repr=False)  # per_sample_extras' columns

    def to_frame(self):
        """A pandas DataFrame with the columns of the forces file."""
        import pandas as pd

        data = {"time": self.time}
        data.update({lab: self.forces[:, j] for j, lab in enumerate(self.labels)})
        for name, values in self.extras.items():
            if name == "peak_pressure_element":  # (indices, labels), dictionary-encoded
                idx, names = values
                values = np.asarray(names, dtype=object)[idx]
            data[name] = values
        return pd.DataFrame(data)


def per_sample_extras(model: SpringModel, absolute_forces, contact, iterations, converged):
    """The extra columns of the forces table, from absolute (un-zeroed) forces.

    Returns ``(extras, peak_index)``; ``extras["peak_pressure_element"]`` is
    ``(indices, labels)`` (dictionary-encoded).
    """
    inv_area_kpa = model._cache.get("__inv_area_kpa__")
    if inv_area_kpa is None:
        inv_area_kpa = model._cache["__inv_area_kpa__"] = 1.0 / (1000.0 * model.areas)
    pressure = absolute_forces * inv_area_kpa                                  # kPa
    converged = np.asarray(converged, dtype=bool)
    if not converged.all():  # NaN rows: keep argmax away from them
        pressure = np.where(np.isnan(pressure), -np.inf, pressure)
    idx = np.argmax(pressure, axis=1)
    peak = pressure[np.arange(len(idx)), idx]
    peak[~converged] = np.nan
    return {
        "contacts_in_touch": np.count_nonzero(contact, axis=1).astype(np.int64),
        "peak_pressure_kPa": peak,
        "peak_pressure_element": (idx, tuple(model.labels)),
        "peak_pressure_to_pain_threshold": peak / model.pain_threshold_kpa,
        "solver_iterations": np.asarray(iterations, dtype=np.int64),
        "converged": converged,
    }, idx


def _window_mask(time: np.ndarray, baseline: Baseline, t_first: float) -> np.ndarray:
    if baseline.kind == "first":
        return time <= t_first + baseline.t1
    return (time >= baseline.t0) & (time <= baseline.t1)


def _baseline_forces(model: SpringModel, cfg: Config, baseline: Baseline, mean_wrench_lc,
                     max_iterations: int) -> Optional[np.ndarray]:
    if baseline.kind == "none":
        return None
    W = np.zeros(6) if baseline.kind == "zero" else cuff_wrench(cfg, mean_wrench_lc)
    sol = solve(model, W, max_iterations=max_iterations)
    if not sol.converged:
        raise ConvergenceError(f"the solver did not converge at the baseline wrench {W.tolist()}")
    return sol.forces


def _as_config(config) -> Config:
    return config if isinstance(config, Config) else load_config(config)


def simulate(config, wrench_lc, *, time=None, arm: str = "compliant",
             baseline: Union[str, Baseline, None] = "none",
             model: Optional[SpringModel] = None) -> SimulationResult:
    """Contact forces for every sample of a wrench log held in memory.

    Parameters
    ----------
    config : Config or path
        A loaded config or the path of a YAML config.
    wrench_lc : array_like, shape (m, 6) or (6,)
        Load-cell readings (Fx, Fy, Fz, Mx, My, Mz) in the config's units
        (``load_cell.force_unit``, ``load_cell.moment_unit``).
    time : array_like, shape (m,), optional
        Sample times [s] (needed for ``first:`` and ``window:`` baselines).
    arm : {'compliant', 'rigid'}
    baseline : str or Baseline
        ``none`` (absolute forces, preload included), ``zero``, ``first:S`` or ``window:T0:T1``.
    model : SpringModel, optional
        A prebuilt model of this config and arm (saves rebuilding it).

    Returns
    -------
    SimulationResult
    """
    cfg = _as_config(config)
    base = parse_baseline(baseline)
    w = np.atleast_2d(np.asarray(wrench_lc, dtype=float))
    if w.ndim != 2 or w.shape[1] != 6:
        raise ValueError(f"wrench: expected shape (m, 6), got {np.shape(wrench_lc)}")
    m = len(w)
    t = np.arange(m, dtype=float) if time is None else np.asarray(time, dtype=float)
    if t.shape != (m,):
        raise ValueError(f"time: expected shape ({m},), got {t.shape}")
    if model is None:
        model = model_from_config(cfg, arm)
    mean_lc = None
    if base.kind in ("first", "window"):
        if time is None:
            raise UsageError("a first: or window: baseline needs sample times", key="--baseline")
        mask = _window_mask(t, base, float(t[0]))
        if not mask.any():
            raise DataError(f"no sample in the baseline window {base} "
                            f"(the log spans {t.min():g} to {t.max():g} s)", key="--baseline")
        mean_lc = w[mask].mean(axis=0)
    f_base = _baseline_forces(model, cfg, base, mean_lc, cfg.max_iterations)
    sol = solve(model, cuff_wrench(cfg, w), max_iterations=cfg.max_iterations)
    extras, idx = per_sample_extras(model, sol.forces, sol.contact, sol.iterations, sol.converged)
    forces = sol.forces if f_base is None else sol.forces - f_base
    return SimulationResult(time=t, labels=tuple(model.labels), forces=forces,
                            absolute_forces=sol.forces, baseline_forces=f_base,
                            contact=sol.contact, iterations=sol.iterations,
                            converged=sol.converged, peak_pressure_kpa=extras["peak_pressure_kPa"],
                            peak_element=idx,
                            pain_ratio=extras["peak_pressure_to_pain_threshold"], extras=extras)


@dataclass
class SimulateSummary:
    """What :func:`simulate_file` did."""

    output: Path
    samples: int
    not_converged: int
    max_peak_pressure_kpa: float
    max_peak_element: str
    max_pain_ratio: float
    max_iterations_used: int
    mean_iterations: float
    baseline_forces: Optional[np.ndarray]
    labels: tuple


def _window_mean(log, columns, base: Baseline, chunk_rows: int) -> np.ndarray:
    """Mean load-cell wrench over the baseline window (one streaming pass, stops early)."""
    total = np.zeros(6)
    count = 0
    t_first = None
    t_min, t_max = math.inf, -math.inf
    for ch in iter_wrench_log(log, columns, chunk_rows=chunk_rows):
        if t_first is None:
            t_first = float(ch.time[0])
        t_min, t_max = min(t_min, float(ch.time.min())), max(t_max, float(ch.time.max()))
        mask = _window_mask(ch.time, base, t_first)
        total += ch.wrench[mask].sum(axis=0)
        count += int(mask.sum())
        if base.kind == "first" and ch.time[-1] > t_first + base.t1 and \
                np.all(np.diff(ch.time) >= 0):
            break
    if count == 0:
        raise DataError(f"no sample in the baseline window {base} (the log spans "
                        f"{t_min:g} to {t_max:g} s)", file=log, key="--baseline")
    return total / count


def simulate_file(config, log, output, *, arm: str = "compliant",
                  baseline: Union[str, Baseline, None] = "none", columns: Optional[dict] = None,
                  chunk_rows: int = 65536, decimals: Optional[int] = 6,
                  progress: Optional[Callable[[int, Optional[int]], None]] = None,
                  on_chunk: Optional[Callable[[np.ndarray, np.ndarray, np.ndarray], None]] = None
                  ) -> SimulateSummary:
    """Stream a wrench log through the model into a forces file.

    Parameters
    ----------
    config : Config or path
    log : path
        Wrench log, CSV or Parquet (SPEC section 7).
    output : path
        Forces file; CSV or Parquet by its extension. Written to a temporary file
        beside it and renamed at the end: a failed run leaves nothing behind.
    arm, baseline
        See :func:`simulate`.
    columns : dict, optional
        Map from spec names to the log's column names; merged over ``load_cell.columns``.
    chunk_rows : int
        Samples per chunk (bounds memory).
    decimals : int or None
        CSV output only: decimals kept in forces and pressures (default 6, i.e.
        1 uN and 1 mPa); None or a negative value keeps every digit. Parquet
        always stores full double precision.
    progress : callable(done, total), optional
        Called after each chunk; ``total`` may be None.
    on_chunk : callable(time, forces, peak_pressure), optional
        Called in this thread once per chunk, in order, with time (m,) [s],
        absolute forces (m, n) [N] and peak pressure (m,) [kPa] (e.g. a
        :class:`phri_spring.workflows.plotting.MaxPool`).
    """
    output = Path(output)
    out_fmt = table_format(output, role="output", option="-o/--output")
    cfg = _as_config(config)
    check_output_path(output, [log, cfg.path, *cfg.stiffness_files], option="-o/--output")
    base = parse_baseline(baseline)
    colmap = dict(cfg.log_columns)
    colmap.update(columns or {})
    model = model_from_config(cfg, arm)

    mean_lc = _window_mean(log, colmap, base, chunk_rows) if base.kind in ("first", "window") \
        else None
    f_base = _baseline_forces(model, cfg, base, mean_lc, cfg.max_iterations)
    total = count_rows(log) if progress is not None else None

    # fine meshes: fewer rows per chunk, so a chunk's arrays stay about 32 MB
    rows = max(1024, min(int(chunk_rows), (1 << 22) // model.n))
    # (chunk, wrench on the cuff): the transform runs on the reader thread when there is one
    chunks = ((ch, cuff_wrench(cfg, ch.wrench))
              for ch in iter_wrench_log(log, colmap, chunk_rows=rows))
    if table_format(log) == "parquet":
        # Parquet is read ahead on a thread (measured: a few % faster), started now so
        # that the first row group is decoded while the writer opens; CSV parsing ahead
        # competes with the CSV writer's threads (measured: 11 % slower)
        chunks = prefetch(chunks)
    try:
        return _stream(cfg, model, chunks, output, out_fmt, f_base, decimals, progress, total,
                       on_chunk)
    finally:
        chunks.close()  # stops the reader thread (or the generator) on an early exit


def _stream(cfg, model, chunks, output, out_fmt, f_base, decimals, progress, total,
            on_chunk=None):
    n_samples = n_bad = 0
    it_max = 0
    it_sum = 0
    extra_types = _extra_arrow_types()
    with atomic_file(output) as tmp:
        with ForcesWriter(tmp, out_fmt, model.labels, extra_types,
                          decimals=decimals) as writer:
            peaks = {}  # chunk number -> (peak [kPa], element, pain ratio)

            def extras_of(number, sol):
                # runs on a writer thread, overlapping the solving of the next chunks;
                # chunks may finish out of order, so each keeps its own peak
                def compute():
                    extras, idx = per_sample_extras(model, sol.forces, sol.contact,
                                                    sol.iterations, sol.converged)
                    pp = extras["peak_pressure_kPa"]
                    if np.isfinite(pp).any():
                        j = int(np.nanargmax(pp))
                        peaks[number] = (float(pp[j]), model.labels[int(idx[j])],
                                         float(extras["peak_pressure_to_pain_threshold"][j]))
                    return extras
                return compute

            for number, (ch, W) in enumerate(chunks):
                sol = solve(model, W, max_iterations=cfg.max_iterations)
                forces = sol.forces if f_base is None else sol.forces - f_base
                writer.write(ch.time, forces, extras_of(number, sol))
                if on_chunk is not None:
                    ex, _ = per_sample_extras(model, sol.forces, sol.contact, sol.iterations,
                                              sol.converged)
                    on_chunk(ch.time, sol.forces, ex["peak_pressure_kPa"])
                n_samples += len(ch.time)
                n_bad += int((~sol.converged).sum())
                it_max = max(it_max, int(sol.iterations.max()))
                it_sum += int(sol.iterations.sum())
                if progress is not None:
                    progress(n_samples, total)
    # the first chunk holding the largest peak (as a sequential pass would find it)
    best = (-math.inf, "", -math.inf)
    for number in sorted(peaks):
        if peaks[number][0] > best[0]:
            best = peaks[number]
    return SimulateSummary(output=output, samples=n_samples, not_converged=n_bad,
                           max_peak_pressure_kpa=best[0], max_peak_element=best[1],
                           max_pain_ratio=best[2], max_iterations_used=it_max,
                           mean_iterations=it_sum / max(n_samples, 1), baseline_forces=f_base,
                           labels=tuple(model.labels))


def _extra_arrow_types() -> dict:
    import pyarrow as pa

    return {"contacts_in_touch": pa.int64(), "peak_pressure_kPa": pa.float64(),
            "peak_pressure_element": pa.dictionary(pa.int32(), pa.string()), "peak_pressure_to_pain_threshold": pa.float64(),
            "solver_iterations": pa.int64(), "converged": pa.bool_()}
