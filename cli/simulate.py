"""``phri simulate``: wrench log -> contact force of every cuff element."""

from __future__ import annotations

import math

import click

from ._common import ArmChoice, StderrProgress, freeze_setup, info, progress_enabled, warn


@click.command("simulate", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("config", metavar="CONFIG")
@click.argument("log", metavar="LOG")
@click.option("-o", "--output", required=True, metavar="OUT",
              help="Forces file to write: .csv or .parquet (chosen by the extension).")
@click.option("--arm", type=ArmChoice(), default="compliant",
              show_default=True,
              help="compliant: tissue and cuff springs in series; rigid: the rigid-arm "
                   "assumption (cuff springs only); coupled: the tissue as a continuum layer "
                   "on the bone (needs tissue.continuum in the config; docs/model.md section 10).")
@click.option("--shear", is_flag=True,
              help="Also write the tangential (shear) force on the arm of every element [N]: "
                   "columns A0_shear_axial_N, A0_shear_circumferential_N, ...")
@click.option("--baseline", default="none", show_default=True, metavar="SPEC",
              help="none (absolute forces, preload included) | zero (subtract the forces at "
                   "zero wrench) | first:SECONDS | window:T0:T1 (subtract the forces at the "
                   "mean wrench of that window, times in s).")
@click.option("--column", "columns", multiple=True, metavar="NAME=LOG_NAME",
              help="Map a spec column (time, Fx, Fy, Fz, Mx, My, Mz; optional activation, 0..1: the muscle under the cuff, docs/model.md section 15) to the log's name, "
                   "e.g. --column 'Fx=Fx (N)'. Repeatable; overrides load_cell.columns.")
@click.option("--group", default=None, metavar="NAME",
              help="TDMS logs: the group holding the channels; MAT logs: the struct holding "
                   "the vectors (default: load_cell.group, else the only group / top level).")
@click.option("--decimals", type=click.IntRange(min=-1, max=17), default=6, show_default=True,
              help="CSV output: decimals of forces [N] and pressures [kPa] (6 = 1 uN); "
                   "-1 keeps every digit. Parquet always keeps full precision.")
@click.option("--plot", "plot", default=None, metavar="FILE",
              help="Also draw the whole log at a glance (.png, .svg or .pdf): peak pressure "
                   "[kPa] with the pain threshold, and every element's force [N] as a heat "
                   "map, both max-pooled over time (no peak lost; bounded memory); and, "
                   "in FILE's stem + '_section', the pressure around the limb in the sample "
                   "of the peak, row by row.")
@click.option("--tolerance", default=None, metavar="CURVE",
              help="Judge how long each element is pressed against a pressure-time curve "
                   "(linder_ganz_2006, reswick_rogers_1976, cuff_calf_pain_2001, ...; "
                   "docs/tolerance.md): adds the columns dose_max [-] and dose_element and "
                   "writes every element's time above the thresholds to OUT's stem + "
                   "'_exposure.csv'. Default: the config's tolerance.curve, else none.")
@click.option("--chunk-rows", type=click.IntRange(min=1), default=65536, show_default=True,
              help="Samples per chunk (bounds memory on long logs); a hint: fewer rows are "
                   "used on fine meshes and when the machine's memory is short.")
@click.option("--progress/--no-progress", default=None,
              help="Progress on stderr (default: only when stderr is a terminal).")
@click.option("--uncertainty", type=click.IntRange(min=2), default=None, metavar="N",
              help="Monte Carlo with N draws: OUT gets the 5/50/95th percentiles of each "
                   "element's force instead (docs/design.md); with a tolerance curve, also "
                   "those of dose_max over the draws.")
@click.option("--uncertainty-sd", default=None, metavar="LIST",
              help="SDs of the draws: tissue=from_csv|FRACTION (k0), stiffening=from_csv|"
                   "FRACTION (the exponential law's beta), tension=N, force=N, moment=N*m "
                   "(default tissue=from_csv, stiffening=from_csv, the others 0).")
@click.option("--seed", type=int, default=0, show_default=True,
              help="Seed of the Monte Carlo draws.")
@click.option("-q", "--quiet", is_flag=True, help="No summary line.")
def simulate(config, log, output, arm, shear, baseline, columns, group, decimals, plot,
             chunk_rows, progress, quiet, uncertainty=None, uncertainty_sd=None, seed=0,
             tolerance=None):
    """Predict the normal force [N] on every cuff element for each sample of LOG.

    CONFIG is a YAML config (see configs/harmony_upper_arm.yaml). LOG is a CSV
    or Parquet wrench log with columns time [s], Fx Fy Fz [N or lbf], Mx My Mz
    [N*m or N*mm] as the load cell reads them (units and axes set in the
    config's load_cell section), or a lab file with channels of those names:
    TDMS (time from a time channel or the waveform timing) or MATLAB .mat
    (needs the lab extra: pip install -e '.[lab]').

    OUT gets time [s], one column per element (A0 ... C6) with the normal
    force [N], then contacts_in_touch, peak_pressure_kPa,
    peak_pressure_element, peak_pressure_to_pain_threshold [-],
    solver_iterations and converged; with a tolerance curve (--tolerance or
    tolerance.curve), also dose_max [-] and dose_element; with strap.model:
    band, also strap_tension_N and strap_pressure_kPa.

    \b
    Example:
      phri simulate configs/harmony_upper_arm.yaml examples/wrench_log.csv \\
          -o forces.csv --baseline first:2
    """
    from phri_spring.io.logs import parse_column_map
    from phri_spring.workflows.simulate import parse_baseline, simulate_file

    colmap = parse_column_map(columns)
    if group is not None:
        from phri_spring.errors import UsageError
        from phri_spring.io.logs.lab import lab_format

        if lab_format(log) is None:
            raise UsageError("--group applies to .tdms and .mat logs only", key="--group")
    base = parse_baseline(baseline)
    if tolerance is not None:
        from phri_spring.io.config.tolerance import curve_option

        curve_option(tolerance)       # an unknown name is refused before anything is read
    if uncertainty is not None:
        from phri_spring.workflows.uncertainty.run import run_cli
        if base.kind == "none":   # (run_cli refuses any other baseline with its own line)
            config = _check_draws(config, log, output, arm, colmap, group, uncertainty,
                                  uncertainty_sd)
        bar = StderrProgress("simulate --uncertainty", progress_enabled(progress))
        try:
            run = run_cli(config, log, output, arm, str(base), colmap, uncertainty,
                          uncertainty_sd, seed, progress=bar if bar.enabled else None,
                          group=group, tolerance=tolerance)
        finally:
            bar.close()
        info(run.summary_line(), quiet)
        return
    pool = None
    if plot is not None:
        from phri_spring.io.config import load_config
        from phri_spring.io.logs import count_rows, reader_options
        from phri_spring.workflows.plots.maxpool import MaxPool, check_plot_path

        check_plot_path(plot, [log, config, output])
        from phri_spring.workflows.plots.section import section_path

        section = check_plot_path(section_path(plot), [log, config, output])
        config = load_config(config)
        from phri_spring.io.config.tolerance import curve_option
        from phri_spring.workflows.columns.tolerance import exposure_plot_path

        exposure_plot = None
        if curve_option(tolerance, config) is not None:
            exposure_plot = check_plot_path(exposure_plot_path(plot), [log, config.path, output])
        # the pool and its figure hold about 2,000 groups per element: check before making it
        from phri_spring.io.logs import table_format
        from phri_spring.io.memory.budget import plan_stream

        cols_read, group_read = reader_options(config, colmap, group)
        plan_stream(config, arm, chunk_rows, shear=shear, plot=True, log=log,
                    output_format=table_format(output, role="output", option="-o/--output"),
                    columns=cols_read, group=group_read)
        pool = MaxPool(len(config.labels), total=count_rows(log, group_read))
    bar = StderrProgress("simulate", progress_enabled(progress))
    freeze_setup()
    try:
        summary = simulate_file(config, log, output, arm=arm, baseline=base, columns=colmap,
                                group=group, shear=shear,
                                chunk_rows=chunk_rows, decimals=decimals,
                                progress=bar if bar.enabled else None, on_chunk=pool,
                                tolerance=tolerance)
    finally:
        bar.close()
    if pool is not None:
        from pathlib import Path

        from phri_spring.workflows.plots.maxpool import write_simulate_plot

        pooled = pool.result()
        write_simulate_plot(pooled, plot, labels=summary.labels,
                            pain_threshold_kpa=config.pain_threshold_kpa,
                            title=f"{Path(log).name}: {arm} arm", layout=config.patches)
        if exposure_plot is not None and summary.exposure is not None:
            from phri_spring.workflows.columns.tolerance import write_exposure_plot

            write_exposure_plot(summary.exposure, summary.labels, exposure_plot,
                                title=f"{Path(log).name}: {arm} arm, exposure against "
                                      f"{summary.exposure.curve.name}")
        if pooled.peak_forces is not None:
            from phri_spring.workflows.plots.section import write_section_plot

            write_section_plot(config, pooled.peak_forces, section,
                               title=f"{Path(log).name}: {arm} arm, the sample of the peak "
                                     f"pressure (t = {pooled.peak_time:g} s)")
    if summary.not_converged and summary.friction_coefficient is not None:
        warn(no_answer_text(summary))
    elif summary.not_converged:
        warn(f"the solver did not converge for {summary.not_converged:,} of "
             f"{summary.samples:,} samples; their forces are NaN (column 'converged')")
    if math.isfinite(summary.max_peak_pressure_kpa):
        peak = (f"peak pressure {summary.max_peak_pressure_kpa:.4g} kPa at "
                f"{summary.max_peak_element}, t = {summary.max_peak_time:g} s "
                f"({100 * summary.max_pain_ratio:.3g}% of the pain threshold)")
    else:
        peak = "no converged sample, no peak pressure"
    law = summary.law_text if getattr(summary, "law_text", None) is not None \
        else _law_clause(config, arm)
    mu = summary.friction_coefficient
    contact = f", friction mu = {mu:g}" if mu is not None else ""
    if summary.max_strap_tension_n is not None:
        peak += f"; largest strap tension {summary.max_strap_tension_n:.4g} N"
    if summary.exposure is not None:
        from phri_spring.workflows.columns.tolerance import exposure_text

        peak += f"; {exposure_text(summary.labels, summary.exposure)} ({summary.exposure_table})"
    info(f"wrote {summary.output} ({summary.samples:,} samples, {len(summary.labels)} elements, "
         f"{arm} arm{law}{contact}, baseline {base}); {peak}; {load_path_text(summary)}; "
         f"solver {summary.mean_iterations:.2f} "
         f"solves/sample on average" + (f"; plot {plot}" if plot else ""), quiet)


def _law_clause(config, arm) -> str:
    """The summary's clause on the tissue law: ``, exponential tissue law (beta 150 1/m)``;
    for the coupled arm, that its continuum is linear when the config gives a nonlinear
    law; nothing for the linear law and the rigid arm."""
    from phri_spring.io.config import Config, load_config
    from phri_spring.workflows.simulate import law_clause

    return law_clause(config if isinstance(config, Config) else load_config(config), arm)


def no_answer_text(summary) -> str:
    """The warning of a run with friction where some samples have no answer: their share,
    by reason, and the worst (docs/model.md section 12.7)."""
    share = 100.0 * summary.not_converged / max(summary.samples, 1)
    reasons = ", ".join(f"{count:,} {reason}" for reason, count in
                        sorted(summary.no_answer_reasons.items(), key=lambda kv: -kv[1]))
    text = (f"{summary.not_converged:,} of {summary.samples:,} samples ({share:.3g}%) have no "
            f"equilibrium with friction mu = {summary.friction_coefficient:g}"
            + (f" ({reasons})" if reasons else "")
            + "; their forces are NaN (columns 'converged', 'no_equilibrium_reason')")
    worst = summary.worst_no_answer
    if worst is not None:
        reason, t, value, unit = worst
        short = f", {value:.4g} {unit} short" if math.isfinite(value) else ""
        text += f"; worst: {reason} at t = {t:g} s{short}"
    return text


def load_path_text(summary) -> str:
    """The summary's clause on what the cuff passes to the skin, by kind (docs/model.md
    section 12.4): shares of the summed force magnitudes over the log, adding up to 100 %."""
    if not all(math.isfinite(x) for x in summary.load_shares):
        return "no force passed to the skin"
    normal, tangential, lifted = percent_parts(summary.load_shares)
    kind = "friction" if summary.friction_coefficient is not None else "bonded ties"
    text = f"force passed to the skin: {normal}% normal, {tangential}% {kind} in contact"
    if summary.friction_coefficient is None:
        text += f", {lifted}% lifted elements' bonded springs"
        if summary.load_shares[2] >= 0.01:
            text += " (set interface.friction_coefficient to release them)"
    return text


def percent_parts(shares, decimals: int = 1) -> list:
    """Shares that add up to one as percentages with ``decimals`` decimals that add up to
    100 as printed (largest remainder: the rounding goes to the largest fractions)."""
    scale = 100 * 10 ** decimals
    raw = [scale * x for x in shares]
    parts = [math.floor(x) for x in raw]
    for i in sorted(range(len(raw)), key=lambda i: parts[i] - raw[i])[:scale - sum(parts)]:
        parts[i] += 1
    return [f"{p / 10 ** decimals:.{decimals}f}" for p in parts]


def _check_draws(config, log, output, arm, colmap, group, draws, sd):
    """The loaded config, after checking that ``draws`` Monte Carlo draws (a model each when
    the tissue or the tension is drawn) fit in memory: nothing is drawn or written before."""
    from phri_spring.io.config import load_config
    from phri_spring.io.logs import reader_options, table_format
    from phri_spring.io.memory.budget import check_draws, check_model
    from phri_spring.workflows.uncertainty.run import parse_sd, uncertain_inputs

    cfg = load_config(config)
    fmt = table_format(output, role="output", option="-o/--output")
    inputs = uncertain_inputs(cfg, **parse_sd(sd))
    check_model(cfg, arm)
    cols_read, group_read = reader_options(cfg, colmap, group)
    distinct = bool(inputs.tissue_sd.any() or inputs.beta_sd.any() or inputs.tension_sd_N > 0)
    check_draws(cfg, arm, draws, distinct=distinct,
                output_format=fmt, log=log, columns=cols_read, group=group_read)
    return cfg
