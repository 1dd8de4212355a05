"""``phri stiffness``: the 6x6 interface stiffness of the cuff on the arm, at the load cell."""

from __future__ import annotations

import click

from ._common import ArmChoice


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
def stiffness(config, arm, as_json):
    """Interface stiffness of the cuff on the arm [N/mm, N*m/deg] at the load cell.

    CONFIG is a YAML config (see configs/harmony_upper_arm.yaml). The stiffness
    is the tangent dW/du at the preloaded state (zero wrench from the robot,
    strap preload as configured): the extra wrench the load cell reads per small
    extra displacement of the load-cell point, in the load-cell axes. Printed
    for people in N/mm, N/deg, N*m/mm and N*m/deg, with the principal values of
    the translational [N/mm] and rotational [N*m/deg] blocks and the torsional
    stiffness about the arm axis; compare with human upper-arm interfaces,
    2.1-4.5 N/mm and 0.03-0.04 N*m/deg in torsion (see docs/stiffness.md).

    \b
    Examples:
      phri stiffness configs/harmony_upper_arm.yaml
      phri stiffness configs/human_upper_arm.yaml --arm rigid --json
    """
    import json

    from phri_spring.io.config import load_config
    from phri_spring.workflows.stiffness import interface_stiffness_report

    cfg = load_config(config)
    report = interface_stiffness_report(cfg, arm)
    if as_json:
        click.echo(json.dumps(report.to_dict(), allow_nan=False))
    else:
        click.echo(report.to_text())
