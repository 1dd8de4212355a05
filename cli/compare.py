"""``phri compare``: RMSE of the arm models' predictions (rigid, compliant, coupled) against a sensorized cuff."""

from __future__ import annotations

import click

from ._common import info, progress_enabled


@click.command("compare", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("config", metavar="CONFIG")
@click.argument("manifest", metavar="MANIFEST")
@click.option("-o", "--output", required=True, metavar="OUTDIR",
              help="Folder to write (created; must not be or contain an input).")
@click.option("--arms", default="rigid,compliant", show_default=True, metavar="LIST",
              help="Arm models to compare, comma-separated: rigid, compliant, coupled "
                   "(coupled needs tissue.continuum in the config).")
@click.option("--tissue-stiffness", metavar="CSV", default=None,
              help="Tissue stiffness map [N/m, indenter basis] written by 'phri fit-stiffness', "
                   "replacing the config's tissue.stiffness.")
@click.option("--group", default=None, metavar="NAME",
              help="Trial tables in TDMS files: the group holding the channels; in .mat "
                   "files: the struct holding the vectors (default: load_cell.group).")
@click.option("--no-figures", is_flag=True,
              help="Write the tables and report.md only (no PNG figures; faster).")
@click.option("--dpi", type=click.IntRange(min=50, max=600), default=170, show_default=True,
              help="Resolution of the PNG figures [dots per inch].")
@click.option("--uncertainty", type=click.IntRange(min=2), default=None, metavar="N",
              help="Also draw the models' 5-95 % bands from N Monte Carlo draws of the tissue "
                   "stiffness and strap tension (bands.csv, bands/*.png; docs/design.md).")
@click.option("--uncertainty-sd", default=None, metavar="LIST",
              help="SDs of the draws: tissue=from_csv|FRACTION (k0), stiffening=from_csv|"
                   "FRACTION (the exponential law's beta), tension=N.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the draws.")
@click.option("--tolerance", default=None, metavar="CURVE",
              help="Also judge each arm's predicted pressures, held over every condition's "
                   "window, against a pressure-time curve (docs/tolerance.md): exposure.csv "
                   "and a section of report.md. Default: the config's tolerance.curve.")
@click.option("-q", "--quiet", is_flag=True,
              help="Print nothing on success (the summary is in OUTDIR/summary.csv).")
def compare(config, manifest, output, arms, tissue_stiffness, group, no_figures, dpi, quiet,
            uncertainty=None, uncertainty_sd=None, seed=0, tolerance=None):
    """Compare predicted and measured cuff loads [N] for every trial and condition.

    CONFIG is a YAML config (see configs/harmony_upper_arm.yaml). MANIFEST is
    an experiment manifest (YAML) listing trial tables:

    \b
      baseline: no_load        # condition both sides are zeroed on
      trials:
        - {file: iact_horizontal_1.csv, experiment: I-Act,
           direction: horizontal, trial: 1}

    Each trial CSV holds time [s], Fx Fy Fz [load-cell force unit], Mx My Mz
    [moment unit], one column per element (A0 ... C6) with the measured load
    [N], and condition (the steady window's label, empty between windows).
    Trial tables may also be TDMS or MATLAB .mat files with channels (vectors)
    of those names (needs the lab extra: pip install -e '.[lab]').

    For each trial, condition and arm model, the measured loads and the model's
    loads at the condition's mean wrench are zeroed on the baseline condition,
    each on its own side, and RMSE [N] = sqrt(sum_e (F_expt - F_sim)^2 / N)
    over the N elements (paper Eq. 1). OUTDIR gets rmse.csv, summary.csv (mean
    and standard error over trials), loads.csv, conditions.csv, rmse_bars.png,
    heatmaps/*.png, wrench/*.png and report.md; the summary table is printed on
    stdout.

    \b
    Example:
      phri compare configs/harmony_upper_arm.yaml \\
          examples/experiment/manifest.yaml -o out/compare
    """
    from phri_spring.io.outputs.atomic import check_output_path
    from phri_spring.workflows.compare.run import (compare as run_compare, parse_arms,
                                               summary_markdown, write_compare)

    arm_list = parse_arms(arms)
    if tolerance is not None:
        from phri_spring.io.config.tolerance import curve_option

        curve_option(tolerance)       # an unknown name is refused before anything is read
    check_output_path(output, [config, manifest, tissue_stiffness], option="-o/--output",
                      directory=True)
    result = run_compare(config, manifest, arms=arm_list, tissue_stiffness=tissue_stiffness,
                         group=group, tolerance=tolerance)
    if uncertainty is not None:  # computed before anything is written: a failure leaves nothing
        from phri_spring.io.memory.budget import check_draws
        from phri_spring.workflows.compare.bands import compare_bands, write_compare_bands

        # every draw's forces at every condition are held at once (models one at a time)
        check_draws(result.config, "coupled" if "coupled" in result.arms else "compliant",
                    uncertainty, distinct=False,
                    rows=sum(len(tc.conditions) for tc in result.trials))
        bands = compare_bands(result, draws=uncertainty, seed=seed, sd=uncertainty_sd)
    if not no_figures and progress_enabled(None):  # progress: only on a terminal
        n_fig = 1 + sum(len(tc.conditions) for tc in result.trials)   # bars, wrench, heat maps
        info(f"compare: {len(result.trials)} trials analysed; writing {n_fig} figures ...",
             quiet)
    section = ""
    if uncertainty is not None:
        from phri_spring.workflows.compare.bands import bands_report_section

        section = bands_report_section(result, bands[1], draws=uncertainty, seed=seed,
                                       figures=not no_figures)
    out = write_compare(result, output, figures=not no_figures, dpi=dpi, bands_markdown=section)
    if uncertainty is not None:
        write_compare_bands(result, *bands, output, figures=not no_figures, dpi=dpi)
    if not quiet:
        click.echo(summary_markdown(result))
    n_heat = sum(1 for f in out.files if f.parent.name == "heatmaps")
    from phri_spring.reports.tissue_law_text import arms_law_text, is_nonlinear

    law = (f"; {arms_law_text(result.config, result.arms)}"
           if is_nonlinear(result.config) and set(result.arms) - {"rigid"} else "")
    dose = ""
    if result.exposure is not None:
        worst = result.exposure.loc[result.exposure["dose"].idxmax()]
        dose = (f"; predicted dose ({result.tolerance.name}) max {worst['dose']:.3g} at "
                f"{worst['element']} ({worst['arm']} arm, trial {worst['trial']})")
    info(f"wrote {out.outdir} ({len(result.trials)} trials, {len(result.rmse)} RMSE values, "
         f"{n_heat} heat maps{law}{dose}); see {out.outdir / 'report.md'}", quiet)
