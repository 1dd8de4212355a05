"""How much the interface stiffness of the presets depends on the shear ratio eta.

eta = k_s / k_e is the tangential-to-normal stiffness ratio of an element's springs
(docs/model.md section 2). The paper's model sets eta = 1 / (2 (1 + nu)), an assumption;
the two limits below bracket what a bonded contact of soft tissue can have:

* thin bonded layer (patch much wider than the layer is thick): simple shear, G / h per
  unit area, against confined compression, E (1 - nu) / ((1 + nu) (1 - 2 nu) h):
  eta = (1 - 2 nu) / (2 (1 - nu));
* rigid flat punch bonded to a half-space (Mindlin 1949): tangential 8 G a / (2 - nu)
  against normal 4 G a / (1 - nu): eta = 2 (1 - nu) / (2 - nu).

For each preset and each arm model that uses eta (compliant: every element's shear
spring; coupled: the tangential cuff springs in series with the FE tissue), the script
sets ``interface.shear_ratio`` in a copy of the config and prints the diagonal of the
interface stiffness ``phri stiffness`` reports (at the load-cell origin, load-cell axes)
and the torsion about the arm axis. Run from the repository root::

    python -m benchmarks.shear_ratio_sensitivity            # Markdown table on stdout

The coupled rows need the ``fe`` extra; the tissue FE is built once per preset (about
20 s) and cached on disk, after which the script takes a few seconds.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import yaml

from benchmarks.common import ROOT  # noqa: E402

from phri_spring.io.config import load_config  # noqa: E402
from phri_spring.workflows.stiffness.matrix import interface_stiffness_report  # noqa: E402

PRESETS = ("harmony_upper_arm.yaml", "human_upper_arm.yaml")
ARMS = ("compliant", "coupled")


def thin_layer_ratio(nu: float) -> float:
    """Shear over confined-compression stiffness of a thin bonded layer [-]."""
    return (1.0 - 2.0 * nu) / (2.0 * (1.0 - nu))


def default_ratio(nu: float) -> float:
    """The paper's eta = G / E = 1 / (2 (1 + nu)) [-]."""
    return 1.0 / (2.0 * (1.0 + nu))


def punch_ratio(nu: float) -> float:
    """Mindlin's bonded flat punch on a half-space, tangential over normal [-]."""
    return 2.0 * (1.0 - nu) / (2.0 - nu)


CASES = (("thin layer", thin_layer_ratio), ("default", default_ratio),
         ("punch", punch_ratio))


def diagonal(config: Path, arm: str, eta: float, workdir: Path):
    """[Fx/x, Fy/y, Fz/z] N/mm, [Mx/rx, My/ry, Mz/rz] N*m/deg and torsion N*m/deg."""
    raw = yaml.safe_load(config.read_text(encoding="utf-8"))
    raw.setdefault("interface", {})["shear_ratio"] = float(eta)
    path = workdir / f"{config.stem}_eta.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False), encoding="utf-8")
    rep = interface_stiffness_report(load_config(path), arm)
    d = rep.people_units().diagonal()
    return d, rep.torsion_Nm_per_deg


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arms", default=",".join(ARMS),
                    help="comma-separated arm models (default: compliant,coupled)")
    args = ap.parse_args(argv)
    arms = [a.strip() for a in args.arms.split(",") if a.strip()]
    print("| config | arm | eta | Fx/x | Fy/y | Fz/z [N/mm] | Mx/rx | My/ry | Mz/rz "
          "[N*m/deg] | torsion about the arm axis [N*m/deg] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in PRESETS:
            config = ROOT / "configs" / name
            nu = load_config(config).poisson_ratio
            for arm in arms:
                for label, ratio in CASES:
                    eta = ratio(nu)
                    d, torsion = diagonal(config, arm, eta, Path(tmp))
                    cells = [f"{v:.4g}" for v in d] + [f"{torsion:.4g}"]
                    print(f"| `{name}` | {arm} | {eta:.4f} ({label}) | " + " | ".join(cells) + " |")
    print()
    print("eta: thin layer (1-2nu)/(2(1-nu)), default 1/(2(1+nu)), punch 2(1-nu)/(2-nu), "
          "nu = tissue.poisson_ratio of each preset")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
