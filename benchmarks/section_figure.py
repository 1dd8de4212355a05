"""What the section figure adds to ``phri simulate --plot`` (benchmarks/SECTION_FIGURE.md).

Runs ``phri simulate CONFIG LOG -o OUT --plot PLOT`` in this process; with
``--skip-section`` the section figure is not drawn (its writer replaced by a no-op), so
that the two runs differ by the section figure only. Time the two forms from outside,
alternated, e.g.

    for i in 1 2 3 4 5; do
      /usr/bin/time -f %e python -m benchmarks.section_figure configs/human_thigh.yaml \\
          examples/wrench_log.csv /tmp/sec
      /usr/bin/time -f %e python -m benchmarks.section_figure --skip-section \\
          configs/human_thigh.yaml examples/wrench_log.csv /tmp/sec
    done
"""

from __future__ import annotations

import sys
from pathlib import Path


def main(argv) -> int:
    skip = "--skip-section" in argv
    config, log, folder = [a for a in argv if a != "--skip-section"]
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    if skip:
        import phri_spring.workflows.plots.section as sp

        sp.write_section_plot = lambda *args, **kwargs: None
    from phri_cli.main import phri

    tag = "b" if skip else "a"
    return phri.main(["simulate", config, log, "-o", str(folder / f"{tag}.csv"), "--plot",
                      str(folder / f"{tag}.png"), "-q"], standalone_mode=False) or 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
