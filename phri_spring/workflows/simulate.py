"""``phri simulate`` as library calls: wrench log -> contact force of every element.

One pipeline: a log is solved chunk by chunk (:func:`_solve_chunk`, the only
place that turns a chunk of load-cell readings into forces and the extra
columns, :func:`per_sample_extras` the only one that turns forces into peak
pressure and its ratio to the pain threshold); :func:`simulate` is that
applied once to arrays in memory, and :func:`simulate_file` applies it to every
chunk of a log, hands each chunk to a writer (bounded memory, written
atomically) and adds the summary up in a :class:`SummaryAccumulator`. What a
streamed run over a log needs before solving (the config, the output checks,
the column map and group, the baseline, the chunked reader, the writer) is a
:class:`LogRun` (:func:`open_log_run`), which ``simulate --uncertainty``
(:mod:`phri_spring.workflows.uncertainty.run`) shares.
"""

from __future__ import annotations

import dataclasses

import math
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional, Union

import numpy as np

from ..errors import ConvergenceError, DataError, UsageError
from ..io.outputs.atomic import atomic_file, check_output_path
from ..io.config import Config, load_config
from ..io.logs.columns import LOG_COLUMNS, OPTIONAL_LOG_COLUMNS
from ..io.config.tolerance import curve_option
from ..io.logs import (ForcesWriter, count_rows, iter_wrench_log, prefetch, reader_options,
                       table_format)
from ..physics.contact.load_path import ChunkedShares
from ..physics.springs.model import SpringModel
from ..physics.contact.no_equilibrium import arm_radius
from ..physics.contact.solver import FactorCache, solve
from .common import cuff_wrench, history_model, model_from_config
from ..io.memory.budget import plan_stream
from .plots.maxpool import MaxPool
from .columns.band import BAND_COLUMN_TYPES, band_extras, has_band, largest_tension
from .columns.no_answer import NO_EQUILIBRIUM_COLUMN_TYPES, NoAnswerTally, no_equilibrium_extras
from .columns.shear import element_loads, has_patch_moments, shear_columns, shear_extras
from .columns.tolerance import (TOLERANCE_COLUMN_TYPES, ExposureTally, exposure_table_path,
                               write_exposure_table)

__all__ = ["Baseline", "parse_baseline", "simulate", "simulate_file", "SimulationResult",
           "SimulateSummary", "SummaryAccumulator", "EXTRA_COLUMNS", "EXTRA_COLUMN_TYPES",
           "shear_columns", "per_sample_extras", "LogRun", "open_log_run", "element_loads"]

#: extra per-sample columns of the forces table, after the element labels, with their types
#: (docs/model.md section 7): counts, kPa, an element label, a ratio, a count, a flag
EXTRA_COLUMN_TYPES = (("contacts_in_touch", "int64"), ("peak_pressure_kPa", "float64"),
                      ("peak_pressure_element", "label"),
                      ("peak_pressure_to_pain_threshold", "float64"),
                      ("solver_iterations", "int64"), ("converged", "bool"))
EXTRA_COLUMNS = tuple(name for name, _ in EXTRA_COLUMN_TYPES)


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
            if isinstance(values, tuple):  # (indices, labels), dictionary-encoded
                idx, names = values
                values = np.asarray(names, dtype=object)[idx]
            data[name] = values
        return pd.DataFrame(data)


def per_sample_extras(model: SpringModel, absolute_forces, contact, iterations, converged):
    """The extra columns of the forces table, from absolute (un-zeroed) forces.

    The peak pressure [kPa] of a sample is its largest force over its element's
    area (``model.inv_area_kpa``), and its ratio to ``model.pain_threshold_kpa``
    [-]; both are NaN where the sample did not converge.

    Returns ``(extras, peak_index)``; ``extras["peak_pressure_element"]`` is
    ``(indices, labels)`` (dictionary-encoded).
    """
    pressure = absolute_forces * model.inv_area_kpa                                 # kPa
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


def _as_config(config) -> Config:
    return config if isinstance(config, Config) else load_config(config)


