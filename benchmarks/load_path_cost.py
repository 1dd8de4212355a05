"""CPU cost of the summary's load split on a one-hour log, in process, one BLAS thread.

Solves the log in chunks of 36,000 samples (what ``phri simulate`` streams on the Harmony
config), then times, over the same solutions (CPU time, best of 5):

* the split as the summary computes it (``load_path.ChunkedShares``: per-chunk sums);
* the per-sample (m, n, 3) route it replaced (``load_path.force_parts`` of every chunk);
* the solve of the log itself, for scale.

    python -m benchmarks.load_path_cost [LOG.csv]   # default: a generated one-hour log
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_v] = "1"

import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from benchmarks.common import HARMONY_CONFIG, make_log  # noqa: E402

from phri_spring.io.config import load_config  # noqa: E402
from phri_spring.io.logs import read_wrench_log  # noqa: E402
from phri_spring.physics.contact.load_path import ChunkedShares, force_parts  # noqa: E402
from phri_spring.physics.contact.solver import FactorCache, solve  # noqa: E402
from phri_spring.workflows.common import cuff_wrench, model_from_config  # noqa: E402

CHUNK = 36_000


def best_cpu(fn, repeats=5):
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def main():
    cfg = load_config(HARMONY_CONFIG)
    model = model_from_config(cfg, "compliant")
    with tempfile.TemporaryDirectory() as tmp:
        if len(sys.argv) > 1:
            log = Path(sys.argv[1])
        else:
            log = Path(tmp) / "hour.csv"
            make_log(log, 360_000, seed=1)
        _, w_lc = read_wrench_log(log)
    W = cuff_wrench(cfg, w_lc)
    starts = range(0, len(W), CHUNK)
    cache = FactorCache()
    sols = [solve(model, W[i:i + CHUNK], cache=cache) for i in starts]

    def split():
        shares = ChunkedShares()
        for number, sol in enumerate(sols):
            shares.add(number, model, sol)
        return shares.shares()

    def old_route():
        for sol in sols:
            force_parts(model, sol.u, sol.contact)

    t_split = best_cpu(split)
    t_old = best_cpu(old_route, 3)
    t_solve = best_cpu(lambda: [solve(model, W[i:i + CHUNK], cache=cache) for i in starts], 3)
    print(f"{len(W):,} samples, {model.n} elements, chunks of {CHUNK:,}; CPU seconds, best of "
          f"several runs:\n  split (per-chunk sums): {t_split:.3f} s\n"
          f"  force_parts, (m, n, 3) per sample: {t_old:.3f} s\n  solve: {t_solve:.3f} s\n"
          f"  shares: {', '.join(f'{100 * s:.1f} %' for s in split())}")


if __name__ == "__main__":
    main()
