"""What the benchmarks share: paths, the Harmony-like test cuff, synthetic logs, timing.

Every benchmark is a module of the ``benchmarks`` package, run from the repository root:

    python -m benchmarks.NAME [options]

so that ``benchmarks.common`` and the reference FEs of ``references/`` (not installed
with phri_spring) import without editing ``sys.path``. phri_spring itself is imported
lazily here, so that :func:`use_checkout` can still choose which copy to time.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
BENCHMARKS = ROOT / "benchmarks"
CONFIGS = ROOT / "configs"
EXAMPLES = ROOT / "examples"
#: the Harmony-like test cuff (3 rows x 7 locations, R = 45 mm): the one definition the
#: benchmarks use; the tests read the same file (tests/support/helpers.py)
HARMONY_CONFIG = CONFIGS / "harmony_upper_arm.yaml"
HUMAN_CONFIG = CONFIGS / "human_upper_arm.yaml"
COLS = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
HOUR = 360_000          # samples in one hour at 100 Hz


def preset(name: str) -> Path:
    """The path of a bundled config (``configs/NAME.yaml``)."""
    return CONFIGS / f"{name}.yaml"


def harmony_config():
    """The Harmony-like test cuff's config (:data:`HARMONY_CONFIG`), loaded."""
    from phri_spring.io.config import load_config

    return load_config(HARMONY_CONFIG)


def harmony_geometry():
    """The Harmony-like test cuff's geometry, from :data:`HARMONY_CONFIG`."""
    from phri_spring.workflows.common import geometry_from_config

    return geometry_from_config(harmony_config())


def load_example(relative: str, name: str | None = None):
    """Import a script of ``examples/`` (``relative`` to it, e.g. ``design/make_task_log.py``)
    as a module, without putting its folder on ``sys.path``."""
    path = EXAMPLES / relative
    name = name or f"phri_example_{path.stem}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def use_checkout(root: Path) -> None:
    """Make ``import phri_spring`` read the phri_spring of another checkout (``root``, e.g. an
    older commit) instead of the installed one, to time both with the same script.

    Must run before anything imports phri_spring; its submodules then load from ``root``.
    """
    if "phri_spring" in sys.modules:
        raise RuntimeError("use_checkout: phri_spring is already imported")
    spec = importlib.machinery.PathFinder.find_spec("phri_spring", [str(Path(root).resolve())])
    if spec is None:
        raise SystemExit(f"--root {root}: no phri_spring package there")
    module = importlib.util.module_from_spec(spec)
    sys.modules["phri_spring"] = module
    spec.loader.exec_module(module)


def child_env():
    """The environment of a timed child process: BLAS thread limits of this process removed."""
    env = dict(os.environ)
    for v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        env.pop(v, None)
    return env


def make_log(path: Path, n: int, seed: int) -> None:
    """A synthetic load-cell log of ``n`` samples at 100 Hz (CSV or Parquet by the suffix of
    ``path``), values rounded to 4 decimals like a load-cell export; fixed by ``seed``."""
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    from phri_spring.synthetic.wrench import smooth_random_log

    path = Path(path)
    chunk = 1_000_000
    writer = None
    for s in range(0, n, chunk):
        e = min(n, s + chunk)
        t, w = smooth_random_log(e - s, seed=seed + s)
        t = np.round((np.arange(s, e)) / 100.0, 2)
        data = {"time": t}
        data.update({c: np.round(w[:, j], 4) for j, c in enumerate(COLS)})
        table = pa.table(data)
        if writer is None:
            writer = (pacsv.CSVWriter(str(path), table.schema) if path.suffix == ".csv"
                      else pq.ParquetWriter(str(path), table.schema))
        writer.write_table(table)
    writer.close()


def run_interleaved(cmds, repeats: int, warmup: bool = True, cpu: bool = False):
    """For each command: (median wall time [s], max peak RSS [MB], all wall times), and
    with ``cpu`` its median CPU time (user + system) [s] fourth.

    The commands run in rotation (A B C A B C ...) after a warm-up round, so the
    machine's drift touches them alike; before each run the command's output
    (the argument after ``-o``) is deleted and the file systems synced, untimed.
    Measured by benchmarks/measure_cmd.py, a small process, so that this (large)
    process's memory does not count in a command's peak RSS.
    """
    cmds = [[str(a) for a in c] for c in cmds]
    outputs = [c[c.index("-o") + 1] if "-o" in c else None for c in cmds]
    spec = {"repeats": repeats, "warmup": warmup, "cmds": cmds, "outputs": outputs}
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "measure_cmd.py"),
                          json.dumps(spec)], capture_output=True, text=True, env=child_env(),
                         cwd=ROOT, check=True).stdout
    res = json.loads(out)
    if "error" in res:
        raise RuntimeError(res["error"])
    return [(statistics.median(r["walls"]), max(r["rss"]), r["walls"])
            + ((statistics.median(r["cpus"]),) if cpu else ()) for r in res["results"]]


def run_process(cmd, repeats: int, warmup: bool = True, cpu: bool = False):
    """Median wall time [s], max peak RSS [MB] and all wall times of one command (and
    with ``cpu`` its median CPU time [s])."""
    return run_interleaved([cmd], repeats, warmup, cpu)[0]


def pin_one_cpu():
    """Pin this process to one CPU (in-process timings); the CPU, or None where unsupported."""
    try:
        cpu = sorted(os.sched_getaffinity(0))[0]
        os.sched_setaffinity(0, {cpu})
        return cpu
    except (AttributeError, OSError):
        return None


def median_time(fn, repeats):
    """Median wall time [s] of ``fn()`` over ``repeats`` calls."""
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)