def simulate(config, wrench_lc, *, time=None, arm: str = "compliant",
             baseline: Union[str, Baseline, None] = "none",
             model=None, shear: bool = False, activation=None,
             tolerance=None) -> SimulationResult:
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
    arm : {'compliant', 'rigid', 'coupled'}
        See :func:`~phri_spring.workflows.common.model_from_config`.
    baseline : str or Baseline
        ``none`` (absolute forces, preload included), ``zero``, ``first:S`` or ``window:T0:T1``.
    model : SpringModel or CoupledModel, optional
        A prebuilt model of this config and arm (saves rebuilding it).
    shear : bool
        Add the tangential (shear) force on the arm of every element to ``extras``:
        ``{label}_shear_axial_N`` and ``{label}_shear_circumferential_N`` [N].
    tolerance : ToleranceCurve or str, optional
        Add ``dose_max`` and ``dose_element`` to ``extras`` (docs/tolerance.md).

    Returns
    -------
    SimulationResult

    Examples
    --------
    The bundled Harmony config (path relative to the repository root) under a
    33.4 N load along the load cell's z axis, the paper's second load level:

    >>> import numpy as np
    >>> res = simulate("configs/harmony_upper_arm.yaml", np.array([[0, 0, 33.4, 0, 0, 0]]))
    >>> res.forces.shape, bool(res.converged[0])
    ((1, 21), True)
    >>> res.labels[int(res.peak_element[0])]                  # where the pressure peaks
    'A4'
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
    if activation is not None:
        activation = check_activation(activation, m)
        model = history_model(model, cfg)
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
    ch = _solve_chunk(model, cuff_wrench(cfg, w), f_base, cfg.max_iterations, FactorCache(),
                      shear, t, activation)
    extras, idx = ch.extras()
    sol = ch.solution
    if tolerance is not None:
        extras.update(ExposureTally(model, tolerance).add(t, sol.forces))
    return SimulationResult(time=t, labels=tuple(model.labels), forces=ch.forces,
                            absolute_forces=sol.forces, baseline_forces=f_base,
                            contact=sol.contact, iterations=sol.iterations,
                            converged=sol.converged, peak_pressure_kpa=extras["peak_pressure_kPa"],
                            peak_element=idx,
                            pain_ratio=extras["peak_pressure_to_pain_threshold"], extras=extras)


class _Chunk:
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


def _solve_chunk(model, W, f_base, max_iterations: int, cache: FactorCache,
                 shear: bool = False, time=None, activation=None) -> _Chunk:
    """Solve cuff wrenches W (m, 6) and zero the forces by the baseline f_base (n,) or None.

    A model with a tissue history solves the samples in order at their times [s] and
    activations (0..1, None: 0), continuing from the chunk before."""
    if getattr(model, "has_history", False):
        sol = model.solve_log(W, time, activation, max_iterations=max_iterations)
    else:
        sol = solve(model, W, max_iterations=max_iterations, cache=cache)
    forces = sol.forces if f_base is None else sol.forces - f_base
    return _Chunk(model, sol, forces, shear, W)


@dataclass
class SimulateSummary:
    """What :func:`simulate_file` did."""

    output: Path
    samples: int
    not_converged: int
    max_peak_pressure_kpa: float
    max_peak_element: str
    max_pain_ratio: float
    max_peak_time: float             # [s] time of the (first) largest peak
    max_iterations_used: int
    mean_iterations: float
    baseline_forces: Optional[np.ndarray]
    labels: tuple
    #: the tissue law the model ran (``linear``, ``exponential``, ...; "" for no tissue)
    tissue_law: str = ""
    #: shares of the force passed to the skin (magnitudes summed over elements and samples)
    #: by the normal forces in contact, the tangential forces in contact and the lifted
    #: elements' bonded springs, each in [0, 1], adding up to one (docs/model.md section
    #: 12.4) [-]; NaN when nothing was passed
    load_shares: tuple = (math.nan, math.nan, math.nan)
    #: interface.friction_coefficient of the run (None: bonded)
    friction_coefficient: Optional[float] = None
    #: with friction: samples without an answer by reason (docs/model.md section 12.7)
    no_answer_reasons: dict = field(default_factory=dict)
    #: with friction: the worst sample without an answer, (reason, time [s], shortfall,
    #: its unit "N" or "N*m"; NaN and "" when not converged), or None
    worst_no_answer: Optional[tuple] = None
    #: with a tolerance curve: every element's exposure (physics.tolerance.Exposure) and
    #: the per-element table written (docs/tolerance.md); None without
    exposure: Optional[object] = None
    exposure_table: Optional[Path] = None
    #: with strap.model: band, the largest band tension of the run [N]; None otherwise
    max_strap_tension_n: Optional[float] = None


