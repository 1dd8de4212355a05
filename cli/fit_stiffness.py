"""``phri fit-stiffness``: indenter recordings -> tissue stiffness map [N/m]."""

from __future__ import annotations

from pathlib import Path

import click

from phri_spring.workflows.fit.laws import ELASTIC_PARTS, FIT_LAWS

from ._common import info, warn


_LAW_HELP = " ".join(f"{name}: {law.description}." for name, law in FIT_LAWS.items())


@click.command("fit-stiffness", context_settings={"help_option_names": ["-h", "--help"]})
@click.pass_context
@click.argument("input_path", metavar="INPUT", type=click.Path(path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), required=True,
              metavar="OUT.csv", help="Stiffness table to write (a valid tissue.stiffness).")
@click.option("--zero-window", type=click.FloatRange(min=0, min_open=True), default=3.0,
              show_default=True, metavar="SECONDS",
              help="Rest period at the start of each trial; the force is zeroed by its mean "
                   "over it [s].")
@click.option("--onset-threshold", type=click.FloatRange(min=0, min_open=True), default=None,
              metavar="NEWTONS",
              help="Rise of the force above its zero level that marks the onset and contact "
                   "[N]. Default per trial: max(5 x noise SD in the zero window, 0.05 N).")
@click.option("--displacement-unit", type=click.Choice(["mm", "m"]), default="mm",
              show_default=True, help="Unit of the displacement column.")
@click.option("--plots", type=click.Path(path_type=Path), default=None, metavar="DIR",
              help="Write force_displacement.png (Fig. 6a) and stiffness_map.png (Fig. 6b) "
                   "into DIR (force_time.png in place of the first with --law qlv).")
@click.option("--skip-bad-trials", is_flag=True,
              help="Leave bad trials out with a warning (n_trials shows it) instead of "
                   "failing.")
@click.option("--min-r2", type=click.FloatRange(max=1.0), default=0.98, show_default=True,
              metavar="R2", help="Flag locations with an unloading fit R^2 below this "
                                    "(with --law qlv: the fit of the force over time).")
@click.option("--max-trial-spread", type=click.FloatRange(min=0.0), default=0.10,
              show_default=True, metavar="FRACTION",
              help="Flag locations whose trials differ by more than this fraction of their "
                   "mean, (max - min) / mean.")
@click.option("--trials-csv", type=click.Path(path_type=Path), default=None, metavar="FILE",
              help="Also write one row per trial (slopes, R^2, onset, zero level ...).")
@click.option("--law", type=click.Choice(list(FIT_LAWS)), default="linear",
              show_default=True, help=_LAW_HELP)
@click.option("--elastic", type=click.Choice(list(ELASTIC_PARTS)), default=None,
              help="Elastic (instantaneous) part of the qlv law: F = k d, or "
                   "F = (k/beta)(exp(beta d) - 1). Default linear; --law qlv only.")
@click.option("--relaxation-terms", type=click.IntRange(1, 4), default=None, metavar="N",
              help="Prony terms of the qlv law (fractions and times free). Default 2; "
                   "--law qlv only.")
@click.option("-q", "--quiet", is_flag=True, help="No summary line (warnings still shown).")
def fit_stiffness(ctx, input_path, output, zero_window, onset_threshold, displacement_unit,
                  plots, skip_bad_trials, min_r2, max_trial_spread, trials_csv, law, elastic,
                  relaxation_terms, quiet):
    """Fit the tissue stiffness map [N/m] from indenter recordings.

    INPUT is a folder of trial files named <label>_<trial>.csv (e.g. B3_2.csv;
    other files such as README or TRUTH.md are ignored) or .mat, or one long CSV
    with columns location, trial, time, displacement, force. Per trial: time [s],
    displacement [mm, or m with --displacement-unit m], force [N].

    Per trial the force is zeroed over the first --zero-window seconds, the onset
    is where it first rises above the zero level by --onset-threshold, the strokes
    are split at the displacement maxima, a line is fitted to each unloading stroke
    in contact, and the trial stiffness is the mean unloading slope [N/m]. The
    location stiffness is the mean over its trials, with the sample SD and count.

    OUT.csv columns: location, row, angle_index, stiffness_N_per_m, std_N_per_m,
    n_trials, then quality columns (n_strokes, r2_min, loading_slope_N_per_m,
    hysteresis_ratio, peak_force_N, peak_depth_mm, trial_spread, n_trials_skipped,
    flags). Use OUT.csv as tissue.stiffness in a config.

    With --law exponential the stiffness columns hold k0, the slope at contact,
    and stiffening_per_m, stiffening_std_per_m (mean and SD of beta over the
    trials [1/m]) follow n_trials; OUT.csv is then both tissue.stiffness and
    tissue.stiffening. A fit that fails or finds no stiffening is a warning.

    With --law qlv the trials must follow the force over time: a hold of 1 s or
    more after the ramp, or trials of a location at loading rates 2x apart. Per
    location all its trials are fitted together; stiffness_N_per_m is k, the
    instantaneous stiffness of the elastic part (with --elastic exponential the
    stiffening columns follow), then relaxation_fraction_<i> [-] and
    relaxation_time_<i>_s [s] per Prony term; std_N_per_m is left empty. The
    summary line gives the tissue.relaxation a config takes (mean over locations).
    --plots writes force_time.png (force over time with the fit) instead of
    force_displacement.png.

    \b
    Examples:
      phri fit-stiffness examples/indenter -o stiffness.csv --plots figs/
      phri fit-stiffness examples/indenter_qlv -o qlv.csv --law qlv --plots figs/
    """
    from click.core import ParameterSource

    from phri_spring.workflows.fit.stiffness import (check_fit_outputs, fit_stiffness as run,
                                                     write_fit)

    if law == "qlv" and ctx.get_parameter_source("max_trial_spread") \
            is ParameterSource.COMMANDLINE:
        raise click.UsageError("--max-trial-spread does not apply to --law qlv: the trials "
                               "of a location are fitted together, there is no spread "
                               "between trial fits")
    if law != "qlv":
        for name, value in (("--elastic", elastic), ("--relaxation-terms", relaxation_terms)):
            if value is not None:
                raise click.UsageError(f"{name} applies to --law qlv only (the {law} law "
                                       "has no relaxation)")
    check_fit_outputs(input_path, output, plots=plots, trials_csv=trials_csv)
    result = run(input_path, zero_window=zero_window, onset_threshold=onset_threshold,
                 displacement_unit=displacement_unit, skip_bad_trials=skip_bad_trials,
                 min_r2=min_r2, max_trial_spread=max_trial_spread, law=law,
                 elastic=elastic, relaxation_terms=relaxation_terms)
    for message in result.warnings:
        warn(message)
    written = write_fit(result, output, plots=plots, trials_csv=trials_csv)
    n_trials = int(sum(loc.n_trials for loc in result.locations))
    info(f"wrote {', '.join(str(p) for p in written if p.suffix == '.csv')}"
         + (f" and plots in {plots}" if plots is not None else "")
         + f" ({n_trials} trials)", quiet=quiet)
    if not quiet:
        click.echo(result.summary_line())
