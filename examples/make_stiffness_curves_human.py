"""Draw docs/img/stiffness_curves_human.png: the human preset's force-displacement curves.

The curves of ``phri stiffness configs/human_upper_arm.yaml --curves OUTDIR`` for the
compliant arm (with the preset's stiffening tissue law, ``tissue.stiffening``) and the
coupled arm in one figure, beside the compliant arm with the same tissue made linear
(``tissue.stiffening`` 0, as the preset was before it stiffened), with the measured human
ranges (docs/stiffness.md, "Force-displacement curves"). The coupled arm builds its tissue
FE on the first run (the ``fe`` extra) and reads it from the cache after that.

    python examples/make_stiffness_curves_human.py [OUT.png]
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

from phri_spring.io.outputs.atomic import atomic_file
from phri_spring.io.config import config_from_dict, load_config, load_yaml
from phri_spring.reports.compare.figures import save_figure
from phri_spring.reports.stiffness_curves_figure import stiffness_curves_figure
from phri_spring.workflows.stiffness.curves import stiffness_curves

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "configs" / "human_upper_arm.yaml"
#: label of the compliant arm with the preset's tissue made linear
LINEAR = "Compliant arm, linear tissue"


def linear_tissue_config():
    """The human preset with ``tissue.stiffening`` 0: the same tissue without stiffening."""
    raw = load_yaml(CONFIG)
    raw["tissue"]["stiffening"] = 0.0
    return config_from_dict(raw, path=CONFIG, base_dir=CONFIG.parent)


def main(out=ROOT / "docs" / "img" / "stiffness_curves_human.png") -> Path:
    cfg = load_config(CONFIG)
    curves = [stiffness_curves(cfg, arm) for arm in ("compliant", "coupled")]
    linear = dataclasses.replace(stiffness_curves(linear_tissue_config(), "compliant"),
                                 arm=LINEAR)
    curves.insert(0, linear)     # drawn first: the preset's own curve on top of it
    fig = stiffness_curves_figure(curves)
    # five legend entries: three columns, so that the long source label fits the width
    (legend,) = fig.legends
    entries = (legend.legend_handles, [t.get_text() for t in legend.get_texts()])
    legend.remove()
    fig.legend(*entries, loc="outside lower center", ncols=3, frameon=False, fontsize=8.5)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(out) as tmp:
        save_figure(fig, tmp)
    for c in curves:
        print(c.summary())
    return out


if __name__ == "__main__":
    print(main(*sys.argv[1:2]))
