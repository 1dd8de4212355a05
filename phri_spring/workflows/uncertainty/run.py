"""``phri simulate --uncertainty``: Monte Carlo over what was measured with scatter.

The uncertain inputs (tissue stiffness, the exponential law's stiffening rate, strap
tension, load-cell noise), their draws and what each arm takes from them (the coupled
arm: the continuum's Young's modulus; the rigid arm: no tissue) are in
:mod:`.uncertain_draws`. Every draw runs the config's tissue law (``tissue.law``,
``tissue.stiffening``): a draw is the config with the drawn values put in.

:func:`monte_carlo` draws N sets of inputs (fixed seed), solves the whole log
for each, and returns the 5th, 50th and 95th percentiles over the draws of
every element's force and of the per-sample peak pressure / pain threshold.
Each draw's chunk is solved, and its peak pressure / pain threshold computed,
by ``simulate``'s own chunk path (:func:`.pipeline.solve_chunk`,
:func:`.pipeline.per_sample_extras`), and :func:`simulate_uncertainty_file`
streams a log through the setup, reader and writer ``simulate`` uses
(:func:`.log_run.open_log_run`). Every output names what scattered. With a tolerance
curve (the config's ``tolerance.curve`` or ``--tolerance``), every draw follows its own
dose over the log and the table gets the percentiles over the draws of ``dose_max``
(docs/tolerance.md).

The bands of ``phri compare --uncertainty`` are in :mod:`.compare_bands`, a
design study's Monte Carlo and Sobol indices in :mod:`.design_uncertainty`;
both are importable from here too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from ...errors import UsageError
from ...io.config import Config
from ...physics.friction.states import interface_mu
from ...physics.contact.solver import FactorCache
from ...reports.tissue_law_text import arm_law_text
from ...reports.uncertainty.report import monte_carlo_summary_line
from ..common import cuff_wrench, history_model, model_from_config
from ..compare.bands import compare_bands, write_compare_bands  # noqa: F401 - importable here
from ..design.uncertainty import sobol_indices, study_uncertainty  # noqa: F401 - importable here
from ..log_run import open_log_run
from ..pipeline import solve_chunk
from .draws import (PERCENTILES, UncertainInputs, check_fe_cache,
                              draw_configs, parse_sd, perturbed_text, reaches_model,
                              uncertain_inputs)

__all__ = ["UncertainInputs", "uncertain_inputs", "monte_carlo", "MonteCarloResult",
           "MonteCarloStream", "MonteCarloRun", "simulate_uncertainty_file",
           "percentile_columns", "RATIO_COLUMNS", "study_uncertainty", "PERCENTILES",
           "write_monte_carlo", "sobol_indices", "compare_bands", "write_compare_bands",
           "parse_sd", "run_cli", "DOSE_COLUMNS", "dose_percentiles"]

#: columns of the percentile table after the forces: peak pressure / pain threshold [-]
RATIO_COLUMNS = tuple(f"peak_pressure_to_pain_threshold_p{q:g}" for q in PERCENTILES)
#: columns after the ratios with a tolerance curve: the largest dose over the elements [-]
DOSE_COLUMNS = tuple(f"dose_max_p{q:g}" for q in PERCENTILES)
#: (draws x samples x elements) values held at once
_CHUNK_ENTRIES = 1 << 23


@dataclass
class MonteCarloResult:
    """Percentiles over the draws (q = :data:`PERCENTILES`).

    Attributes
    ----------
    forces : ndarray, shape (3, m, n)
        Percentiles of each element's normal force [N] at each sample.
    pain_ratio : ndarray, shape (3, m)
        Percentiles of the per-sample peak pressure / pain threshold [-].
    draws : int
    not_converged : int
        (draw, sample) pairs the solver did not converge on (left out).
    labels : tuple
    perturbed : str
        The inputs that scattered for the arm (``none``: the percentiles coincide).
    tissue_law : str
        The arm's tissue (:func:`~phri_spring.reports.tissue_law_text.arm_law_text`).
    """

    forces: np.ndarray
    pain_ratio: np.ndarray
    draws: int
    not_converged: int
    labels: tuple
    perturbed: str = ""
    tissue_law: str = ""


class MonteCarloStream:
    """Monte Carlo percentiles block by block, for a log of any length in bounded memory.

    The samples are taken in blocks of a fixed size (about 8 M forces per
    block over all draws); draw d's load-cell noise in block c comes from its
    own random stream (seed, d, c), so the percentiles depend only on the seed
    and the number of draws, not on how the log is read. :func:`monte_carlo`
    (arrays) and ``phri simulate --uncertainty`` (streamed) share it.

    Parameters
    ----------
    cfg : Config
    draws : int
        Monte Carlo draws N (>= 2).
    seed : int
    arm : str
    inputs : UncertainInputs, optional
        Default: the tissue SD from the config's CSV, no other scatter.
    tolerance : ToleranceCurve or str, optional
        Follow every draw's dose against this curve (an
        :class:`~phri_spring.physics.response.tolerance.Exposure` per draw, carried
        from block to block); the blocks must then come with their times, in log order.

    Attributes
    ----------
    block_samples : int
        Samples per block.
    perturbed : str
        The inputs that scatter for this arm (``none`` when none does).
    tissue_law : str
        The arm's tissue law, e.g. ``exponential tissue law, beta 150 1/m``.
    not_converged : int
        (draw, sample) pairs the solver did not converge on so far (left out).
    exposures : list or None
        With a curve: each draw's exposure so far.
    dose : ndarray or None
        With a curve: the percentiles over the draws of the largest dose over the
        elements at each sample of the last block, shape (3, k) [-].
    """

    def __init__(self, cfg: Config, *, draws: int, seed: int = 0, arm: str = "compliant",
                 inputs: Optional[UncertainInputs] = None, tolerance=None):
        if int(draws) < 2:
            raise UsageError(f"expected at least 2 draws, got {draws}", key="--uncertainty")
        self.cfg, self.draws, self.seed = cfg, int(draws), int(seed)
        inputs = uncertain_inputs(cfg) if inputs is None else inputs
        cfgs = draw_configs(cfg, inputs, self.draws, self.seed)
        #: what scattered for this arm (:func:`.uncertain_draws.perturbed_text`)
        self.perturbed = perturbed_text(cfg, inputs, arm)
        self.tissue_law = f"{arm} arm: {arm_law_text(cfg, arm)}"
        if reaches_model(cfg, inputs, arm):
            check_fe_cache(cfg, inputs, [arm])
            self.models = [model_from_config(c, arm) for c in cfgs]
        else:   # nothing this arm uses scatters: every draw's model is the config's own
            self.models = [model_from_config(cfg, arm)] * self.draws
        if self._history and self.draws > 1 and self.models[0] is self.models[1]:
            # a relaxing tissue remembers its draw's own samples: a model each
            self.models = [model_from_config(cfg, arm) for _ in range(self.draws)]
        self.noise_sd = inputs.noise_sd
        self.block_samples = max(1, _CHUNK_ENTRIES // (self.draws * cfg.n_elements))
        self.not_converged = 0
        self.exposures, self.dose = None, None
        if tolerance is not None:
            from ...physics.response.tolerance import Exposure

            self.exposures = [Exposure(tolerance, cfg.n_elements, m.pain_threshold_kpa)
                              for m in self.models]
        self._paths = {}   # draw -> its cache, kept only with friction (the path's state)

    def _cache(self, d: int) -> FactorCache:
        """Draw d's cache: a fresh one per block, except with friction, where each draw
        runs the whole log as one loading path from the strap's state (docs/model.md 12.2)."""
        if interface_mu(self.models[d]) is None:
            return FactorCache()
        if d not in self._paths:
            self._paths[d] = FactorCache(64)
        return self._paths[d]

    @property
    def _history(self) -> bool:
        return getattr(self.models[0], "has_history", False)

    def block(self, number: int, wrench_lc, time=None, activation=None):
        """Percentiles of block ``number`` (its samples in the load cell's units, (k, 6)).

        Returns the force percentiles, shape (3, k, n) [N], and those of the
        peak pressure / pain threshold, shape (3, k) [-]. With a curve or a tissue with a
        history (``tissue.relaxation``, an ``activation`` (k,) 0..1 as a log's column),
        ``time`` (k,) [s] is needed, blocks come in log order and every draw carries its
        own history; with a curve :attr:`dose` holds the block's dose percentiles.
        """
        cfg, n = self.cfg, self.cfg.n_elements
        w = np.atleast_2d(np.asarray(wrench_lc, dtype=float))
        if activation is not None and not self._history:   # as simulate does with the column
            self.models = [history_model(m, cfg) for m in self.models]
        if (self.exposures is not None or self._history) and time is None:
            raise ValueError("a stream with a tolerance curve or a tissue history needs "
                             "each block's times")
        F = np.empty((self.draws, len(w), n))
        R = np.empty((self.draws, len(w)))
        D = None if self.exposures is None else np.empty((self.draws, len(w)))
        for d in range(self.draws):
            wd = w
            if self.noise_sd.any():
                rng = np.random.default_rng([self.seed, 1, d, int(number)])
                wd = wd + rng.standard_normal(wd.shape) * self.noise_sd
            # a cache of its own: a draw's model is not the next draw's; with friction the
            # draw's cache also carries its loading path from block to block
            chunk = solve_chunk(self.models[d], cuff_wrench(cfg, wd), None,
                                cfg.max_iterations, self._cache(d), False, time, activation)
            F[d] = chunk.forces
            R[d] = chunk.extras()[0]["peak_pressure_to_pain_threshold"]
            self.not_converged += int((~chunk.solution.converged).sum())
            if D is not None:   # the draw's own run: its dose goes on from its last block
                D[d] = self.exposures[d].add(time, chunk.forces,
                                             scale=self.models[d].inv_area_kpa)[0]
        q = np.array(PERCENTILES)
        pct = np.nanpercentile if self.not_converged else np.percentile
        if D is not None:
            self.dose = dose_percentiles(D, q)
        return pct(F, q, axis=0), pct(R, q, axis=0)

    def blocks(self, chunks):
        """Percentiles of a log read in chunks of any size.

        ``chunks`` yields ``(time, wrench_lc)`` pairs, shapes (k,) and (k, 6), or
        ``(time, wrench_lc, activation)`` with activation (k,) or None;
        yields ``(time, force percentiles, ratio percentiles)`` block by block
        (see :meth:`block`), holding at most one block of samples.
        """
        times, wrenches, acts, held, number = [], [], [], 0, 0
        k = self.block_samples
        for chunk in chunks:
            t, w = chunk[0], chunk[1]
            a = chunk[2] if len(chunk) > 2 else None
            times.append(np.asarray(t, dtype=float))
            wrenches.append(np.atleast_2d(np.asarray(w, dtype=float)))
            acts.append(None if a is None else np.asarray(a, dtype=float))
            held += len(times[-1])
            if held < k:
                continue
            t_all, w_all, a_all = (np.concatenate(times), np.concatenate(wrenches),
                                   _joined(acts, times))                  # once a chunk
            start = 0
            while held - start >= k:
                tk = t_all[start:start + k]
                ak = None if a_all is None else a_all[start:start + k]
                yield (tk, *self.block(number, w_all[start:start + k], tk, ak))
                number, start = number + 1, start + k
            times, wrenches, held = [t_all[start:]], [w_all[start:]], held - start
            acts = [None if a_all is None else a_all[start:]]
        if held:
            tk = np.concatenate(times)
            yield (tk, *self.block(number, np.concatenate(wrenches), tk, _joined(acts, times)))


