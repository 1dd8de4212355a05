"""``phri compare`` as library calls: rigid- vs compliant-arm predictions against a sensorized cuff.

Method (docs/model.md section 7, paper sections III-C and IV-B):

1. Every trial table is reduced to one mean wrench and one mean load per
   element for each condition (all rows of that condition).
2. For each arm model (``rigid``, ``compliant``) the spring network is solved
   at each condition's mean wrench (converted from load-cell readings to the
   cuff wrench with the config's load-cell pose, units and convention). The
   compliant arm runs the config's tissue law (``tissue.law``, ``tissue.stiffening``);
   the coupled arm's continuum is linear, and the report says so.
3. Zeroing, each side on its own baseline: measured loads minus the measured
   loads of the trial's baseline condition; simulated loads minus the
   simulated loads at the baseline condition's mean wrench.
4. Per trial, condition and arm: RMSE = sqrt(sum_e (F_expt,e - F_sim,e)^2 / N)
   over the N elements (paper Eq. 1).
5. Per experiment, direction, condition and arm: mean RMSE over trials and its
   standard error (sample SD, ddof = 1, / sqrt(n)).

The baseline condition is left out of the RMSE tables and figures (its zeroed
loads are 0 on both sides by construction, so its RMSE is 0, and the paper's
Fig. 7 shows only the loaded conditions); it stays in ``loads.csv`` and
``conditions.csv``.

- :func:`compare` does the analysis and returns a :class:`CompareResult`.
- :func:`write_compare` writes its tables, figures and ``report.md``
  (:mod:`phri_spring.reports.compare.report`) into a folder atomically (a
  failed run leaves no folder behind).
- ``--uncertainty``: the Monte Carlo bands are :mod:`.compare_bands`.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence, Union

import numpy as np

from ...errors import ConvergenceError, DataError, UsageError
from ...io.outputs.atomic import atomic_directory, check_output_path, naming
from ...io.config import Config, load_config, resolve_stiffness
from ...io.recordings.experiment import WRENCH_COLUMNS, Manifest, TrialData, load_manifest, read_trial
from ...io.logs import reader_options
from ...physics.response.metrics import mean_and_se, rmse as rmse_eq1, zero_on
from ...physics.contact.solver import solve_segments
from ...reports.compare.report import compare_report, summary_markdown as _summary_table
from ...io.config.tolerance import curve_option
from ..common import ARM_MODELS, cuff_wrench, model_from_config
from ..columns.tolerance import compare_exposure, compare_exposure_markdown

__all__ = ["compare", "write_compare", "CompareResult", "TrialComparison", "CompareOutputs",
           "parse_arms", "summary_markdown", "DEFAULT_ARMS", "RMSE_COLUMNS", "SUMMARY_COLUMNS"]

#: the arm models compared by default, in the paper's order
DEFAULT_ARMS = ("rigid", "compliant")
#: columns of rmse.csv (docs/model.md section 8), then load_N
RMSE_COLUMNS = ("experiment", "direction", "condition", "trial", "arm", "rmse_N")
#: columns of summary.csv (docs/model.md section 8), then load_N
SUMMARY_COLUMNS = ("experiment", "direction", "condition", "arm", "mean_rmse_N", "se_rmse_N",
                   "n_trials")


def parse_arms(arms: Union[str, Sequence[str], None]) -> tuple:
    """``"rigid,compliant"`` or a sequence -> a tuple of distinct arm names.

    Raises
    ------
    UsageError
        For an unknown, repeated or missing arm (key ``--arms``).
    """
    if arms is None:
        return DEFAULT_ARMS
    items = [a.strip() for a in arms.split(",")] if isinstance(arms, str) else \
        [str(a).strip() for a in arms]
    items = [a for a in items if a]
    if not items:
        raise UsageError(f"expected at least one of {', '.join(ARM_MODELS)}", key="--arms")
    for a in items:
        if a not in ARM_MODELS:
            raise UsageError(f"unknown arm model {a!r}; expected a comma-separated list of "
                             f"{', '.join(ARM_MODELS)}", key="--arms")
    if len(set(items)) != len(items):
        raise UsageError(f"arm models repeated in {','.join(items)}; expected each once",
                         key="--arms")
    return tuple(items)


@dataclass(eq=False)
class TrialComparison:
    """One trial's conditions, measured and simulated (c conditions, n elements).

    Attributes
    ----------
    data : TrialData
        The trial's condition means as read.
    measured : ndarray, shape (c, n)
        Zeroed measured loads [N].
    simulated : dict of str -> ndarray, shape (c, n)
        Zeroed simulated loads [N] per arm model.
    simulated_abs : dict of str -> ndarray, shape (c, n)
        Absolute simulated loads [N] (preload included) per arm model.
    rmse : dict of str -> ndarray, shape (c,)
        RMSE [N] per arm model (0 at the baseline).
    cuff_wrench : ndarray, shape (c, 6)
        Mean wrench on the cuff [N, N*m], cuff frame.
    load_n : ndarray, shape (c,)
        ``|mean force - baseline's mean force|`` [N].
    """

    data: TrialData
    measured: np.ndarray
    simulated: dict
    simulated_abs: dict
    rmse: dict
    cuff_wrench: np.ndarray
    load_n: np.ndarray

    @property
    def spec(self):
        return self.data.spec

    @property
    def conditions(self) -> tuple:
        return self.data.conditions

    @property
    def baseline_index(self) -> int:
        return self.data.baseline_index

    @property
    def zeroed_wrench(self) -> np.ndarray:
        """Mean load-cell reading minus the baseline's (log units), shape (c, 6)."""
        return self.data.wrench - self.data.wrench[self.baseline_index]


