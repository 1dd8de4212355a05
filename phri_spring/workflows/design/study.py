"""``phri design``: parameter studies of a cuff over a load set, with Pareto fronts.

A design is the study's base config (its YAML mapping) with the varied values
put at their dotted paths, validated by the config schema itself. Each design
is simulated over the whole load set with the vectorised solver (one pass per
design), and reduced to every objective of the objectives table,
:data:`phri_spring.objectives.OBJECTIVE_TABLE` (name, unit, sense, definition).

This module runs a study and writes its outputs; each other job is a module
of its own, and their public names are re-exported here:

- :mod:`~phri_spring.workflows.config_paths`: editing a config by dotted path;
- :mod:`~phri_spring.workflows.design.plan`: the plan (every design's values
  and validated config);
- :mod:`~phri_spring.workflows.design.objectives`: the load set (identical
  rows merged, exact), the objectives of a design, the Pareto mask;
- :mod:`~phri_spring.workflows.design.resume`: the finished batches kept for
  resuming;
- :mod:`phri_spring.reports.design.report`: report.md.
"""

from __future__ import annotations

import copy
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from ...errors import UsageError
from ...io.outputs.atomic import atomic_file, check_output_path
from ...io.config.study import OBJECTIVES, Study, load_study
from ...reports.design.report import design_report
from ...reports.tissue_law_text import designs_law_text, is_nonlinear
from ..common import ARM_MODELS
from .objectives import (LoadSet, evaluate_batch, evaluate_design, load_set,
                                pareto_mask, weighted_percentile)
from .plan import build_designs, design_mapping, design_values
from .resume import STATE_DIR, BatchState, batch_size, fingerprint, split_batches

__all__ = ["LoadSet", "load_set", "design_values", "design_mapping", "build_designs",
           "evaluate_batch", "evaluate_design", "pareto_mask", "weighted_percentile",
           "run_study", "StudyResult", "STATE_DIR"]


# --------------------------------------------------------------------------- running
@dataclass
class StudyResult:
    """What :func:`run_study` produced."""

    study: Study
    table: object                  # pandas DataFrame, one row per design
    best: int                      # design id of the best design (-1 if none is feasible)
    best_config: Optional[dict]    # its config mapping
    element_peak_kpa: np.ndarray   # (d, n)
    labels: tuple
    row_labels: tuple
    n_angles: int
    loads: LoadSet
    outdir: Path
    #: cuff.patches of the base config (a free layout: its figure is the unrolled surface)
    patches: object = None
    resumed_batches: int = 0
    total_batches: int = 0
    compute_seconds: float = 0.0   # sum over the batches computed in this run [s]
    map_seconds: float = 0.0       # wall time of running those batches [s]
    workers: int = 1
    wall_seconds: float = 0.0
    files: list = field(default_factory=list)
    uncertainty: Optional[dict] = None
    pain_threshold_kpa: float = 120.0
    #: the arm's tissue over the designs (``exponential tissue law (beta 150 1/m)``, ``linear
    #: continuum (tissue.stiffening is used by the compliant arm only)``, ...)
    tissue_law: str = ""
    #: whether some design gives a nonlinear tissue law (the summary line then names it)
    nonlinear_law: bool = False


def prepare_study(study_path) -> tuple:
    """Load a study, its base config, its load set and its designs (nothing written).

    Returns ``(study, base_config, loads, values, configs)``.
    """
    from ...io.config import load_config

    study = load_study(study_path) if not isinstance(study_path, Study) else study_path
    base = load_config(study.config)
    _check_tolerance(study, base)
    loads = load_set(study.loads, base.log_columns, group=base.log_group,
                     force_tol=study.merge_force_N, moment_tol=study.merge_moment_Nm)
    values, configs = build_designs(study, base)
    return study, base, loads, values, configs


def _check_tolerance(study: Study, base) -> None:
    """A study that names an objective defined only with a tolerance curve needs one."""
    from ...errors import ConfigError
    from ...objectives import OBJECTIVE_BY_NAME

    if base.tolerance is not None:
        return
    for name in (*study.objectives, *(c.objective for c in study.constraints)):
        if OBJECTIVE_BY_NAME[name].needs_tolerance:
            raise ConfigError(f"objective {name!r} needs a pressure-time curve: add "
                              f"tolerance: {{curve: NAME}} to the config {study.config} "
                              f"(docs/tolerance.md)", file=study.path, key=name)


