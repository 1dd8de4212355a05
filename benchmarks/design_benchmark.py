"""Benchmark of ``phri design``: a 1,000-design grid over a 10-minute 100 Hz log.

Usage (from the repository root, after `pip install -e .[dask]`):

    python -m benchmarks.design_benchmark              # full run, writes benchmarks/DESIGN_RESULTS.md
    python -m benchmarks.design_benchmark --quick      # 100 designs, one repeat, nothing written

The log (60,000 samples, synthetic, fixed seed, rounded to 4 decimals like a
load-cell export) and the study are generated into a temporary folder. Rows
measured, each a fresh output folder (no resuming):

1. ``phri design`` as a user runs it (separate process, default pool over all
   cores, figures on): wall time against the 60 s target.
2. The study in-process on a pool of 1 and of 2 workers, in turns (medians over
   repeats): the speed-up of 2 workers over 1 (target >= 1.7x).
3. Scheduling overhead of each run = 1 - (sum of the batches' compute times /
   workers) / (wall time of the batch phase): time the workers were not
   computing designs (start-up, sending work and results, idle tail), target <= 5 %.
4. Accuracy cost of the opt-in merge tolerance (rows snapped to 1 N / 0.05 N*m and
   2 N / 0.1 N*m) on five designs, on the benchmark log and on the bundled example's task
   log: rows kept, time per design, largest relative change of each objective against
   exact merging.
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import platform  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import yaml  # noqa: E402

from benchmarks.common import ROOT, load_example  # noqa: E402
CONFIG = ROOT / "configs" / "harmony_upper_arm.yaml"
COLS = ["time", "Fx", "Fy", "Fz", "Mx", "My", "Mz"]


def make_inputs(folder: Path, n_samples: int, levels: int) -> Path:
    from phri_spring.synthetic.wrench import smooth_random_log

    t, W = smooth_random_log(n_samples, seed=12)
    pd.DataFrame(np.column_stack([np.round(t, 4), np.round(W, 4)]), columns=COLS).to_csv(
        folder / "log.csv", index=False)
    shutil.copy(CONFIG, folder / "base.yaml")
    study = {
        "name": "benchmark grid",
        "config": "base.yaml",
        "loads": ["log.csv"],
        "arm": "compliant",
        "vary": {
            "strap.tension": {"range": [5.0, 40.0], "count": levels},
            "cuff.stiffness.per_angle": {
                "scale": [float(v) for v in np.round(np.geomspace(0.25, 4.0, levels), 6)]},
            "cuff.stiffness.per_angle[5]": {"range": [1.0e5, 2.0e6], "log": True,
                                            "count": levels},
        },
        "plan": "grid",
        "minimise": ["peak_pressure_to_pain_threshold", "lift_off_fraction"],
        "constraints": {"stiffness_translational_N_per_mm": ">= 2"},
    }
    (folder / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    return folder / "study.yaml"


def run_inprocess(study: Path, out: Path, workers: int):
    from phri_spring.workflows.design.study import run_study

    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    r = run_study(study, out, workers=workers, figures=False)
    wall = time.perf_counter() - t0
    overhead = 1.0 - (r.compute_seconds / workers) / r.map_seconds
    return wall, r.map_seconds, r.compute_seconds, overhead, r.table


def run_cli(study: Path, out: Path) -> float:
    shutil.rmtree(out, ignore_errors=True)
    env = dict(os.environ)
    for v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        env.pop(v, None)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "from phri_cli.main import main; main()", "design",
                    str(study), "-o", str(out), "-q"], check=True, env=env)
    return time.perf_counter() - t0


def tolerance_cost(study: Path, log: Path, force_tol: float, moment_tol: float,
                   n_designs: int = 5) -> dict:
    """Rows kept and the largest relative change of each objective, tolerance vs exact."""
    from phri_spring.io.config.study import OBJECTIVES
    from phri_spring.workflows.design.study import evaluate_design, load_set, prepare_study

    st, base, _loads, _values, cfgs = prepare_study(study)
    exact = load_set([log], base.log_columns)
    approx = load_set([log], base.log_columns, force_tol=force_tol, moment_tol=moment_tol)
    idx = np.linspace(0, len(cfgs) - 1, n_designs).astype(int)
    worst = {o: 0.0 for o in OBJECTIVES}
    t_exact = t_approx = 0.0
    for i in idx:
        t0 = time.perf_counter()
        a = evaluate_design(cfgs[i], exact, st.arm)
        t1 = time.perf_counter()
        b = evaluate_design(cfgs[i], approx, st.arm)
        t2 = time.perf_counter()
        t_exact += t1 - t0
        t_approx += t2 - t1
        for o in OBJECTIVES:
            ref = abs(a[o]) if a[o] != 0 else 1.0
            worst[o] = max(worst[o], abs(b[o] - a[o]) / ref)
    return {"rows_exact": len(exact.weights), "rows_tol": len(approx.weights),
            "worst": worst, "designs": len(idx), "time_ratio": t_approx / t_exact}


def task_log_file(folder: Path) -> Path:
    """The bundled example's 10-minute assistance log (examples/design/make_task_log.py)."""
    t, W = load_example("design/make_task_log.py").task_log()
    path = folder / "task_log.csv"
    pd.DataFrame(np.column_stack([np.round(t, 3), np.round(W, 4)]), columns=COLS).to_csv(
        path, index=False)
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    levels = 10 if not args.quick else 5
    repeats = 1 if args.quick else args.repeats
    load_before = os.getloadavg()
    tmp = Path(tempfile.mkdtemp(prefix="phri-design-bench-"))
    try:
        study = make_inputs(tmp, 60_000, levels)
        n_designs = levels ** 3
        cli = [run_cli(study, tmp / "cli")]
        one, two = [], []
        for _ in range(repeats):
            one.append(run_inprocess(study, tmp / "w1", 1))
            two.append(run_inprocess(study, tmp / "w2", 2))
        if not args.quick:
            cli.append(run_cli(study, tmp / "cli"))
        pd.testing.assert_frame_equal(one[0][4], two[0][4], check_exact=True)
        tols = [(name, f, m, tolerance_cost(study, log, f, m))
                for name, log in (("benchmark log", tmp / "log.csv"),
                                  ("example task log", task_log_file(tmp)))
                for f, m in ((1.0, 0.05), (2.0, 0.1))]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    med = statistics.median
    w1 = med(r[0] for r in one)
    w2 = med(r[0] for r in two)
    m1 = med(r[1] for r in one)
    m2 = med(r[1] for r in two)
    lines = [
        f"designs: {n_designs}, samples: 60,000, repeats: {repeats}, machine: "
        f"{os.cpu_count()} cores, {platform.python_version()}",
        f"machine load (1-minute load average, other jobs included): {load_before[0]:.1f} "
        f"at the start, {os.getloadavg()[0]:.1f} at the end",
        f"phri design (CLI, default pool, figures): {', '.join(f'{c:.1f}' for c in cli)} s "
        f"(median {med(cli):.1f} s; target <= 60 s)",
        f"1 worker: wall {w1:.1f} s (batch phase {m1:.1f} s); runs "
        f"{', '.join(f'{r[0]:.1f}' for r in one)} s",
        f"2 workers: wall {w2:.1f} s (batch phase {m2:.1f} s); runs "
        f"{', '.join(f'{r[0]:.1f}' for r in two)} s",
        f"speed-up 2 vs 1 worker: {w1 / w2:.2f}x wall, {m1 / m2:.2f}x batch phase "
        "(target >= 1.7x)",
        f"scheduling overhead: 1 worker {100 * med(r[3] for r in one):.1f} %, 2 workers "
        f"{100 * med(r[3] for r in two):.1f} % of the batch phase (target <= 5 %)",
        f"compute per design (1 worker): {1000 * med(r[2] for r in one) / n_designs:.1f} ms",
    ]
    for name, f, m, tol in tols:
        lines.append(
            f"merge tolerance {f:g} N / {m:g} N*m on the {name}: {tol['rows_exact']:,} -> "
            f"{tol['rows_tol']:,} rows, {tol['time_ratio']:.2f}x the time per design; worst "
            f"relative change over {tol['designs']} designs: "
            + ", ".join(f"{k} {v:.1e}" for k, v in tol["worst"].items()))
    print("\n".join(lines))
    if not args.quick:
        text = ["# phri design benchmark", "",
                "Command: `python -m benchmarks.design_benchmark` (from the repository root, "
                "after `pip install -e .[dask]`).", "",
                "A 1,000-design grid (strap tension x cuff-profile scale x stiffness at "
                "location 5, 10 levels each) over a 10-minute 100 Hz log (60,000 samples), "
                "spring model, compliant arm. Medians over repeats; 1 and 2 workers measured "
                "in turns in the same run.", "", "```", *lines, "```", ""]
        (ROOT / "benchmarks" / "DESIGN_RESULTS.md").write_text("\n".join(text))


if __name__ == "__main__":
    main()