@dataclass(eq=False)
class CompareResult:
    """Everything :func:`compare` computed.

    DataFrames (units in the column names):

    - ``rmse``: experiment, direction, condition, trial, arm, rmse_N, load_N
    - ``summary``: experiment, direction, condition, arm, mean_rmse_N,
      se_rmse_N, n_trials, load_N
    - ``loads``: one row per trial, condition and element (baseline included):
      zeroed and absolute measured and simulated loads and the condition's mean wrench
    - ``conditions``: one row per trial and condition (baseline included):
      samples, mean and zeroed wrench, load_N and the RMSE of each arm
    """

    config: Config
    manifest: Manifest
    arms: tuple
    trials: list
    rmse: "object"
    summary: "object"
    loads: "object"
    conditions: "object"
    tissue_stiffness_file: Optional[Path] = None
    input_paths: tuple = field(default_factory=tuple)
    #: with a tolerance curve: the curve and every element's predicted exposure per trial
    #: and arm (workflows/tolerance_extras.py, docs/tolerance.md); None without
    tolerance: Optional[object] = None
    exposure: "object" = None

    @property
    def labels(self) -> tuple:
        return tuple(self.config.labels)


@dataclass
class CompareOutputs:
    """What :func:`write_compare` wrote (paths inside ``outdir``)."""

    outdir: Path
    files: list


def _with_tissue(cfg: Config, tissue_stiffness) -> Config:
    path = Path(tissue_stiffness)
    if not path.is_file():
        raise DataError("file not found; expected a tissue stiffness CSV written by "
                        "'phri fit-stiffness'", file=path, key="--tissue-stiffness")
    k = resolve_stiffness(str(path.resolve()), cfg.n_rows, cfg.angle_count, cfg.labels,
                          path=path, key="--tissue-stiffness", allow_inf=False)
    return dataclasses.replace(cfg, tissue_stiffness=k, tissue_basis="indenter",
                               tissue_stiffness_csv=Path(path))


