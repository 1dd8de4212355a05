"""``phri simulate`` as library calls: wrench log -> contact force of every element.

One pipeline (:mod:`phri_spring.workflows.pipeline`): a log is solved chunk by
chunk (:func:`~.pipeline.solve_chunk`, the only place that turns a chunk of
load-cell readings into forces and the extra columns, :func:`per_sample_extras`
the only one that turns forces into peak pressure and its ratio to the pain
threshold); :func:`simulate` is that applied once to arrays in memory, and
:func:`simulate_file` applies it to every chunk of a log, hands each chunk to a
writer (bounded memory, written atomically) and adds the summary up in a
:class:`SummaryAccumulator`. What a streamed run over a log needs before solving
(the config, the output checks, the column map and group, the baseline, the
chunked reader, the writer) is a :class:`LogRun` (:func:`open_log_run`,
:mod:`phri_spring.workflows.log_run`), which ``simulate --uncertainty``
(:mod:`phri_spring.workflows.uncertainty.run`) shares.
"""

from __future__ import annotations

import collections
import dataclasses

import math
from dataclasses import dataclass, field
from typing import Callable, Optional, Union

import numpy as np

from ..errors import DataError, UsageError
from ..io.outputs.atomic import check_output_path
from ..io.config.tolerance import curve_option
from ..io.logs import prefetch, table_format
from ..physics.contact.no_equilibrium import arm_radius
from ..physics.contact.solver import FactorCache
from .common import cuff_wrench, history_model, model_from_config, refuse_activation
from ..io.memory.budget import plan_stream
from .columns.band import has_band
from .columns.no_answer import NoAnswerTally
from .columns.shear import element_loads, has_patch_moments, shear_columns
from .log_run import LogRun, SimulateSummary, SummaryAccumulator, open_log_run
from .pipeline import (EXTRA_COLUMN_TYPES, EXTRA_COLUMNS, Baseline, as_config, baseline_forces,
                       check_activation, extra_arrow_types, parse_baseline, per_sample_extras,
                       solve_chunk, window_mask, ForcesRing)

__all__ = ["Baseline", "parse_baseline", "simulate", "simulate_file", "SimulationResult",
           "SimulateSummary", "SummaryAccumulator", "EXTRA_COLUMNS", "EXTRA_COLUMN_TYPES",
           "shear_columns", "per_sample_extras", "LogRun", "open_log_run", "element_loads",
           "check_activation"]


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
    cfg = as_config(config)
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
        mask = window_mask(t, base, float(t[0]))
        if not mask.any():
            raise DataError(f"no sample in the baseline window {base} "
                            f"(the log spans {t.min():g} to {t.max():g} s)", key="--baseline")
        mean_lc = w[mask].mean(axis=0)
    f_base = baseline_forces(model, cfg, base, mean_lc, cfg.max_iterations)
    ch = solve_chunk(model, cuff_wrench(cfg, w), f_base, cfg.max_iterations, FactorCache(),
                     shear, t, activation)
    extras, idx = ch.extras()
    sol = ch.solution
    if tolerance is not None:
        from .columns.tolerance import ExposureTally   # on demand: only with a curve

        extras.update(ExposureTally(model, tolerance).add(t, sol.forces))
    return SimulationResult(time=t, labels=tuple(model.labels), forces=ch.forces,
                            absolute_forces=sol.forces, baseline_forces=f_base,
                            contact=sol.contact, iterations=sol.iterations,
                            converged=sol.converged, peak_pressure_kpa=extras["peak_pressure_kPa"],
                            peak_element=idx,
                            pain_ratio=extras["peak_pressure_to_pain_threshold"], extras=extras)




def law_clause(cfg, arm: str) -> str:
    """The summary's clause on the tissue law: ``, exponential tissue law (beta 150 1/m)``;
    for the coupled arm, that its continuum is linear when the config gives a nonlinear
    law; nothing for the linear law and the rigid arm."""
    from ..reports.tissue_law_text import arm_law_text, is_nonlinear

    return f", {arm_law_text(cfg, arm)}" if arm != "rigid" and is_nonlinear(cfg) else ""