def _joined(acts, times):
    """The activations of held chunks as one array (0 where a chunk had none), or None."""
    if all(a is None for a in acts):
        return None
    return np.concatenate([np.zeros(len(t)) if a is None else a for a, t in zip(acts, times)])


def dose_percentiles(doses, q) -> np.ndarray:
    """Percentiles ``q`` over the draws (axis 0) of doses that may be infinite (a
    time-independent curve once pressed), shape (len(q), k): linear between the two draws
    around each rank as ``np.percentile``, where two infinite doses give an infinite one
    (``np.percentile`` gives NaN there: inf - inf)."""
    s = np.sort(np.asarray(doses, dtype=float), axis=0)
    pos = np.asarray(q, dtype=float) / 100.0 * (len(s) - 1)
    lo = np.floor(pos).astype(np.intp)
    hi = np.minimum(lo + 1, len(s) - 1)
    g = (pos - lo)[:, None]
    a, b = s[lo], s[hi]
    with np.errstate(invalid="ignore"):
        between = a + (b - a) * g
    return np.where((a == b) | (g == 0), a, between)


def monte_carlo(cfg: Config, wrench_lc, *, draws: int, seed: int = 0, arm: str = "compliant",
                inputs: Optional[UncertainInputs] = None, time=None,
                activation=None) -> MonteCarloResult:
    """Monte Carlo percentiles of the forces for every sample of a log.

    Parameters
    ----------
    cfg : Config
    wrench_lc : array_like, shape (m, 6)
        Load-cell readings in the config's units.
    draws : int
        Monte Carlo draws N (>= 2).
    seed : int
        Results depend only on the seed and N (draw d's noise comes from its own
        stream, block by block of samples of a fixed size: see
        :class:`MonteCarloStream`, which streams a log of any length).
    arm : str
    inputs : UncertainInputs, optional
        Default: the tissue SD from the config's CSV, no other scatter.
    time : array_like, shape (m,), optional
        Sample times [s]: needed by a relaxing tissue (``tissue.relaxation``).
    activation : array_like, shape (m,), optional
        Muscle activation 0..1 of every sample (docs/model.md section 15.2).

    Returns
    -------
    MonteCarloResult
    """
    mc = MonteCarloStream(cfg, draws=draws, seed=seed, arm=arm, inputs=inputs)
    w = np.atleast_2d(np.asarray(wrench_lc, dtype=float))
    m, n = len(w), cfg.n_elements
    out_f = np.empty((3, m, n))
    out_r = np.empty((3, m))
    for c, s in enumerate(range(0, m, mc.block_samples)):
        e = min(m, s + mc.block_samples)
        out_f[:, s:e], out_r[:, s:e] = mc.block(
            c, w[s:e], None if time is None else np.asarray(time, dtype=float)[s:e],
            None if activation is None else np.asarray(activation, dtype=float)[s:e])
    return MonteCarloResult(out_f, out_r, mc.draws, mc.not_converged, tuple(cfg.labels),
                            mc.perturbed, mc.tissue_law)