def compare(config, manifest, *, arms: Union[str, Sequence[str], None] = DEFAULT_ARMS,
            tissue_stiffness=None, columns: Optional[dict] = None,
            group: Optional[str] = None, tolerance=None) -> CompareResult:
    """Compare the arm models' predictions (rigid, compliant, coupled) with a sensorized-cuff experiment.

    Parameters
    ----------
    config : Config or path
        The model config (geometry, load cell, stiffness, strap).
    manifest : Manifest or path
        The experiment manifest (YAML; see :mod:`phri_spring.io.recordings.experiment`).
    arms : str or sequence of str
        Arm models to compare, among ``rigid`` and ``compliant``.
    tissue_stiffness : path, optional
        A ``phri fit-stiffness`` CSV (indenter basis) replacing the config's
        tissue stiffness map.
    columns : dict, optional
        Map from spec names (``time``, ``Fx`` ...) to the trial tables' names;
        merged over the config's ``load_cell.columns``.
    group : str, optional
        TDMS and MAT trial tables: the group or struct holding the channels;
        default the config's ``load_cell.group``.
    tolerance : ToleranceCurve or str, optional
        Default the config's ``tolerance.curve``: also every element's predicted
        exposure against that curve (``exposure``).

    Returns
    -------
    CompareResult

    Raises
    ------
    ConfigError, DataError
        Bad config, manifest or trial data (one line naming the file and the
        key, column or condition).
    ConvergenceError
        If the solver fails at some condition's wrench.
    UsageError
        For unknown arm models.
    """
    import pandas as pd

    arms = parse_arms(arms)
    cfg = config if isinstance(config, Config) else load_config(config)
    tissue_file = None
    if tissue_stiffness is not None:
        tissue_file = Path(tissue_stiffness)
        cfg = _with_tissue(cfg, tissue_file)
    man = manifest if isinstance(manifest, Manifest) else load_manifest(manifest)
    models = {arm: model_from_config(cfg, arm) for arm in arms}
    colmap, group = reader_options(cfg, columns, group)
    datas = [read_trial(t, cfg.labels, columns=colmap, row_labels=cfg.row_labels, group=group)
             for t in man.trials]
    if not any(len(d.conditions) > 1 for d in datas):
        raise DataError("no trial has a condition besides its baseline; nothing to compare",
                        file=man.path, key="trials")

    # one solve per arm on every condition of every trial, stacked
    W_lc = np.vstack([d.wrench for d in datas])
    W = cuff_wrench(cfg, W_lc)
    bounds = np.cumsum([0] + [len(d.conditions) for d in datas])
    sims = {}
    for arm, model in models.items():
        # with friction each trial is its own loading path (docs/model.md section 12.2)
        sol = solve_segments(model, W, bounds, max_iterations=cfg.max_iterations)
        if not np.all(sol.converged):
            i = int(np.argmin(sol.converged))
            t = int(np.searchsorted(bounds, i, side="right") - 1)
            d = datas[t]
            raise ConvergenceError(f"the {arm}-arm solver did not converge at the mean wrench of "
                                   f"condition {d.conditions[i - bounds[t]]!r} "
                                   f"(W = {np.round(W[i], 4).tolist()})", file=d.spec.file,
                                   key="condition")
        sims[arm] = sol.forces

    trials = []
    for t, d in enumerate(datas):
        sl = slice(bounds[t], bounds[t + 1])
        b = d.baseline_index
        meas = zero_on(d.loads, d.loads[b])
        sim_abs = {arm: sims[arm][sl] for arm in arms}
        sim = {arm: zero_on(f, f[b]) for arm, f in sim_abs.items()}
        err = {arm: rmse_eq1(meas, s) for arm, s in sim.items()}
        Wc = W[sl]
        load = np.linalg.norm(Wc[:, :3] - Wc[b, :3], axis=1)
        trials.append(TrialComparison(data=d, measured=meas, simulated=sim, simulated_abs=sim_abs,
                                      rmse=err, cuff_wrench=Wc, load_n=load))

    rmse_df = _rmse_frame(trials, arms, pd)
    summary_df = _summary_frame(rmse_df, arms, pd)
    loads_df = _loads_frame(trials, arms, cfg, pd)
    cond_df = _conditions_frame(trials, arms, pd)
    inputs = [cfg.path, man.path] + [t.file for t in man.trials]
    if tissue_file is not None:
        inputs.append(tissue_file)
    curve = curve_option(tolerance, cfg)
    return CompareResult(config=cfg, manifest=man, arms=arms, trials=trials, rmse=rmse_df,
                         summary=summary_df, loads=loads_df, conditions=cond_df,
                         tissue_stiffness_file=tissue_file,
                         input_paths=tuple(p for p in inputs if p is not None),
                         tolerance=curve, exposure=None if curve is None
                         else compare_exposure(trials, models, curve))


