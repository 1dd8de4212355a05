"""Uncertainty of the predictions: Monte Carlo over what was measured with scatter, Sobol indices.

The uncertain inputs (tissue stiffness, strap tension, load-cell noise), their
draws and what each arm takes from them (the coupled arm: the continuum's
Young's modulus; the rigid arm: no tissue) are in :mod:`.uncertain_draws`.

:func:`monte_carlo` draws N sets of inputs (fixed seed), solves the whole log
for each, and returns the 5th, 50th and 95th percentiles over the draws of
every element's force and of the per-sample peak pressure / pain threshold.
:func:`study_uncertainty` does the same for a design study's objectives at
its best design, and, with SALib, the first-order and total Sobol indices of
each objective to each scalar input the arm uses (per-location tissue
stiffness or the continuum's modulus, strap tension): which measurement is
worth repeating. Load-cell noise is random per sample, not one scalar, so it is
in the Monte Carlo but not in the indices. Every output names what scattered.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from ..errors import UsageError
from ..io.config import Config
from ..physics.solver import solve
from .common import cuff_wrench, model_from_config
from .uncertain_draws import (UncertainInputs, check_fe_cache, config_at, draw_configs,
                              parse_sd, perturbed_text, reaches_model, sobol_inputs,
                              uncertain_inputs)

__all__ = ["UncertainInputs", "uncertain_inputs", "monte_carlo", "MonteCarloResult",
           "MonteCarloStream", "MonteCarloRun", "simulate_uncertainty_file",
           "percentile_columns", "RATIO_COLUMNS", "study_uncertainty", "PERCENTILES",
           "write_monte_carlo"]

#: percentiles reported [%]
PERCENTILES = (5.0, 50.0, 95.0)
#: columns of the percentile table after the forces: peak pressure / pain threshold [-]
RATIO_COLUMNS = tuple(f"peak_pressure_to_pain_threshold_p{q:g}" for q in PERCENTILES)
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
    """

    forces: np.ndarray
    pain_ratio: np.ndarray
    draws: int
    not_converged: int
    labels: tuple
    perturbed: str = ""


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

    Attributes
    ----------
    block_samples : int
        Samples per block.
    perturbed : str
        The inputs that scatter for this arm (``none`` when none does).
    not_converged : int
        (draw, sample) pairs the solver did not converge on so far (left out).
    """

    def __init__(self, cfg: Config, *, draws: int, seed: int = 0, arm: str = "compliant",
                 inputs: Optional[UncertainInputs] = None):
        if int(draws) < 2:
            raise UsageError(f"expected at least 2 draws, got {draws}", key="--uncertainty")
        self.cfg, self.draws, self.seed = cfg, int(draws), int(seed)
        inputs = uncertain_inputs(cfg) if inputs is None else inputs
        cfgs = draw_configs(cfg, inputs, self.draws, self.seed)
        #: what scattered for this arm (:func:`.uncertain_draws.perturbed_text`)
        self.perturbed = perturbed_text(cfg, inputs, arm)
        if reaches_model(cfg, inputs, arm):
            check_fe_cache(cfg, inputs, [arm])
            self.models = [model_from_config(c, arm) for c in cfgs]
        else:   # nothing this arm uses scatters: every draw's model is the config's own
            self.models = [model_from_config(cfg, arm)] * self.draws
        self.noise_sd = inputs.noise_sd
        self.block_samples = max(1, _CHUNK_ENTRIES // (self.draws * cfg.n_elements))
        self.not_converged = 0
        self._inv_area_kpa = 1.0 / (1000.0 * self.models[0].areas)
        self._thr = np.array([m.pain_threshold_kpa for m in self.models])[:, None]

    def block(self, number: int, wrench_lc):
        """Percentiles of block ``number`` (its samples in the load cell's units, (k, 6)).

        Returns the force percentiles, shape (3, k, n) [N], and those of the
        peak pressure / pain threshold, shape (3, k) [-].
        """
        cfg, n = self.cfg, self.cfg.n_elements
        w = np.atleast_2d(np.asarray(wrench_lc, dtype=float))
        F = np.empty((self.draws, len(w), n))
        for d in range(self.draws):
            wd = w
            if self.noise_sd.any():
                rng = np.random.default_rng([self.seed, 1, d, int(number)])
                wd = wd + rng.standard_normal(wd.shape) * self.noise_sd
            sol = solve(self.models[d], cuff_wrench(cfg, wd), max_iterations=cfg.max_iterations)
            F[d] = sol.forces
            self.not_converged += int((~sol.converged).sum())
        R = (F * self._inv_area_kpa).max(axis=2) / self._thr
        q = np.array(PERCENTILES)
        pct = np.nanpercentile if self.not_converged else np.percentile
        return pct(F, q, axis=0), pct(R, q, axis=0)

    def blocks(self, chunks):
        """Percentiles of a log read in chunks of any size.

        ``chunks`` yields ``(time, wrench_lc)`` pairs, shapes (k,) and (k, 6);
        yields ``(time, force percentiles, ratio percentiles)`` block by block
        (see :meth:`block`), holding at most one block of samples.
        """
        times, wrenches, held, number = [], [], 0, 0
        k = self.block_samples
        for t, w in chunks:
            times.append(np.asarray(t, dtype=float))
            wrenches.append(np.atleast_2d(np.asarray(w, dtype=float)))
            held += len(times[-1])
            if held < k:
                continue
            t_all, w_all = np.concatenate(times), np.concatenate(wrenches)   # once a chunk
            start = 0
            while held - start >= k:
                yield (t_all[start:start + k], *self.block(number, w_all[start:start + k]))
                number, start = number + 1, start + k
            times, wrenches, held = [t_all[start:]], [w_all[start:]], held - start
        if held:
            yield (np.concatenate(times), *self.block(number, np.concatenate(wrenches)))


def monte_carlo(cfg: Config, wrench_lc, *, draws: int, seed: int = 0, arm: str = "compliant",
                inputs: Optional[UncertainInputs] = None) -> MonteCarloResult:
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
        out_f[:, s:e], out_r[:, s:e] = mc.block(c, w[s:e])
    return MonteCarloResult(out_f, out_r, mc.draws, mc.not_converged, tuple(cfg.labels),
                            mc.perturbed)


def write_monte_carlo(result: MonteCarloResult, time, output) -> Path:
    """Write the percentile table (CSV or Parquet by extension), atomically.

    Columns: time [s]; for each element ``{label}_p5``, ``{label}_p50``,
    ``{label}_p95`` [N]; ``peak_pressure_to_pain_threshold_p5/_p50/_p95`` [-].
    """
    import pandas as pd

    from ..io.atomic import atomic_file
    from ..io.logs import table_format

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


# --------------------------------------------------------------------------- studies
def _objectives_at(cfg, loads, arm, objectives) -> tuple[np.ndarray, np.ndarray]:
    """(objective values (k,) in the order of ``objectives``, each element's peak pressure
    over the load set (n,) [kPa]) of one design."""
    from .design_objectives import evaluate_design

    r = evaluate_design(cfg, loads, arm)
    return np.array([r[o] for o in objectives], dtype=float), r["element_peak_pressure_kPa"]


def study_uncertainty(cfg: Config, loads, arm: str, spec, objectives) -> dict:
    """Monte Carlo (and optional Sobol indices) of a study's objectives at one design.

    Parameters
    ----------
    cfg : Config
        The design (usually the best).
    loads : LoadSet
    arm : str
    spec : UncertaintySpec
        The study's ``uncertainty:`` section.
    objectives : sequence of str

    Returns
    -------
    dict
        ``tables`` (file name -> DataFrame) and ``markdown`` (a report section).
    """
    import pandas as pd

    from .design_objectives import LoadSet

    inputs = uncertain_inputs(cfg, tissue_sd=spec.tissue_stiffness_sd,
                              tension_sd_N=spec.strap_tension_sd_N,
                              force_sd_N=spec.loadcell_force_sd_N,
                              moment_sd_Nm=spec.loadcell_moment_sd_Nm)
    cfgs = draw_configs(cfg, inputs, spec.draws, spec.seed)
    check_fe_cache(cfg, inputs, [arm])
    perturbed = perturbed_text(cfg, inputs, arm)
    noisy = bool(inputs.noise_sd.any())
    if noisy:   # noise is per sample: expand the merged rows back to every sample
        full = np.repeat(loads.wrench_lc, loads.weights.astype(np.int64), axis=0)
    vals, peaks = [], []
    for d, c in enumerate(cfgs):
        ls = loads
        if noisy:
            rng = np.random.default_rng([int(spec.seed), 1, d])
            w = full + rng.standard_normal(full.shape) * inputs.noise_sd
            ls = LoadSet(w, np.ones(len(w)), len(w))
        v, p = _objectives_at(c, ls, arm, objectives)
        vals.append(v)
        peaks.append(p)
    V = np.array(vals)
    P = np.array(peaks)
    q = np.array(PERCENTILES)
    obj = pd.DataFrame({"objective": list(objectives),
                        **{f"p{x:g}": np.nanpercentile(V, x, axis=0) for x in q},
                        "mean": np.nanmean(V, axis=0), "sd": np.nanstd(V, axis=0, ddof=1),
                        "draws_converged": np.isfinite(V).sum(axis=0),
                        "perturbed": perturbed})
    pat = pd.DataFrame({"location": list(cfg.labels),
                        **{f"peak_pressure_kPa_p{x:g}": np.nanpercentile(P, x, axis=0)
                           for x in q}})
    tables = {"uncertainty_objectives.csv": obj, "uncertainty_patches.csv": pat}
    md = ["## Uncertainty of the best design", "",
          f"Monte Carlo, {spec.draws} draws (seed {spec.seed}), {arm} arm "
          "(uncertainty_objectives.csv, uncertainty_patches.csv). Perturbed for this arm: "
          f"{perturbed}.", "",
          "| objective | p5 | p50 | p95 |", "|---|---|---|---|"]
    for _, r in obj.iterrows():
        md.append(f"| {r['objective']} | {r['p5']:.4g} | {r['p50']:.4g} | {r['p95']:.4g} |")
    lost = spec.draws - obj["draws_converged"].min()
    if lost:
        md += ["", f"{lost} of {spec.draws} draws did not converge and are left out."]
    if spec.sobol:
        sob = sobol_indices(cfg, loads, arm, inputs, objectives, spec.sobol, spec.seed)
        if sob is not None:
            tables["sobol.csv"] = sob
            md += ["", "Sobol indices (SALib, Saltelli sampling with "
                   f"{spec.sobol} base samples; sobol.csv): the inputs with the largest total "
                   "index ST are the measurements most worth repeating.", "",
                   "| objective | input | S1 | ST |", "|---|---|---|---|"]
            notes = []
            for o in objectives:
                mine = sob[sob["objective"] == o]
                if mine["note"].iloc[0]:     # unavailable: never printed as a measured 0
                    md.append(f"| {o} | (all) | unavailable | unavailable |")
                    notes.append(f"- {o}: {mine['note'].iloc[0]}.")
                    continue
                for _, r in mine.sort_values("ST", ascending=False).head(3).iterrows():
                    md.append(f"| {o} | {r['input']} | {r['S1']:.3f} | {r['ST']:.3f} |")
            if notes:
                md += ["", *notes]
        else:
            md += ["", f"(No Sobol indices: no input the {arm} arm uses has a non-zero SD.)"]
    return {"tables": tables, "markdown": "\n".join(md)}


def sobol_indices(cfg: Config, loads, arm: str, inputs: UncertainInputs, objectives,
                  n_base: int, seed: int = 0):
    """First-order and total Sobol indices of each objective to each scalar input (SALib).

    Inputs: those the arm uses with a non-zero SD (:func:`.uncertain_draws.sobol_inputs`:
    each location's tissue stiffness, or the continuum's Young's modulus, and the
    strap tension), each Gaussian. Costs n_base * (D + 2) evaluations over the
    load set (D inputs).

    Returns
    -------
    pandas.DataFrame or None
        objective, input, S1, S1_conf, ST, ST_conf, note; None when no input has an
        SD. An objective some evaluation gave no value for (not converged), or that
        never varies, has NaN indices and its reason in ``note`` (empty otherwise).
    """
    import pandas as pd

    try:
        from SALib.analyze import sobol as sobol_analyze
        from SALib.sample import sobol as sobol_sample
    except ImportError:
        raise UsageError("Sobol indices need SALib: pip install -e .[sensitivity]",
                         key="uncertainty.sobol") from None
    scalars = sobol_inputs(cfg, inputs, arm)
    if not scalars:
        return None
    names = [nm for nm, *_ in scalars]
    which = [w for *_, w in scalars]
    problem = {"num_vars": len(names), "names": names,
               "bounds": [[mean, sd] for _, mean, sd, _ in scalars],
               "dists": ["norm"] * len(names)}
    X = sobol_sample.sample(problem, int(n_base), calc_second_order=False, seed=int(seed))
    Y = np.empty((len(X), len(objectives)))
    for i, x in enumerate(X):
        Y[i] = _objectives_at(config_at(cfg, which, x), loads, arm, objectives)[0]
    rows = []
    for j, o in enumerate(objectives):
        y = Y[:, j]
        bad = int(np.count_nonzero(~np.isfinite(y)))
        note = (f"unavailable: {bad} of {len(y)} evaluations did not converge" if bad else
                f"unavailable: the objective is the same in all {len(y)} evaluations (no "
                "variance to apportion)" if np.ptp(y) == 0 else "")
        if note:
            rows += [{"objective": o, "input": nm, "S1": math.nan, "S1_conf": math.nan,
                      "ST": math.nan, "ST_conf": math.nan, "note": note} for nm in names]
            continue
        res = sobol_analyze.analyze(problem, y, calc_second_order=False, seed=int(seed))
        for i, nm in enumerate(names):
            rows.append({"objective": o, "input": nm, "S1": float(res["S1"][i]),
                         "S1_conf": float(res["S1_conf"][i]), "ST": float(res["ST"][i]),
                         "ST_conf": float(res["ST_conf"][i]), "note": ""})
    return pd.DataFrame(rows)


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

    def summary_line(self) -> str:
        """The line ``phri simulate --uncertainty`` ends with: sizes, draws, the peak."""
        peak = (f"; 95th percentile of peak pressure up to {100 * self.max_pain_ratio_p95:.3g}%"
                f" of the pain threshold (t = {self.max_pain_ratio_time:g} s)"
                if math.isfinite(self.max_pain_ratio_p95) else "")
        bad = (f"; {self.not_converged} draw-samples did not converge and were left out"
               if self.not_converged else "")
        return (f"wrote {self.output} ({self.samples:,} samples x {len(self.labels)} elements, "
                f"5/50/95th percentiles over {self.draws} Monte Carlo draws, seed {self.seed}"
                f"{bad}; perturbed: {self.perturbed or 'none'}){peak}")


def percentile_columns(labels) -> list:
    """Force columns of the percentile table: ``{label}_p5``, ``_p50``, ``_p95`` per element."""
    tags = [f"p{q:g}" for q in PERCENTILES]
    return [f"{lab}_{tag}" for lab in labels for tag in tags]


def simulate_uncertainty_file(config, log, output, *, draws: int, seed: int = 0,
                              arm: str = "compliant", columns: Optional[dict] = None,
                              sd: Optional[str] = None, progress=None) -> MonteCarloRun:
    """``phri simulate --uncertainty N``: stream a log through :class:`MonteCarloStream`.

    The table (the columns of :func:`write_monte_carlo`; CSV forces to 1 uN)
    is written block by block into a temporary file that replaces ``output``
    at the end, so a log of any length runs in bounded memory (measured: a
    3 h log with 10 draws in 0.77 GB, against 1.6 GB when it was held whole).
    ``progress(samples_done, total)`` is called after each block.
    """
    import pyarrow as pa

    from ..io.atomic import atomic_file, check_output_path
    from ..io.config import load_config
    from ..io.logs import ForcesWriter, iter_wrench_log, table_format

    cfg = config if isinstance(config, Config) else load_config(config)
    fmt = table_format(output, role="output", option="-o/--output")
    check_output_path(output, [log, cfg.path, *cfg.stiffness_files], option="-o/--output")
    colmap = dict(cfg.log_columns)
    colmap.update(columns or {})
    inputs = uncertain_inputs(cfg, **parse_sd(sd))
    mc = MonteCarloStream(cfg, draws=draws, seed=seed, arm=arm, inputs=inputs)
    ratio = {name: pa.float64() for name in RATIO_COLUMNS}
    total = None
    if progress is not None:
        from ..io.logs import count_rows

        total = count_rows(log, columns=colmap)
    samples, peak, peak_time = 0, -math.inf, math.nan
    output = Path(output)
    with atomic_file(output) as tmp:
        with ForcesWriter(tmp, fmt, percentile_columns(cfg.labels), ratio) as writer:
            chunks = ((ch.time, ch.wrench) for ch in iter_wrench_log(log, colmap))
            for time, f_pct, r_pct in mc.blocks(chunks):
                k = len(time)
                # (3, k, n) -> (k, n, 3): each element's p5, p50, p95 side by side
                writer.write(time, f_pct.transpose(1, 2, 0).reshape(k, -1),
                             dict(zip(ratio, r_pct)))
                if np.isfinite(r_pct[2]).any() and np.nanmax(r_pct[2]) > peak:
                    j = int(np.nanargmax(r_pct[2]))
                    peak, peak_time = float(r_pct[2][j]), float(time[j])
                samples += k
                if progress is not None:
                    progress(samples, total)
    return MonteCarloRun(output, samples, mc.draws, mc.not_converged, tuple(cfg.labels),
                         mc.seed, peak if samples and np.isfinite(peak) else math.nan,
                         peak_time, mc.perturbed)


def run_cli(config, log, output, arm, baseline, columns, draws, sd, seed,
            progress=None) -> "MonteCarloRun":
    """The ``--uncertainty`` branch of ``phri simulate`` (absolute forces only)."""
    if baseline != "none":
        raise UsageError(f"--uncertainty gives percentiles of absolute forces; expected "
                         f"--baseline none, got {baseline}", key="--baseline")
    return simulate_uncertainty_file(config, log, output, draws=draws, seed=seed, arm=arm,
                                     columns=columns, sd=sd, progress=progress)


# --------------------------------------------------------------------------- compare bands
def compare_bands(result, *, draws: int, seed: int = 0, sd: Optional[str] = None):
    """Monte Carlo bands of a ``phri compare`` result's simulated (zeroed) loads.

    The config's uncertain inputs (tissue stiffness, strap tension; see
    :func:`parse_sd`) are drawn ``draws`` times, the same draws for every arm, each
    arm taking what its model uses (:mod:`.uncertain_draws`: the coupled arm the
    continuum's modulus, the rigid arm no tissue), and every trial's condition-mean
    wrenches solved again; each draw's loads are zeroed on its own baseline
    condition, as :func:`phri_spring.workflows.compare.compare` does. Load-cell
    noise is left out: the wrenches are means over a steady window.

    Parameters
    ----------
    result : CompareResult
    draws, seed
    sd : str, optional
        ``tissue=from_csv|FRACTION,tension=N`` (force and moment are ignored).

    Returns
    -------
    bands : dict
        (trial index, arm) -> ndarray (3, c, n) of the 5/50/95th percentiles [N].
    table : pandas.DataFrame
        experiment, direction, trial, condition, arm, location, measured_N,
        simulated_N, sim_p5_N, sim_p50_N, sim_p95_N, perturbed (what scattered for
        the row's arm; ``none``: the band is the prediction itself).
    """
    import pandas as pd

    if int(draws) < 2:
        raise UsageError(f"expected at least 2 draws, got {draws}", key="--uncertainty")
    cfg = result.config
    kw = parse_sd(sd)
    kw["force_sd_N"] = kw["moment_sd_Nm"] = 0.0
    inputs = uncertain_inputs(cfg, **kw)
    cfgs = draw_configs(cfg, inputs, int(draws), seed)
    check_fe_cache(cfg, inputs, result.arms)
    W = np.vstack([tc.cuff_wrench for tc in result.trials])
    bounds = np.cumsum([0] + [len(tc.conditions) for tc in result.trials])
    bands, rows = {}, []
    q = np.array(PERCENTILES)
    for arm in result.arms:
        perturbed = perturbed_text(cfg, inputs, arm, noise=False)
        F = np.empty((len(cfgs), len(W), cfg.n_elements))
        if reaches_model(cfg, inputs, arm):
            for d, c in enumerate(cfgs):
                F[d] = solve(model_from_config(c, arm), W,
                             max_iterations=cfg.max_iterations).forces
        else:       # nothing this arm uses scatters: every draw is the config itself
            F[:] = solve(model_from_config(cfg, arm), W, max_iterations=cfg.max_iterations).forces
        for t, tc in enumerate(result.trials):
            Ft = F[:, bounds[t]:bounds[t + 1]]
            Z = Ft - Ft[:, tc.baseline_index][:, None, :]
            P = np.nanpercentile(Z, q, axis=0) if np.isnan(Z).any() else np.percentile(Z, q,
                                                                                       axis=0)
            bands[(t, arm)] = P
            for i, cond in enumerate(tc.conditions):
                for j, lab in enumerate(cfg.labels):
                    rows.append({"experiment": tc.spec.experiment,
                                 "direction": tc.spec.direction, "trial": tc.spec.trial,
                                 "condition": cond, "arm": arm, "location": lab,
                                 "measured_N": tc.measured[i, j],
                                 "simulated_N": tc.simulated[arm][i, j],
                                 "sim_p5_N": P[0, i, j], "sim_p50_N": P[1, i, j],
                                 "sim_p95_N": P[2, i, j], "perturbed": perturbed})
    return bands, pd.DataFrame(rows)


def write_compare_bands(result, bands, table, outdir, *, figures: bool = True,
                        dpi: int = 150) -> list:
    """Write ``bands.csv`` and ``bands/<trial>.png`` into a compare output folder (atomically)."""
    from ..io.atomic import atomic_file
    from ..reports.compare_figures import save_figure
    from ..reports.uncertainty_figures import bands_figure

    outdir = Path(outdir)
    files = []
    with atomic_file(outdir / "bands.csv") as tmp:
        table.to_csv(tmp, index=False, float_format="%.6f")
    files.append(outdir / "bands.csv")
    if figures:
        (outdir / "bands").mkdir(exist_ok=True)
        for t, tc in enumerate(result.trials):
            fig = bands_figure(tc.measured, {arm: bands[(t, arm)] for arm in result.arms},
                               conditions=tc.conditions, labels=result.labels,
                               baseline_index=tc.baseline_index,
                               title=f"{tc.spec.experiment} {tc.spec.direction} trial "
                                     f"{tc.spec.trial}: zeroed loads, model 5-95 % band")
            name = f"{tc.spec.experiment}_{tc.spec.direction}_{tc.spec.trial}".replace(" ", "_")
            path = outdir / "bands" / f"{name}.png"
            with atomic_file(path) as tmp:
                save_figure(fig, tmp, dpi=dpi)
            files.append(path)
    return files
