"""Draw docs/img/section_human_thigh.png: the pressure around the limb, row by row.

The section figure ``phri simulate configs/human_thigh.yaml examples/wrench_log.csv -o OUT
--plot PLOT.png`` writes beside its plot (``PLOT_section.png``): the thigh preset's
elliptic, tapered section under the example log's sample of the peak pressure (compliant
arm), drawn small enough for the docs.

    python examples/make_section_figure.py [OUT.png]
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from phri_spring.io.config import load_config
from phri_spring.workflows.plots.maxpool import MaxPool
from phri_spring.workflows.plots.section import write_section_plot
from phri_spring.workflows.simulate import simulate_file

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "configs" / "human_thigh.yaml"
LOG = ROOT / "examples" / "wrench_log.csv"


def main(out: Path) -> Path:
    cfg = load_config(CONFIG)
    pool = MaxPool(len(cfg.labels), bins=100)
    with tempfile.TemporaryDirectory() as tmp:
        simulate_file(cfg, LOG, Path(tmp) / "forces.parquet", on_chunk=pool)
    res = pool.result()
    return write_section_plot(cfg, res.peak_forces, out, dpi=90,
                              title=f"{CONFIG.name}, {LOG.name}: compliant arm, the sample of "
                                    f"the peak pressure (t = {res.peak_time:g} s)")


if __name__ == "__main__":
    path = main(Path(sys.argv[1]) if len(sys.argv) > 1
                else ROOT / "docs" / "img" / "section_human_thigh.png")
    print(f"wrote {path} ({path.stat().st_size / 1e3:.0f} kB)")