def run_study(study_path, outdir, *, scheduler: Optional[str] = None,
              workers: Optional[int] = None, figures: bool = True, dpi: int = 150,
              progress: Optional[Callable[[int, int], None]] = None,
              message: Optional[Callable[[str], None]] = None) -> StudyResult:
    """Run (or resume) a study and write its outputs into ``outdir``.

    Parameters
    ----------
    study_path : path or Study
    outdir : path
        Output folder: created if missing; a folder holding the batches of the
        same study resumes from them; one holding another study is refused.
    scheduler, workers
        See :func:`phri_spring.workflows.design.executors.batch_executor`.
    figures : bool
        Write the PNG figures.
    progress : callable(done_designs, total_designs), optional
    message : callable(str), optional
        Receives one-line notes for the user (e.g. that the study resumed).

    Raises
    ------
    ConfigError, DataError, UsageError
        Before anything is written.
    """
    from .executors import batch_executor

    t_wall = time.perf_counter()
    outdir = Path(outdir)
    study, base, loads, values, configs = prepare_study(study_path)
    check_output_path(outdir, [study.path, study.config, *study.loads, *base.stiffness_files],
                      option="-o/--output", directory=True)
    if outdir.exists() and not outdir.is_dir():
        raise UsageError(f"output {str(outdir)!r} is a file; expected a folder",
                         key="-o/--output")
    bs = batch_size(study, len(configs))
    store = BatchState(outdir, fingerprint(study, base, values, loads, bs))
    batches = split_batches(configs, bs)
    done = store.finished(batches)
    todo = [(b, payload) for b, payload in batches if b not in done]
    n_total = len(configs)

    with batch_executor(scheduler, workers) as run:  # connects first: errors before writing
        store.start(n_total, len(batches))
        if done and message is not None:
            message(f"resuming: {len(done)} of {len(batches)} batches "
                    f"({sum(len(done[b]['design']) for b in done)} designs) already in "
                    f"{store.folder}; computing the other {len(todo)}")
        count = [sum(len(d["design"]) for d in done.values())]
        if progress is not None:
            progress(count[0], n_total)

        def on_result(b, res):
            store.save(b, res)
            done[b] = res
            count[0] += len(res["design"])
            if progress is not None:
                progress(count[0], n_total)

        t_map = time.perf_counter()
        # the arm's record, not its name: a worker process then imports the module that
        # registered it (its build function travels by reference), whoever registered it
        run(evaluate_batch, todo, (loads, ARM_MODELS[study.arm]), on_result=on_result)
        map_seconds = time.perf_counter() - t_map

    result = _assemble(study, base, values, configs, loads, done, outdir)
    result.tissue_law = designs_law_text(configs, study.arm)
    result.nonlinear_law = any(is_nonlinear(c) for c in configs)
    result.resumed_batches = len(batches) - len(todo)
    result.total_batches = len(batches)
    result.compute_seconds = float(sum(float(done[b]["seconds"]) for b, _ in todo))
    result.map_seconds = map_seconds
    if study.uncertainty is not None and result.best >= 0:
        from .uncertainty import study_uncertainty

        result.uncertainty = study_uncertainty(configs[result.best], loads, study.arm,
                                               study.uncertainty, study.objectives)
    write_outputs(result, figures=figures, dpi=dpi)
    result.wall_seconds = time.perf_counter() - t_wall
    return result


def _assemble(study, base, values, configs, loads, done, outdir) -> StudyResult:
    import pandas as pd

    parts = [done[b] for b in sorted(done)]
    ids = np.concatenate([p["design"] for p in parts])
    order = np.argsort(ids)
    if not np.array_equal(ids[order], np.arange(len(configs))):
        raise RuntimeError("the batches do not cover every design exactly once")
    cols = {"design": ids[order]}
    for j, p in enumerate(study.parameters):
        cols[p.path] = values[:, j]
    for name in study.objectives:
        cols[name] = np.concatenate([p[name] for p in parts])[order]
    for name in OBJECTIVES:
        if name not in cols and any(c.objective == name for c in study.constraints):
            cols[name] = np.concatenate([p[name] for p in parts])[order]
    for name in OBJECTIVES:
        if name not in cols and name in parts[0]:    # (dose_max: only with a curve)
            cols[name] = np.concatenate([p[name] for p in parts])[order]
    nc = np.concatenate([p["not_converged_samples"] for p in parts])[order]
    peaks = np.concatenate([p["element_peak_pressure_kPa"] for p in parts])[order]
    feasible = nc == 0
    for c in study.constraints:
        feasible &= np.array([c.holds(v) for v in cols[c.objective]], dtype=bool)
    F = np.column_stack([s * np.asarray(cols[o]) for o, s in zip(study.objectives,
                                                                  study.senses)])
    pareto = pareto_mask(F, feasible)
    cols["not_converged_samples"] = nc
    cols["feasible"] = feasible
    cols["pareto"] = pareto
    table = pd.DataFrame(cols)
    best = -1
    best_cfg = None
    if pareto.any():
        s = study.senses[study.objectives.index(study.best)]
        key = s * table[study.best].to_numpy()
        cand = np.flatnonzero(pareto)
        best = int(cand[np.argmin(key[cand])])        # ties: the lowest design id
        best_cfg = design_mapping(base.raw, study, values[best])
    thr = configs[best].pain_threshold_kpa if best >= 0 else base.pain_threshold_kpa
    return StudyResult(pain_threshold_kpa=thr, study=study, table=table, best=best,
                       best_config=best_cfg, element_peak_kpa=peaks, labels=tuple(base.labels),
                       row_labels=tuple(base.row_labels), n_angles=base.angle_count,
                       loads=loads, outdir=outdir, patches=base.patches)


