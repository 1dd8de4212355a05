"""Draw docs/img/stiffness_curves_human.png: the human preset's force-displacement curves.

The curves of ``phri stiffness configs/human_upper_arm.yaml --curves OUTDIR`` for the
compliant and the coupled arm in one figure, with the measured human ranges
(docs/stiffness.md, "Force-displacement curves"). The coupled arm builds its tissue FE
on the first run (the ``fe`` extra) and reads it from the cache after that.

    python examples/make_stiffness_curves_human.py [OUT.png]
"""

from __future__ import annotations

import sys
from pathlib import Path

from phri_spring.io.atomic import atomic_file
from phri_spring.io.config import load_config
from phri_spring.reports.compare_figures import save_figure
from phri_spring.reports.stiffness_curves_figure import stiffness_curves_figure
from phri_spring.workflows.stiffness_curves import stiffness_curves

ROOT = Path(__file__).resolve().parents[1]


def main(out=ROOT / "docs" / "img" / "stiffness_curves_human.png") -> Path:
    cfg = load_config(ROOT / "configs" / "human_upper_arm.yaml")
    curves = [stiffness_curves(cfg, arm) for arm in ("compliant", "coupled")]
    fig = stiffness_curves_figure(curves)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(out) as tmp:
        save_figure(fig, tmp)
    for c in curves:
        print(c.summary())
    return out


if __name__ == "__main__":
    print(main(*sys.argv[1:2]))