@dataclass(frozen=True)
class LogRun:
    """A wrench log streamed into a table, set up and checked before anything is solved.

    Made by :func:`open_log_run`; ``simulate`` and ``simulate --uncertainty``
    read and write through it.

    Attributes
    ----------
    cfg : Config
    log : path
        The wrench log (CSV, Parquet, TDMS or MAT).
    output : Path
        The table to write (CSV or Parquet by its extension).
    out_fmt : str
        ``'csv'`` or ``'parquet'``.
    columns : dict
        Spec name -> the log's column name: ``load_cell.columns``, overridden by
        the run's own.
    group : str or None
        TDMS group or MAT struct read: the run's own, else ``load_cell.group``.
    baseline : Baseline
    """

    cfg: Config
    log: object
    output: Path
    out_fmt: str
    columns: dict
    group: Optional[str]
    baseline: Baseline

    def chunks(self, chunk_rows: Optional[int] = None):
        """The log in chunks of about ``chunk_rows`` rows (default: the reader's), as
        :func:`~phri_spring.io.logs.iter_wrench_log` yields them."""
        size = {} if chunk_rows is None else {"chunk_rows": chunk_rows}
        return iter_wrench_log(self.log, self.columns, group=self.group,
                               wanted=LOG_COLUMNS + OPTIONAL_LOG_COLUMNS, **size)

    def count(self) -> Optional[int]:
        """Rows of the log (in the group read), best effort: for progress only."""
        return count_rows(self.log, self.group, columns=self.columns)

    @contextmanager
    def writer(self, labels, extra_types: dict, *, decimals: Optional[int] = 6):
        """A :class:`~phri_spring.io.logs.ForcesWriter` into a temporary file that
        replaces ``output`` only when the block ends without an error."""
        with atomic_file(self.output) as tmp:
            with ForcesWriter(tmp, self.out_fmt, labels, extra_types,
                              decimals=decimals) as writer:
                yield writer


def open_log_run(config, log, output, *, baseline: Union[str, Baseline, None] = "none",
                 columns: Optional[dict] = None, group: Optional[str] = None) -> LogRun:
    """Check a streamed run's output and inputs and set up its reading (nothing written).

    Parameters
    ----------
    config : Config or path
    log, output : path
    baseline : str or Baseline
        See :func:`parse_baseline`.
    columns : dict, optional
        Merged over ``load_cell.columns``.
    group : str, optional
        TDMS group or MAT struct; default ``load_cell.group``.

    Raises
    ------
    UsageError
        An output of unknown type, or one that is an input; a bad baseline.
    """
    output = Path(output)
    out_fmt = table_format(output, role="output", option="-o/--output")
    cfg = _as_config(config)
    check_output_path(output, [log, cfg.path, *cfg.stiffness_files], option="-o/--output")
    base = parse_baseline(baseline)
    colmap, group = reader_options(cfg, columns, group)
    return LogRun(cfg, log, output, out_fmt, colmap, group, base)


def _window_mean(run: LogRun, chunk_rows: int) -> np.ndarray:
    """Mean load-cell wrench over the baseline window (one streaming pass, stops early)."""
    base = run.baseline
    total = np.zeros(6)
    count = 0
    t_first = None
    t_min, t_max = math.inf, -math.inf
    for ch in run.chunks(chunk_rows):
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
                        f"{t_min:g} to {t_max:g} s)", file=run.log, key="--baseline")
    return total / count