# --------------------------------------------------------------------------- outputs
def _portable_config(cfg_raw: dict, base: Optional[Path], outdir: Path) -> dict:
    """The config mapping with stiffness-file paths (and a ``tissue.stiffening`` CSV, and
    ``geometry.scan.file``) made relative to ``outdir``."""
    raw = copy.deepcopy(cfg_raw)
    base_dir = base.parent if base is not None else Path(".")
    for sec, key in (("tissue", "stiffness"), ("cuff", "stiffness"), ("tissue", "stiffening")):
        v = raw.get(sec, {}).get(key) if isinstance(raw.get(sec), dict) else None
        if isinstance(v, str):
            src = Path(v) if Path(v).is_absolute() else base_dir / v
            try:
                raw[sec][key] = os.path.relpath(src.resolve(), outdir.resolve())
            except ValueError:  # another drive (Windows)
                raw[sec][key] = str(src.resolve())
    scan = raw.get("geometry", {}).get("scan") if isinstance(raw.get("geometry"), dict) else None
    if isinstance(scan, dict) and isinstance(scan.get("file"), str):
        src = Path(scan["file"]) if Path(scan["file"]).is_absolute() else base_dir / scan["file"]
        try:
            scan["file"] = os.path.relpath(src.resolve(), outdir.resolve())
        except ValueError:  # another drive (Windows)
            scan["file"] = str(src.resolve())
    return raw


def write_outputs(result: StudyResult, *, figures: bool = True, dpi: int = 150) -> list:
    """Write designs.csv, designs.parquet, best.yaml, report.md and the figures (atomically)."""
    import yaml

    out = result.outdir
    files = []
    with atomic_file(out / "designs.csv") as tmp:
        result.table.to_csv(tmp, index=False, float_format="%.10g")
    files.append(out / "designs.csv")
    with atomic_file(out / "designs.parquet") as tmp:
        result.table.to_parquet(tmp, index=False)
    files.append(out / "designs.parquet")
    for name in ("uncertainty_objectives.csv", "uncertainty_patches.csv", "sobol.csv"):
        if result.uncertainty is None or name not in result.uncertainty["tables"]:
            (out / name).unlink(missing_ok=True)    # from an earlier run of this study
    if result.uncertainty is not None:
        for name, df in result.uncertainty["tables"].items():
            with atomic_file(out / name) as tmp:
                df.to_csv(tmp, index=False, float_format="%.10g")
            files.append(out / name)
    if result.best_config is not None:
        raw = _portable_config(result.best_config, result.study.config, out)
        head = (f"# best design {result.best} of the study "
                f"{result.study.path.name if result.study.path else ''} "
                f"(phri design); a complete config for phri simulate\n")
        with atomic_file(out / "best.yaml") as tmp:
            tmp.write_text(head + yaml.safe_dump(raw, sort_keys=False, allow_unicode=True),
                           encoding="utf-8")
        files.append(out / "best.yaml")
    else:   # a best design of an earlier ranking of this study would contradict report.md
        (out / "best.yaml").unlink(missing_ok=True)
        (out / "best_peak_pressure.png").unlink(missing_ok=True)
    figs = []
    if figures:
        from ...reports.compare.figures import save_figure
        from ...reports.design import figures as dfig

        st = result.study
        made = [("pareto.png", "Pareto front",
                 dfig.pareto_figure(result.table, st.objectives, st.senses, best=result.best)),
                ("objectives_vs_parameters.png", "Objectives against parameters",
                 dfig.objectives_vs_parameters_figure(result.table,
                                                      [p.path for p in st.parameters],
                                                      st.objectives))]
        lay = result.patches
        if result.best >= 0 and lay is not None:
            from ...reports.layout_figures import layout_figure

            made.append(("best_peak_pressure.png", "Peak pressure of the best design",
                         layout_figure(lay.x, lay.theta, lay.width, lay.length,
                                       result.element_peak_kpa[result.best],
                                       labels=lay.labels, value_label="peak pressure [kPa]",
                                       title=f"Best design {result.best}: peak pressure over "
                                             "the load set [kPa]")))
        elif result.best >= 0:
            made.append(("best_peak_pressure.png", "Peak pressure of the best design",
                         dfig.peak_pressure_heatmap_figure(
                             result.element_peak_kpa[result.best], row_labels=result.row_labels,
                             n_angles=result.n_angles,
                             pain_threshold_kpa=result.pain_threshold_kpa,
                             title=f"Best design {result.best}: peak pressure over the load "
                                   "set [kPa]")))
        for name, caption, fig in made:
            with atomic_file(out / name) as tmp:
                save_figure(fig, tmp, dpi=dpi)
            files.append(out / name)
            figs.append((name, caption))
    with atomic_file(out / "report.md") as tmp:
        tmp.write_text(design_report(result, figs), encoding="utf-8")
    files.append(out / "report.md")
    result.files = files
    return files
