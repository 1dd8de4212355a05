"""``phri design``: parameter studies of a cuff over a load set (Pareto front, best design)."""

from __future__ import annotations

import click

from ._common import StderrProgress, info, progress_enabled, warn


class _DesignProgress(StderrProgress):
    def __call__(self, done: int, total: int | None) -> None:
        if not self.enabled:
            return
        import sys

        pct = int(100 * done / total) if total else 0
        if pct == self._last:
            return
        self._last = pct
        sys.stderr.write(f"\r{self.label}: {pct:3d}% ({done:,} / {total:,} designs)")
        sys.stderr.flush()


@click.command("design", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("study", metavar="STUDY")
@click.option("-o", "--output", required=True, metavar="OUTDIR",
              help="Folder to write (created). Run the same study into it again to resume "
                   "an interrupted run.")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run on dask: the address of a running dask.distributed scheduler "
                   "(tcp://host:8786), or local:N for a LocalCluster of N workers. "
                   "Default: a local process pool.")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Processes of the local pool (default: one per core).")
@click.option("--no-figures", is_flag=True, help="Write the tables, best.yaml and report.md only.")
@click.option("--dpi", type=click.IntRange(min=50, max=600), default=150, show_default=True,
              help="Resolution of the PNG figures [dots per inch].")
@click.option("--progress/--no-progress", default=None,
              help="Progress on stderr (default: only when stderr is a terminal).")
@click.option("-q", "--quiet", is_flag=True, help="No summary line.")
def design(study, output, scheduler, workers, no_figures, dpi, progress, quiet):
    """Evaluate every design of STUDY over its load set; write the Pareto set and the best.

    STUDY is a YAML file naming a base config, wrench logs, the config values
    to vary by their dotted paths, a plan (grid, lhs:N, sobol:N) and the
    objectives (paths inside are relative to the study file):

    \b
      config: ../configs/harmony_upper_arm.yaml
      loads: [task_log.csv]
      arm: compliant
      vary:
        strap.tension: {values: [5, 10, 20, 40]}                  # N
        cuff.stiffness.per_angle: {scale: [0.25, 0.5, 1, 2, 4]}   # factor
        cuff.stiffness.per_angle[5]: {range: [1.0e5, 2.0e6], log: true}
      plan: grid
      minimise: [peak_pressure_to_pain_threshold, lift_off_fraction]
      constraints: {stiffness_translational_N_per_mm: ">= 2"}

    OUTDIR gets designs.csv and designs.parquet (one row per design: design,
    the parameters, the objectives, feasible, pareto), best.yaml (a complete
    config for 'phri simulate'), pareto.png, objectives_vs_parameters.png,
    best_peak_pressure.png and report.md. See docs/design.md.

    \b
    Example:
      phri design examples/design/study.yaml -o out/design
    """
    from phri_spring.workflows.design.study import run_study

    study = _checked_study(study, scheduler, workers)
    bar = _DesignProgress("design", progress_enabled(progress))
    try:
        result = run_study(study, output, scheduler=scheduler, workers=workers,
                           figures=not no_figures, dpi=dpi,
                           progress=bar if bar.enabled else None,
                           message=lambda m: info(m, quiet))
    finally:
        bar.close()
    t = result.table
    n_bad = int((t["not_converged_samples"] > 0).sum())
    if n_bad:
        warn(f"{n_bad} designs had samples the solver did not converge on; their objectives "
             "are empty and they are infeasible (column not_converged_samples)")
    best = (f"best design {result.best} ({result.study.best} = "
            f"{t[result.study.best].iloc[result.best]:.4g}) -> {result.outdir / 'best.yaml'}"
            if result.best >= 0 else "no feasible design (best.yaml not written)")
    law = (f"; {result.study.arm} arm: {result.tissue_law}"
           if result.nonlinear_law and result.study.arm != "rigid" else "")
    info(f"wrote {result.outdir} ({len(t):,} designs over {result.loads.n_samples:,} samples, "
         f"{int(t['feasible'].sum()):,} feasible, {int(t['pareto'].sum()):,} on the Pareto "
         f"front{law}); {best}; see {result.outdir / 'report.md'}", quiet)


def _checked_study(path, scheduler, workers):
    """The loaded study, after checking that its designs (every design's config is kept)
    and the local workers (each evaluates one design over the whole load set) fit in memory,
    before any design is made or anything written."""
    from phri_spring.io.config import load_config
    from phri_spring.io.logs import count_rows
    from phri_spring.io.config.study import load_study
    from phri_spring.workflows.design.executors import default_workers, parse_scheduler
    from phri_spring.io.memory.budget import check_design

    study = load_study(path)
    base = load_config(study.config)
    kind, n_local = parse_scheduler(scheduler)
    local = {"pool": workers or default_workers(), "local": n_local}.get(kind, 0)
    samples = sum(count_rows(f, base.log_group, columns=base.log_columns) or 0
                  for f in study.loads)
    check_design(study, base, local, samples)
    return study