# --------------------------------------------------------------------------- tables
def _rmse_frame(trials, arms, pd):
    rows = []
    for tc in trials:
        s = tc.spec
        for j, c in enumerate(tc.conditions):
            if j == tc.baseline_index:
                continue
            for arm in arms:
                rows.append((s.experiment, s.direction, c, s.trial, arm, float(tc.rmse[arm][j]),
                             float(tc.load_n[j])))
    return pd.DataFrame(rows, columns=list(RMSE_COLUMNS) + ["load_N"])


def _summary_frame(rmse_df, arms, pd):
    rows = []
    if len(rmse_df):
        groups = list(dict.fromkeys(zip(rmse_df["experiment"], rmse_df["direction"])))
        for exp, direc in groups:
            g = rmse_df[(rmse_df["experiment"] == exp) & (rmse_df["direction"] == direc)]
            for cond in dict.fromkeys(g["condition"]):
                gc = g[g["condition"] == cond]
                for arm in arms:
                    v = gc.loc[gc["arm"] == arm, "rmse_N"].to_numpy(dtype=float)
                    mean, se = mean_and_se(v)
                    load = float(np.mean(gc.loc[gc["arm"] == arm, "load_N"]))
                    rows.append((exp, direc, cond, arm, float(mean), float(se), int(v.size), load))
    return pd.DataFrame(rows, columns=list(SUMMARY_COLUMNS) + ["load_N"])


def _loads_frame(trials, arms, cfg, pd):
    n = len(cfg.labels)
    n_ang = cfg.angle_count
    parts = []
    for tc in trials:
        s, d = tc.spec, tc.data
        c = len(tc.conditions)
        rep = np.repeat(np.arange(c), n)
        cols = {
            "experiment": np.full(c * n, s.experiment, dtype=object),
            "direction": np.full(c * n, s.direction, dtype=object),
            "trial": np.full(c * n, s.trial, dtype=object),
            "condition": np.asarray(tc.conditions, dtype=object)[rep],
            "is_baseline": rep == tc.baseline_index,
            "element": np.tile(np.asarray(cfg.labels, dtype=object), c),
            "row": np.tile(np.repeat(np.asarray(cfg.row_labels, dtype=object), n_ang), c),
            "location": np.tile(np.tile(np.arange(n_ang), cfg.n_rows), c),
            "measured_N": tc.measured.ravel(),
        }
        for arm in arms:
            cols[f"{arm}_N"] = tc.simulated[arm].ravel()
        cols["measured_abs_N"] = d.loads.ravel()
        for arm in arms:
            cols[f"{arm}_abs_N"] = tc.simulated_abs[arm].ravel()
        for k, name in enumerate(WRENCH_COLUMNS):
            cols[name] = d.wrench[rep, k]
        cols["load_N"] = tc.load_n[rep]
        cols["n_samples"] = d.n_samples[rep]
        parts.append(pd.DataFrame(cols))
    df = pd.concat(parts, ignore_index=True)
    if all(isinstance(tc.spec.trial, int) for tc in trials):
        df["trial"] = df["trial"].astype(np.int64)
    return df


def _conditions_frame(trials, arms, pd):
    rows = []
    for tc in trials:
        s, d = tc.spec, tc.data
        zw = tc.zeroed_wrench
        for j, c in enumerate(tc.conditions):
            row = {"experiment": s.experiment, "direction": s.direction, "trial": s.trial,
                   "condition": c, "is_baseline": j == tc.baseline_index,
                   "n_samples": int(d.n_samples[j])}
            row.update({name: float(d.wrench[j, k]) for k, name in enumerate(WRENCH_COLUMNS)})
            row.update({f"{name}_zeroed": float(zw[j, k])
                        for k, name in enumerate(WRENCH_COLUMNS)})
            row["load_N"] = float(tc.load_n[j])
            row.update({f"rmse_{arm}_N": float(tc.rmse[arm][j]) for arm in arms})
            rows.append(row)
    return pd.DataFrame(rows)