def _plots(on_chunk) -> bool:
    """Whether ``on_chunk`` draws the run (a MaxPool), without loading the plots' module for
    a run that has none."""
    if on_chunk is None:
        return False
    from .plots.maxpool import MaxPool

    return isinstance(on_chunk, MaxPool)


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
        mask = window_mask(ch.time, base, t_first)
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
        # the dose's columns and table load on demand: a run without a curve skips them
        from .columns.tolerance import ExposureTally, exposure_table_path, write_exposure_table

        check_output_path(exposure_table_path(output), [log, cfg.path, output,
                                                        *cfg.stiffness_files])
    # rows per chunk: the hint, capped so that a fine mesh's chunk stays about 32 MB, and
    # fewer when memory is short; a run that cannot fit is refused here, before any output
    rows = plan_stream(cfg, arm, chunk_rows, output_format=run.out_fmt, shear=shear,
                       plot=_plots(on_chunk), log=log, columns=run.columns,
                       group=run.group, cache_dir=cache_dir)
    if arm == "coupled" and cfg.continuum_law != "linear" and run.has_activation():
        refuse_activation(cfg, arm)   # before minutes of identification
    model = model_from_config(cfg, arm, cache_dir=cache_dir)

    mean_lc = _window_mean(run, rows) if base.kind in ("first", "window") else None
    f_base = baseline_forces(model, cfg, base, mean_lc, cfg.max_iterations)
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
                                                        binned=_plots(on_chunk))
    try:
        summary = _stream(run, model, chunks, f_base, decimals, progress, total, on_chunk, shear,
                          tally, dose)
        reasons, worst = tally.result()
        table = None if dose is None else write_exposure_table(
            exposure_table_path(output), model.labels, dose.exposure)
        return dataclasses.replace(summary, tissue_law=law.name if law is not None else "",
                                   law_text=law_clause(cfg, arm),
                                   friction_coefficient=model.friction_coefficient,
                                   no_answer_reasons=reasons, worst_no_answer=worst,
                                   exposure=None if dose is None else dose.exposure,
                                   exposure_table=table)
    finally:
        chunks.close()  # stops the reader thread (or the generator) on an early exit




def _stream(run: LogRun, model, chunks, f_base, decimals, progress, total, on_chunk, shear,
            tally=None, dose=None):
    cfg = run.cfg
    acc = SummaryAccumulator(model.labels)
    cache = FactorCache()  # one run, one model: factorisations reused across chunks

    def extras_job(number, time, chunk, load_path_done=False):
        # runs on a writer thread, overlapping the solving of the next chunks
        def compute():
            # first, so that a failure below cannot leave the next chunks waiting for it
            dosed = {} if dose is None else dose.add_in_order(number, time,
                                                              chunk.solution.forces)
            if not load_path_done:
                acc.add_load_path(number, model, chunk.solution)
            extras, idx = chunk.extras()
            extras.update(dosed)
            acc.add_peak(number, time, extras, idx)
            if tally is not None:
                tally.add(number, time, extras)
            return extras
        return compute

    with run.writer(model.labels, extra_arrow_types(model.labels if shear else (),
                                                    has_patch_moments(model),
                                                    model.friction_coefficient is not None,
                                                    dose is not None, has_band(model)),
                    decimals=decimals) as writer:
        # the solver writes each chunk's forces into one of a few arrays used in turn, one
        # more than the writer may still be reading: a fresh chunk-sized array would be
        # faulted in anew every chunk
        ring = ForcesRing(writer.in_flight + 1, len(model.labels))
        # (number, solution) of the chunks the writer may not have finished yet
        recent = collections.deque(maxlen=writer.in_flight + 1)
        for number, (ch, W) in enumerate(chunks):
            if ch.activation is not None and number == 0:   # the log has muscle activation
                model = history_model(model, cfg)
            chunk = solve_chunk(model, W, f_base, cfg.max_iterations, cache, shear, ch.time,
                                ch.activation, out=ring.next(len(W)))
            acc.add_solution(chunk.solution)
            # every chunk the writer may hold still unfinished: the writer is the slower of
            # the two, so this thread adds this chunk's load path itself (the same sums)
            helped = writer.in_flight > 0 and writer.backlog >= writer.in_flight
            if helped:
                acc.add_load_path(number, model, chunk.solution)
            job = extras_job(number, ch.time, chunk, helped)
            if on_chunk is not None:  # the observer needs the extras now, in order
                extras = job()
                on_chunk(ch.time, chunk.solution.forces, extras["peak_pressure_kPa"])
                job = extras
            writer.write(ch.time, chunk.forces, job)
            recent.append((number, chunk.solution))
            if progress is not None:
                progress(acc.samples, total)
        # the log is solved: while the writer finishes its last chunks, this thread adds
        # their load paths, the newest first (the writer starts from the oldest; each chunk
        # is added once, by the first thread to take it, and the sums in chunk order)
        for number, sol in reversed(recent):
            acc.add_load_path(number, model, sol)
    return acc.summary(run.output, f_base)
