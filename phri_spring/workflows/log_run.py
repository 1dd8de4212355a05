"""A streamed run over a wrench log: its setup (:class:`LogRun`, :func:`open_log_run`)
and its summary, added up chunk by chunk (:class:`SummaryAccumulator` ->
:class:`SimulateSummary`).

``simulate`` (:func:`~phri_spring.workflows.simulate.simulate_file`) and
``simulate --uncertainty`` (:mod:`phri_spring.workflows.uncertainty.run`) read and
write through a :class:`LogRun`.
"""

from __future__ import annotations

import math
import threading
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Union

import numpy as np

from .columns.band import largest_tension
from ..io.config import Config
from ..io.logs import ForcesWriter, count_rows, iter_wrench_log, reader_options, table_format
from ..io.logs.columns import LOG_COLUMNS, OPTIONAL_LOG_COLUMNS
from ..io.outputs.atomic import atomic_file, check_output_path
from ..physics.contact.load_path import ChunkedShares
from .pipeline import Baseline, as_config, parse_baseline

__all__ = ["SimulateSummary", "SummaryAccumulator", "LogRun", "open_log_run"]


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
    #: the summary's clause on the tissue law (``, exponential tissue law (...)``), made where
    #: the config is at hand; None: not made (the command line makes it from the config)
    law_text: Optional[str] = None
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
    baseline : phri_spring.workflows.pipeline.Baseline
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

    def has_activation(self) -> bool:
        """Whether the log carries the optional muscle activation column (reads its first
        rows)."""
        for ch in self.chunks(1):
            return ch.activation is not None
        return False

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
    cfg = as_config(config)
    check_output_path(output, [log, cfg.path, *cfg.stiffness_files], option="-o/--output")
    base = parse_baseline(baseline)
    colmap, group = reader_options(cfg, columns, group)
    return LogRun(cfg, log, output, out_fmt, colmap, group, base)


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
        self._claimed = set()           # chunks whose load path a thread has taken
        self._claim_lock = threading.Lock()
        self.strap_max = None           # the band strap's largest tension [N] (band only)

    def add_load_path(self, number: int, model, sol) -> None:
        """Add chunk ``number``'s force passed to the skin by kind (normal, tangential,
        lifted); chunks may come from any thread, in any order, and a chunk is added once:
        a call for a chunk another call has taken already returns at once."""
        with self._claim_lock:
            if number in self._claimed:
                return
            self._claimed.add(number)
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