# --------------------------------------------------------------------------- report
def summary_markdown(result: CompareResult) -> str:
    """The summary as a Markdown table: one line per experiment, direction and condition.

    Columns: experiment, direction, condition, load [N], then per arm model
    ``<arm> RMSE [N]`` as mean +- standard error, and the number of trials
    (:func:`phri_spring.reports.compare.report.summary_markdown`).
    """
    return _summary_table(result.summary, result.arms)


def _rmse_rows(result: CompareResult) -> list:
    """``(experiment, direction, trial, condition, load [N], {arm: RMSE [N]})`` of every
    trial and loaded condition, for the report."""
    rows = []
    for tc in result.trials:
        s = tc.spec
        for j, c in enumerate(tc.conditions):
            if j != tc.baseline_index:
                rows.append((s.experiment, s.direction, s.trial, c, tc.load_n[j],
                             {a: tc.rmse[a][j] for a in result.arms}))
    return rows


_SAFE = re.compile(r"[^A-Za-z0-9._-]+")


def _slug(*parts) -> str:
    return "_".join(_SAFE.sub("-", str(p)).strip("-") or "x" for p in parts)


def _unique(name: str, used: set) -> str:
    out, k = name, 2
    while out in used:
        out = f"{name}-{k}"
        k += 1
    used.add(out)
    return out


def _scale(heat: dict) -> float:
    """The colour scale of a heat-map job: its largest |value| [N]."""
    vals = np.concatenate([np.ravel(heat["measured"])] +
                          [np.ravel(v) for v in heat["simulated"].values()])
    vals = vals[np.isfinite(vals)]
    return float(np.max(np.abs(vals))) if vals.size else 0.0


def _heat_title(tc: TrialComparison, j: int, cfg: Config) -> str:
    s = tc.spec
    zw = tc.zeroed_wrench[j]
    fu, mu = cfg.force_unit, cfg.moment_unit.replace("*", "·")
    return (f"{s.experiment} {s.direction}, trial {s.trial}, {tc.conditions[j]} "
            f"({tc.load_n[j]:.1f} N), zeroed on {s.baseline}\n"
            f"load-cell wrench, zeroed: Fx {zw[0]:+.2f}, Fy {zw[1]:+.2f}, Fz {zw[2]:+.2f} {fu}; "
            f"Mx {zw[3]:+.3f}, My {zw[4]:+.3f}, Mz {zw[5]:+.3f} {mu}")