def simulate_file(config, log, output, *, arm: str = "compliant",
                  baseline: Union[str, Baseline, None] = "none", columns: Optional[dict] = None,
                  group: Optional[str] = None,
                  chunk_rows: int = 65536, decimals: Optional[int] = 6, shear: bool = False,
                  cache_dir=None, tolerance=None,
                  progress: Optional[Callable[[int, Optional[int]], None]] = None,
                  on_chunk: Optional[Callable[[np.ndarray, np.ndarray, np.ndarray], None]] = None
                  ) -> SimulateSummary:
    """Stream a wrench log through the model into a forces file.

    Parameters
    ----------
    config : Config or path
    log : path
        Wrench log: CSV, Parquet, TDMS or MAT (docs/model.md section 7).
    output : path
        Forces file; CSV or Parquet by its extension. Written to a temporary file
        beside it and renamed at the end: a failed run leaves nothing behind.
    arm, baseline, shear
        See :func:`simulate`.
    columns : dict, optional
        Map from spec names to the log's column names; merged over ``load_cell.columns``.
    group : str, optional
        TDMS group or MAT struct holding the log's channels; default ``load_cell.group``.
    chunk_rows : int
        Samples per chunk (bounds memory): a hint, capped at about 4 M values per chunk
        and lowered when the machine's memory is short
        (:func:`~phri_spring.io.memory.budget.plan_stream`).
    decimals : int or None
        CSV output only: decimals kept in forces and pressures (default 6, i.e.
        1 uN and 1 mPa); None or a negative value keeps every digit. Parquet
        always stores full double precision.
    cache_dir : path, optional
        ``coupled`` only: where the built-in FE's surface stiffness is cached.
    tolerance : ToleranceCurve or str, optional
        Default ``cfg.tolerance``: add the dose columns and write every element's
        exposure to :func:`~.tolerance_extras.exposure_table_path` (docs/tolerance.md).
    progress : callable(done, total), optional
        Called after each chunk; ``total`` may be None.
    on_chunk : callable(time, absolute_forces, peak_pressure_kpa), optional
        Called in order, on the calling thread, once per chunk with its times (m,)
        [s], absolute forces (m, n) [N] and peak pressures (m,) [kPa] (e.g. to
        draw the run, :mod:`phri_spring.workflows.plots.maxpool`; a ``MaxPool`` and its
        figure count in the memory estimate).

    Raises
    ------
    ConfigError
        The run cannot fit in this machine's memory even in small chunks, or its CSV
        table would be wider than pyarrow's CSV writer allows; nothing is written.
    """
    run = open_log_run(config, log, output, baseline=baseline, columns=columns, group=group)
    cfg, base = run.cfg, run.baseline
    tolerance = curve_option(tolerance, cfg)
    if tolerance is not None:
        check_output_path(exposure_table_path(output), [log, cfg.path, output,
                                                        *cfg.stiffness_files])
    # rows per chunk: the hint, capped so that a fine mesh's chunk stays about 32 MB, and
    # fewer when memory is short; a run that cannot fit is refused here, before any output
    rows = plan_stream(cfg, arm, chunk_rows, output_format=run.out_fmt, shear=shear,
                       plot=isinstance(on_chunk, MaxPool), log=log, columns=run.columns,
                       group=run.group, cache_dir=cache_dir)
    model = model_from_config(cfg, arm, cache_dir=cache_dir)

    mean_lc = _window_mean(run, rows) if base.kind in ("first", "window") else None
    f_base = _baseline_forces(model, cfg, base, mean_lc, cfg.max_iterations)
    total = run.count() if progress is not None else None

    # (chunk, wrench on the cuff): the transform runs on the reader thread when there is one
    chunks = ((ch, cuff_wrench(cfg, ch.wrench)) for ch in run.chunks(rows))
    if table_format(log) == "parquet":
        # Parquet is read ahead on a thread, started now so that the first row group is
        # decoded while the writer opens; CSV is not: parsing ahead would compete with
        # the CSV writer's threads
        chunks = prefetch(chunks)
    law = model.law
    tally = NoAnswerTally(arm_radius(model.geometry))
    dose = None if tolerance is None else ExposureTally(model, tolerance,
                                                        binned=isinstance(on_chunk, MaxPool))
    try:
        summary = _stream(run, model, chunks, f_base, decimals, progress, total, on_chunk, shear,
                          tally, dose)
        reasons, worst = tally.result()
        table = None if dose is None else write_exposure_table(
            exposure_table_path(output), model.labels, dose.exposure)
        return dataclasses.replace(summary, tissue_law=law.name if law is not None else "",
                                   friction_coefficient=model.friction_coefficient,
                                   no_answer_reasons=reasons, worst_no_answer=worst,
                                   exposure=None if dose is None else dose.exposure,
                                   exposure_table=table)
    finally:
        chunks.close()  # stops the reader thread (or the generator) on an early exit