def write_monte_carlo(result: MonteCarloResult, time, output) -> Path:
    """Write the percentile table (CSV or Parquet by extension), atomically.

    Columns: time [s]; for each element ``{label}_p5``, ``{label}_p50``,
    ``{label}_p95`` [N]; ``peak_pressure_to_pain_threshold_p5/_p50/_p95`` [-].
    """
    import pandas as pd

    from ...io.outputs.atomic import atomic_file
    from ...io.logs import table_format

    output = Path(output)
    fmt = table_format(output, role="output", option="-o/--output")
    data = {"time": np.asarray(time, dtype=float)}
    m, n = result.forces.shape[1:]
    data.update(zip(percentile_columns(result.labels),
                    result.forces.transpose(1, 2, 0).reshape(m, 3 * n).T))
    data.update(zip(RATIO_COLUMNS, result.pain_ratio))
    df = pd.DataFrame(data)
    with atomic_file(output) as tmp:
        if fmt == "parquet":
            df.to_parquet(tmp, index=False)
        else:
            df.to_csv(tmp, index=False, float_format="%.6f")
    return output


@dataclass(frozen=True)
class MonteCarloRun:
    """What ``phri simulate --uncertainty`` wrote: the table and its size."""

    output: Path
    samples: int
    draws: int
    not_converged: int
    labels: tuple
    seed: int = 0
    #: the largest 95th percentile of peak pressure / pain threshold [-] and its time [s]
    max_pain_ratio_p95: float = math.nan
    max_pain_ratio_time: float = math.nan
    #: the inputs that scattered for the arm that ran
    perturbed: str = ""
    #: the arm and its tissue law (``compliant arm: exponential tissue law, beta 150 1/m``)
    tissue_law: str = ""
    #: with a tolerance curve: (its name, p5, p50, p95 of the largest dose at the end) [-]
    dose: Optional[tuple] = None

    def summary_line(self) -> str:
        """The line ``phri simulate --uncertainty`` ends with: sizes, draws, the peak."""
        return monte_carlo_summary_line(
            self.output, samples=self.samples, elements=len(self.labels), draws=self.draws,
            seed=self.seed, not_converged=self.not_converged, perturbed=self.perturbed,
            tissue_law=self.tissue_law, dose=self.dose,
            max_pain_ratio_p95=self.max_pain_ratio_p95,
            max_pain_ratio_time=self.max_pain_ratio_time)


