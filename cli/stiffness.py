"""``phri stiffness``: the 6x6 interface stiffness of the cuff on the arm, at the load cell."""

from __future__ import annotations

from pathlib import Path

import click

from ._common import ArmChoice, info, warn


@click.command("stiffness", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("config", metavar="CONFIG")
@click.option("--arm", type=ArmChoice(), default="compliant", show_default=True,
              help="Arm model (docs/model.md section 11.4): compliant (tissue and cuff "
                   "springs in series), rigid (cuff springs only), coupled (the tissue as a "
                   "continuum) or any other model listed.")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object instead of the table: key K is the 6x6 matrix in SI "
                   "units (N/m, N/rad, N*m/m, N*m/rad), rows Fx Fy Fz Mx My Mz, columns "
                   "x y z rx ry rz, at the load-cell origin in the load-cell axes.")
@click.option("--curves", type=click.Path(path_type=Path), default=None, metavar="OUTDIR",
              help="Also write the force-displacement curves under load along and about each "
                   "load-cell axis into OUTDIR: stiffness_curves.csv and stiffness_curves.png "
                   "(with the measured human ranges; docs/stiffness.md).")
@click.option("--max-force", type=float, default=60.0, show_default=True, metavar="N",
              help="With --curves: largest force along each axis, both signs [N].")
@click.option("--max-moment", type=float, default=3.0, show_default=True, metavar="N*M",
              help="With --curves: largest moment about each axis, both signs [N*m].")
@click.pass_context
def stiffness(ctx, config, arm, as_json, curves, max_force, max_moment):
    """Interface stiffness of the cuff on the arm [N/mm, N*m/deg] at the load cell.

    CONFIG is a YAML config (see configs/harmony_upper_arm.yaml). The stiffness
    is the tangent dW/du at the preloaded state (zero wrench from the robot,
    strap preload as configured): the extra wrench the load cell reads per small
    extra displacement of the load-cell point, in the load-cell axes. Printed
    for people in N/mm, N/deg, N*m/mm and N*m/deg, with the principal values of
    the translational [N/mm] and rotational [N*m/deg] blocks and the torsional
    stiffness about the arm axis; compare with human upper-arm interfaces,
    2.1-4.5 N/mm and 0.03-0.04 N*m/deg in torsion (see docs/stiffness.md).

    With --curves, the robot's force (moment) at the load cell is swept from 0
    to --max-force (--max-moment) along (about) each load-cell axis in both
    signs, and the motion of the load-cell point is written against it; the
    slope at zero load is 1/(K^-1)_ii, what a load-controlled test measures.

    \b
    Examples:
      phri stiffness configs/harmony_upper_arm.yaml
      phri stiffness configs/human_upper_arm.yaml --arm rigid --json
      phri stiffness configs/human_upper_arm.yaml --arm coupled --curves curves/
    """
    import json

    from click.core import ParameterSource

    from phri_spring.io.config import load_config
    from phri_spring.workflows.common import model_from_config
    from phri_spring.workflows.stiffness.matrix import interface_stiffness_report

    if curves is None:
        for name in ("max_force", "max_moment"):
            if ctx.get_parameter_source(name) is ParameterSource.COMMANDLINE:
                raise click.UsageError(f"--{name.replace('_', '-')} needs --curves OUTDIR")
    else:
        from phri_spring.workflows.stiffness.curves import check_curves_output

        check_curves_output(curves, [config])          # before the work: a bad path fails fast
    cfg = load_config(config)
    model = model_from_config(cfg, arm)
    report = interface_stiffness_report(cfg, arm, model=model)
    if curves is not None:
        from phri_spring.workflows.stiffness.curves import (stiffness_curves,
                                                            write_stiffness_curves)

        result = stiffness_curves(cfg, arm, max_force=max_force, max_moment=max_moment,
                                  model=model)
        if result.failed:
            warn(f"{result.failed} of {result.converged.size} loaded samples did not converge "
                 "(NaN in the table, gaps in the figure)")
        written = write_stiffness_curves(result, curves,
                                         inputs=[config, *cfg.stiffness_files])
        info(f"wrote {', '.join(str(p) for p in written)}")
    if as_json:
        click.echo(json.dumps(report.to_dict(), allow_nan=False))
    else:
        click.echo(report.to_text())
