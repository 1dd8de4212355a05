"""Import time of ``phri --help`` for two installs, alternated (A B A B ...), medians.

Each run is ``PYTHON -X importtime -c "import phri_cli.main"`` in a fresh process; the
figure is the cumulative import time of ``phri_cli.main`` (what ``phri --help`` imports
before it prints) as Python's own ``-X importtime`` reports it, in microseconds.

    python -m benchmarks.import_time A_PYTHON B_PYTHON [-n RUNS]

Prints the median of A, of B and of the pairwise ratios A/B.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess


def cumulative_us(python: str) -> int:
    """The cumulative import time [us] of phri_cli.main in one fresh interpreter."""
    run = subprocess.run([python, "-X", "importtime", "-c", "import phri_cli.main"],
                         capture_output=True, text=True, check=True)
    for line in run.stderr.splitlines():
        parts = [p.strip() for p in line.split("|")]
        if len(parts) == 3 and parts[2] == "phri_cli.main":
            return int(parts[1])
    raise SystemExit(f"{python}: no import time for phri_cli.main")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("a")
    parser.add_argument("b")
    parser.add_argument("-n", type=int, default=21)
    args = parser.parse_args()
    cumulative_us(args.a), cumulative_us(args.b)          # warm the file caches
    a, b = [], []
    for _ in range(args.n):
        a.append(cumulative_us(args.a))
        b.append(cumulative_us(args.b))
    ratios = [x / y for x, y in zip(a, b)]
    print(f"A median {statistics.median(a) / 1e3:.1f} ms (min {min(a) / 1e3:.1f}, "
          f"max {max(a) / 1e3:.1f})")
    print(f"B median {statistics.median(b) / 1e3:.1f} ms (min {min(b) / 1e3:.1f}, "
          f"max {max(b) / 1e3:.1f})")
    print(f"A/B median of pairwise ratios {statistics.median(ratios):.3f} over {args.n} pairs")


if __name__ == "__main__":
    main()