def write_compare(result: CompareResult, outdir, *, figures: bool = True,
                  dpi: Optional[int] = None, workers: Optional[int] = None,
                  bands_markdown: str = "") -> CompareOutputs:
    """Write the tables, figures and report of a comparison into ``outdir``.

    Files: ``rmse.csv``, ``summary.csv``, ``loads.csv``, ``conditions.csv``,
    ``report.md`` and, with ``figures``, ``rmse_bars.png`` (Fig. 7),
    ``heatmaps/<experiment>_<direction>_<trial>_<condition>.png`` for every
    trial and non-baseline condition (Fig. 8b) and
    ``wrench/<experiment>_<direction>_<trial>.png`` (Fig. 8a) and
    ``sections/<arm>_peak.png`` (the pressure around the limb where each arm predicts
    its highest pressure).

    Everything is written into a temporary folder beside ``outdir`` that
    replaces it at the end: a failed run leaves nothing behind. The figures are
    drawn on ``workers`` processes (default: the available cores; they are
    independent, and the images do not depend on the number of processes).
    ``bands_markdown``: the report's section on ``--uncertainty``'s bands
    (:func:`.compare_bands.bands_report_section`).

    Raises
    ------
    UsageError
        If ``outdir`` is (or contains) an input, is a file, or its parent folder
        does not exist.
    """
    from ...reports.compare.figures import DEFAULT_DPI, render_figures

    dpi = DEFAULT_DPI if dpi is None else int(dpi)
    outdir = Path(outdir)
    check_output_path(outdir, result.input_paths, option="-o/--output", directory=True)
    if outdir.exists() and not outdir.is_dir():
        raise UsageError(f"output {str(outdir)!r} is a file; expected a folder",
                         key="-o/--output")
    cfg = result.config
    written = []
    fig_index = []
    with atomic_directory(outdir) as tmp:
        def csv(df, name):
            with naming(tmp / name):
                df.to_csv(tmp / name, index=False, float_format="%.10g")
            written.append(outdir / name)

        csv(result.rmse, "rmse.csv")
        csv(result.summary, "summary.csv")
        csv(result.loads, "loads.csv")
        csv(result.conditions, "conditions.csv")
        if result.exposure is not None:
            csv(result.exposure, "exposure.csv")
        if figures:
            local, jobs = [], []
            if len(result.summary):
                # drawn here: its arguments are DataFrames (not worth pickling)
                local.append(("bars", tmp / "rmse_bars.png",
                              {"summary": result.summary, "rmse": result.rmse,
                               "arms": result.arms}))
                written.append(outdir / "rmse_bars.png")
            (tmp / "heatmaps").mkdir()
            (tmp / "wrench").mkdir()
            used_h, used_w = set(), set()
            for tc in result.trials:
                s = tc.spec
                wname = _unique(_slug(s.experiment, s.direction, s.trial), used_w) + ".png"
                d = tc.data
                jobs.append(("wrench", tmp / "wrench" / wname,
                             {"time": d.time, "wrench": d.wrench_series,
                              "conditions": d.condition_series,
                              "title": f"{s.experiment} {s.direction}, trial {s.trial}: "
                                       "load-cell wrench",
                              "force_unit": cfg.force_unit, "moment_unit": cfg.moment_unit}))
                written.append(outdir / "wrench" / wname)
                heat = []
                for j, c in enumerate(tc.conditions):
                    if j == tc.baseline_index:
                        continue
                    hname = _unique(_slug(s.experiment, s.direction, s.trial, c), used_h) + ".png"
                    kw = {"measured": tc.measured[j],
                          "simulated": {a: tc.simulated[a][j] for a in result.arms},
                          "title": _heat_title(tc, j, cfg),
                          "rmse": {a: float(tc.rmse[a][j]) for a in result.arms}}
                    if cfg.patches is None:
                        jobs.append(("heatmap", tmp / "heatmaps" / hname,
                                     {**kw, "row_labels": tuple(cfg.row_labels),
                                      "n_angles": cfg.angle_count}))
                    else:   # a free layout: drawn on the unrolled limb surface
                        lay = cfg.patches
                        jobs.append(("layout", tmp / "heatmaps" / hname,
                                     {**kw, "x": lay.x, "theta": lay.theta, "width": lay.width,
                                      "length": lay.length, "labels": lay.labels}))
                    written.append(outdir / "heatmaps" / hname)
                    heat.append((c, f"heatmaps/{hname}"))
                fig_index.append((s, f"wrench/{wname}", heat))
            # this process draws from the front of the list, the workers from the back: heat
            # maps in order of their colour scale keep the figures sharing a layout together
            jobs.sort(key=lambda j: (j[0] == "heatmap", _scale(j[2]) if j[0] == "heatmap"
                                     else 0.0))
            render_figures(jobs, dpi, workers=workers, local=local)
            from ..plots.section import write_compare_sections

            written.extend(write_compare_sections(result, tmp, outdir, dpi))
        report = compare_report(
            cfg, result.manifest, arms=result.arms, n_trials=len(result.trials),
            baselines=sorted({t.spec.baseline for t in result.trials}),
            tissue_stiffness_file=result.tissue_stiffness_file, summary=result.summary,
            rmse_rows=_rmse_rows(result), figures=figures, fig_index=fig_index,
            bands_markdown=bands_markdown)
        if result.exposure is not None:
            report += compare_exposure_markdown(result.exposure, result.tolerance)
        (tmp / "report.md").write_text(report, encoding="utf-8")
        written.append(outdir / "report.md")
    return CompareOutputs(outdir=outdir, files=written)