class SummaryAccumulator:
    """Adds up a streamed run's summary chunk by chunk.

    Counts come from the main thread (:meth:`add_solution`); each chunk's
    largest peak may come from a writer thread, in any order (:meth:`add_peak`);
    :meth:`summary` keeps the first largest, as one sequential pass would.
    """

    def __init__(self, labels):
        self.labels = tuple(labels)
        self.samples = self.not_converged = self.it_max = self.it_sum = 0
        self._peaks = {}  # chunk number -> (peak [kPa], element, pain ratio, time [s])
        self._shares = ChunkedShares()  # what carries the load (docs/model.md section 12.4)
        self.strap_max = None           # the band strap's largest tension [N] (band only)

    def add_load_path(self, number: int, model, sol) -> None:
        """Add chunk ``number``'s force passed to the skin by kind (normal, tangential,
        lifted); chunks may come from any thread, in any order."""
        self._shares.add(number, model, sol)

    def add_solution(self, sol) -> None:
        self.samples += len(sol.iterations)
        self.not_converged += int((~sol.converged).sum())
        self.it_max = max(self.it_max, int(sol.iterations.max()))
        self.it_sum += int(sol.iterations.sum())
        if hasattr(sol, "strap_tension"):   # an elastic band strap
            self.strap_max = float(np.fmax(np.nan if self.strap_max is None else self.strap_max,
                                           largest_tension(sol)))

    def add_peak(self, number: int, time, extras: dict, peak_index) -> None:
        pp = extras["peak_pressure_kPa"]
        if np.isfinite(pp).any():
            j = int(np.nanargmax(pp))
            self._peaks[number] = (float(pp[j]), self.labels[int(peak_index[j])],
                                   float(extras["peak_pressure_to_pain_threshold"][j]),
                                   float(time[j]))

    def summary(self, output, baseline_forces) -> SimulateSummary:
        best = (-math.inf, "", -math.inf, math.nan)
        for number in sorted(self._peaks):
            if self._peaks[number][0] > best[0]:
                best = self._peaks[number]
        return SimulateSummary(output=output, samples=self.samples,
                               not_converged=self.not_converged, max_peak_pressure_kpa=best[0],
                               max_peak_element=best[1], max_pain_ratio=best[2],
                               max_peak_time=best[3], max_iterations_used=self.it_max,
                               mean_iterations=self.it_sum / max(self.samples, 1),
                               baseline_forces=baseline_forces, labels=self.labels,
                               load_shares=self._shares.shares(),
                               max_strap_tension_n=self.strap_max)


def _stream(run: LogRun, model, chunks, f_base, decimals, progress, total, on_chunk, shear,
            tally=None, dose=None):
    cfg = run.cfg
    acc = SummaryAccumulator(model.labels)
    cache = FactorCache()  # one run, one model: factorisations reused across chunks

    def extras_job(number, time, chunk):
        # runs on a writer thread, overlapping the solving of the next chunks
        def compute():
            # first, so that a failure below cannot leave the next chunks waiting for it
            dosed = {} if dose is None else dose.add_in_order(number, time,
                                                              chunk.solution.forces)
            acc.add_load_path(number, model, chunk.solution)
            extras, idx = chunk.extras()
            extras.update(dosed)
            acc.add_peak(number, time, extras, idx)
            if tally is not None:
                tally.add(number, time, extras)
            return extras
        return compute

    with run.writer(model.labels, _extra_arrow_types(model.labels if shear else (),
                                                     has_patch_moments(model),
                                                     model.friction_coefficient is not None,
                                                     dose is not None, has_band(model)),
                    decimals=decimals) as writer:
        for number, (ch, W) in enumerate(chunks):
            if ch.activation is not None and number == 0:   # the log has muscle activation
                model = history_model(model, cfg)
            chunk = _solve_chunk(model, W, f_base, cfg.max_iterations, cache, shear, ch.time,
                                 ch.activation)
            acc.add_solution(chunk.solution)
            job = extras_job(number, ch.time, chunk)
            if on_chunk is not None:  # the observer needs the extras now, in order
                extras = job()
                on_chunk(ch.time, chunk.solution.forces, extras["peak_pressure_kPa"])
                job = extras
            writer.write(ch.time, chunk.forces, job)
            if progress is not None:
                progress(acc.samples, total)
    return acc.summary(run.output, f_base)


def _extra_arrow_types(shear_labels=(), moments: bool = False, friction: bool = False,
                       tolerance: bool = False, band: bool = False) -> dict:
    import pyarrow as pa

    types = {"int64": pa.int64(), "float64": pa.float64(), "bool": pa.bool_(),
             "label": pa.dictionary(pa.int32(), pa.string())}
    out = {name: types[kind] for name, kind in EXTRA_COLUMN_TYPES}
    out.update({name: pa.float64() for name in shear_columns(shear_labels, moments)})
    if friction:   # why a sample has no answer (physics/no_equilibrium.py)
        out.update({name: types[kind] for name, kind in NO_EQUILIBRIUM_COLUMN_TYPES})
    if tolerance:  # the dose against a tolerance curve (docs/tolerance.md)
        out.update({name: types[kind] for name, kind in TOLERANCE_COLUMN_TYPES})
    if band:       # the elastic band strap's tension (docs/model.md section 3.1)
        out.update({name: types[kind] for name, kind in BAND_COLUMN_TYPES})
    return out