def percentile_columns(labels) -> list:
    """Force columns of the percentile table: ``{label}_p5``, ``_p50``, ``_p95`` per element."""
    tags = [f"p{q:g}" for q in PERCENTILES]
    return [f"{lab}_{tag}" for lab in labels for tag in tags]


def simulate_uncertainty_file(config, log, output, *, draws: int, seed: int = 0,
                              arm: str = "compliant", columns: Optional[dict] = None,
                              group: Optional[str] = None, sd: Optional[str] = None,
                              progress=None, tolerance=None) -> MonteCarloRun:
    """``phri simulate --uncertainty N``: stream a log through :class:`MonteCarloStream`.

    The log is read, and the table written, as ``simulate`` does
    (:func:`.log_run.open_log_run`: ``columns`` merged over
    ``load_cell.columns``, ``group`` the TDMS group or MAT struct, default
    ``load_cell.group``). The table (the columns of :func:`write_monte_carlo`;
    CSV forces to 1 uN) is written block by block into a temporary file that
    replaces ``output`` at the end, so that a log of any length runs in
    bounded memory. ``progress(samples_done, total)`` is called after each block.
    ``tolerance`` (default the config's ``tolerance.curve``) adds :data:`DOSE_COLUMNS`,
    each draw's dose followed over the whole log (docs/tolerance.md).
    """
    import pyarrow as pa

    from ...io.config.tolerance import curve_option

    run = open_log_run(config, log, output, columns=columns, group=group)
    cfg = run.cfg
    curve = curve_option(tolerance, cfg)
    inputs = uncertain_inputs(cfg, **parse_sd(sd))
    mc = MonteCarloStream(cfg, draws=draws, seed=seed, arm=arm, inputs=inputs, tolerance=curve)
    ratio = {name: pa.float64() for name in RATIO_COLUMNS}
    if curve is not None:
        ratio.update({name: pa.float64() for name in DOSE_COLUMNS})
    dose_end = None
    total = run.count() if progress is not None else None
    samples, peak, peak_time = 0, -math.inf, math.nan
    with run.writer(percentile_columns(cfg.labels), ratio) as writer:
        chunks = ((ch.time, ch.wrench, ch.activation) for ch in run.chunks())
        for time, f_pct, r_pct in mc.blocks(chunks):
            k = len(time)
            # (3, k, n) -> (k, n, 3): each element's p5, p50, p95 side by side
            extra = dict(zip(RATIO_COLUMNS, r_pct))
            if curve is not None:
                extra.update(zip(DOSE_COLUMNS, mc.dose))
                dose_end = mc.dose[:, -1]
            writer.write(time, f_pct.transpose(1, 2, 0).reshape(k, -1), extra)
            if np.isfinite(r_pct[2]).any() and np.nanmax(r_pct[2]) > peak:
                j = int(np.nanargmax(r_pct[2]))
                peak, peak_time = float(r_pct[2][j]), float(time[j])
            samples += k
            if progress is not None:
                progress(samples, total)
    return MonteCarloRun(run.output, samples, mc.draws, mc.not_converged, tuple(cfg.labels),
                         mc.seed, peak if samples and np.isfinite(peak) else math.nan,
                         peak_time, mc.perturbed, mc.tissue_law,
                         None if dose_end is None else (curve.name, *map(float, dose_end)))


def run_cli(config, log, output, arm, baseline, columns, draws, sd, seed,
            progress=None, group: Optional[str] = None, tolerance=None) -> "MonteCarloRun":
    """The ``--uncertainty`` branch of ``phri simulate`` (absolute forces only)."""
    if baseline != "none":
        raise UsageError(f"--uncertainty gives percentiles of absolute forces; expected "
                         f"--baseline none, got {baseline}", key="--baseline")
    return simulate_uncertainty_file(config, log, output, draws=draws, seed=seed, arm=arm,
                                     columns=columns, group=group, sd=sd, progress=progress,
                                     tolerance=tolerance)
