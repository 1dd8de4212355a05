"""Benchmarks of phri-spring: every scenario against its baseline, in one run.

Usage (from the repository root, after `pip install -e .`):

    python -m benchmarks.run_benchmarks                 # full run, writes benchmarks/RESULTS.md
    python -m benchmarks.run_benchmarks --quick         # fewer repeats, no ten-hour log
    python -m benchmarks.run_benchmarks --only compare  # one group of rows (printed; not
    python -m benchmarks.run_benchmarks --only plot     #   written to RESULTS.md without --out)
    python -m benchmarks.run_benchmarks --only simulate # the 1 h log against the per-sample loop

Logs are generated into a temporary folder (synthetic, fixed seeds, values
rounded to 4 decimals like a load-cell export). phri-spring's modules are
compiled to bytecode first, as an installed package's are. Times are medians over repeats;
ratios are taken against a baseline measured in the same run, because shared
machines are noisy. In-process scenarios (solver, single sample, fine meshes)
run on one core (BLAS limited to one thread, process pinned to one CPU);
command-line scenarios run `phri` as a user would, as a separate process, and
report its wall time and peak resident memory (from the kernel's rusage).
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_v] = "1"          # in-process scenarios: one core (set before numpy loads)

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from benchmarks.common import (COLS, HARMONY_CONFIG as CONFIG, ROOT,  # noqa: E402,F401
                               child_env, make_log, run_interleaved, run_process)


def compile_bytecode() -> None:
    """Compile phri-spring's modules to bytecode, as ``pip install`` does for a package.

    An editable install run with PYTHONDONTWRITEBYTECODE set (as on the project's
    machine) would otherwise recompile every module on every start (about 20 ms).
    """
    import compileall
    import importlib.util

    for name in ("phri_spring", "phri_cli"):
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.submodule_search_locations:
            for folder in spec.submodule_search_locations:
                compileall.compile_dir(folder, quiet=1)


from benchmarks.common import median_time, pin_one_cpu  # noqa: E402,F401


def fine_model(rows: int, angles: int):
    """A Harmony-like cuff (245 deg wrap, 75 mm long) cut into rows x angles elements."""
    from phri_spring.physics.cuff.geometry import cuff_geometry
    from phri_spring.physics.springs.model import build_model, tissue_element_stiffness

    span = 245.0
    step = span / angles
    g = cuff_geometry(np.linspace(-0.025, 0.025, rows), 0.045, 0.075 / rows,
                      57.5 + step / 2, step, angles)
    th = np.degrees(g.theta)
    k_c = 1e6 * 0.5 ** (np.abs(((th - 250.0 + 180.0) % 360.0) - 180.0) / 35.0)
    k_t = tissue_element_stiffness(np.full(g.n, 4242.0), g.areas)
    return build_model(g, k_t, k_c)


EXPERIMENT = ROOT / "examples" / "experiment" / "manifest.yaml"


def bench_simulate(phri, work, log_csv, log_pq, reps, base_reps, row):
    """The one-hour log end to end: the default ``simulate`` (CSV), ``--arm rigid`` and
    Parquet in and out, taking turns (the ratios between them stay fair when the machine's
    speed drifts); then the per-sample loop (benchmarks/baseline_loop.py) in the same run,
    the yardstick whose ratio shows a slowdown of the default path."""
    out_csv = work / "forces.csv"
    (t_csv, rss_csv, _, c_csv), (t_rigid, _, _, c_rigid), (t_pq, rss_pq, _, _) = run_interleaved(
        [phri + ["simulate", str(CONFIG), str(log_csv), "-o", str(out_csv), "-q"],
         phri + ["simulate", str(CONFIG), str(log_csv), "-o", str(work / "rigid.csv"),
                 "--arm", "rigid", "-q"],
         phri + ["simulate", str(CONFIG), str(log_pq), "-o", str(work / "forces.parquet"), "-q"]],
        reps, cpu=True)
    t_base, rss_base, _, c_base = run_process(
        [sys.executable, str(ROOT / "benchmarks" / "baseline_loop.py"), str(CONFIG), str(log_csv),
         str(work / "base.csv")], base_reps, warmup=False, cpu=True)
    row("simulate 1 h @ 100 Hz (360,000 samples), CSV -> CSV", f"{t_csv:.2f} s",
        f"{t_base:.1f} s (per-sample loop)", f"{t_base / t_csv:.1f}x faster",
        "<= 1.5 s and >= 9x", t_csv <= 1.5 and t_base / t_csv >= 9)
    # CPU seconds (its writer threads included) against the loop's: a ratio that a busy
    # shared machine moves less than it moves wall times measured minutes apart
    row("  CPU time (user + system), CSV -> CSV", f"{c_csv:.2f} s",
        f"{c_base:.1f} s (per-sample loop)", f"{c_base / c_csv:.1f}x less", ">= 9x",
        c_base / c_csv >= 9)
    row("  peak memory, CSV -> CSV", f"{rss_csv:.0f} MB", f"{rss_base:.0f} MB", "",
        "<= 500 MB", rss_csv <= 500)
    row("simulate 1 h, --arm rigid, CSV -> CSV", f"{t_rigid:.2f} s",
        f"{t_base:.1f} s (per-sample loop, compliant)", f"{t_base / t_rigid:.1f}x faster",
        "<= 1.5 s and >= 9x", t_rigid <= 1.5 and t_base / t_rigid >= 9)
    row("  CPU time (user + system), --arm rigid", f"{c_rigid:.2f} s",
        f"{c_base:.1f} s (per-sample loop, compliant)", f"{c_base / c_rigid:.1f}x less", ">= 9x",
        c_base / c_rigid >= 9)
    row("simulate 1 h, Parquet -> Parquet", f"{t_pq:.2f} s", f"{t_csv:.2f} s (CSV)",
        f"{t_csv / t_pq:.1f}x", "<= 0.8 s", t_pq <= 0.8)
    row("  peak memory, Parquet -> Parquet", f"{rss_pq:.0f} MB", "", "", "<= 500 MB",
        rss_pq <= 500)


def bench_compare(phri, work, reps, row):
    """`phri compare` on the bundled example with figures and with --no-figures, in turns."""
    # --output (not -o): the folder is rewritten in place on every run, not deleted
    (t_fig, _, _), (t_tab, _, _) = run_interleaved(
        [phri + ["compare", str(CONFIG), str(EXPERIMENT), "--output", str(work / "cmp_fig"),
                 "-q"],
         phri + ["compare", str(CONFIG), str(EXPERIMENT), "--output", str(work / "cmp_tab"),
                 "-q", "--no-figures"]], reps)
    n_png = len(list((work / "cmp_fig").rglob("*.png")))
    row(f"compare, bundled example: figures vs --no-figures ({n_png} figures, "
        f"{os.cpu_count()} cores)", f"{t_fig:.2f} s", f"{t_tab:.2f} s (--no-figures)",
        f"{t_fig / t_tab:.1f}x", "<= 4x", t_fig / t_tab <= 4.0)


def bench_plot(phri, work, row, log10h, reps=3):
    """`phri simulate --plot` on a 10 h log: peak memory and time against the run without."""
    out = work / "forces_plot.csv"
    (t_no, rss_no, _), (t_plot, rss_plot, _) = run_interleaved(
        [phri + ["simulate", str(CONFIG), str(log10h), "-o", str(out), "-q"],
         phri + ["simulate", str(CONFIG), str(log10h), "-o", str(out), "-q",
                 "--plot", str(work / "plot.png")]], reps)
    row("simulate 10 h, CSV -> CSV, --plot (peak pressure and heat map)",
        f"{t_plot:.1f} s, {rss_plot:.0f} MB", f"{t_no:.1f} s, {rss_no:.0f} MB (without --plot)",
        f"{rss_plot - rss_no:+.0f} MB, {t_plot / t_no:.2f}x the time",
        "<= +100 MB", rss_plot - rss_no <= 100)
    out.unlink(missing_ok=True)


def _table():
    """(row, markdown): record table rows (printing each as it comes) and render them."""
    rows = []

    def row(scenario, value, baseline, ratio, target, ok):
        rows.append((scenario, value, baseline, ratio, target, "yes" if ok else "**no**"))
        print(f"{scenario}: {value} | {baseline} | {ratio} | {target} | "
              f"{'met' if ok else 'NOT met'}", flush=True)

    def markdown():
        lines = ["| scenario | result | baseline (same run) | ratio | target | met |",
                 "|---|---|---|---|---|---|"]
        return lines + ["| " + " | ".join(r) + " |" for r in rows]

    return row, markdown


def main_only(args):
    """The rows of one group (``--only``), printed (and written with ``--out``)."""
    compile_bytecode()
    work = Path(args.workdir or tempfile.mkdtemp(prefix="phri-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    phri = [sys.executable, "-m", "phri_cli.main"]
    row, markdown = _table()
    reps = 3 if args.quick else 5
    if args.only == "compare":
        bench_compare(phri, work, reps, row)
    elif args.only == "simulate":
        log_csv, log_pq = work / "log_1h.csv", work / "log_1h.parquet"
        for log in (log_csv, log_pq):
            if not log.exists():
                make_log(log, 360_000, seed=1)
        bench_simulate(phri, work, log_csv, log_pq, reps, 1 if args.quick else 3, row)
    else:
        log10h = work / "log_10h.csv"
        if not log10h.exists():
            print(f"generating the 10 h log in {work} ...", flush=True)
            make_log(log10h, 3_600_000, seed=11)
        bench_plot(phri, work, row, log10h, reps=2 if args.quick else 3)
    lines = markdown()
    text = (f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python "
            f"{platform.python_version()}. {time.strftime('%Y-%m-%d')}.\n\nCommand: `python "
            f"benchmarks/run_benchmarks.py --only {args.only}"
            f"{' --quick' if args.quick else ''}`\n\n" + "\n".join(lines) + "\n")
    print("\n" + text)
    if args.out_given:
        Path(args.out).write_text(text)
    if args.workdir is None:
        shutil.rmtree(work, ignore_errors=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats; skip the ten-hour log")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "RESULTS.md"))
    ap.add_argument("--workdir", default=None, help="where logs go (default: a temp folder)")
    ap.add_argument("--only", choices=("compare", "plot", "simulate"), default=None,
                    help="run one group of rows: compare (figures vs --no-figures), plot "
                         "(simulate --plot on a 10 h log) or simulate (the 1 h log: default, "
                         "--arm rigid and Parquet against the per-sample loop)")
    args = ap.parse_args()
    args.out_given = "--out" in sys.argv
    if args.only:
        return main_only(args)
    reps = 3 if args.quick else 7
    compile_bytecode()
    work = Path(args.workdir or tempfile.mkdtemp(prefix="phri-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    phri = [sys.executable, "-m", "phri_cli.main"]
    row, markdown = _table()

    n1h = 360_000
    log_csv, log_pq = work / "log_1h.csv", work / "log_1h.parquet"
    print(f"generating logs in {work} ...", flush=True)
    make_log(log_csv, n1h, seed=1)
    make_log(log_pq, n1h, seed=1)
    tiny = work / "log_tiny.csv"
    make_log(tiny, 100, seed=1)

    # 1. start-up
    t_help, _, _ = run_process(phri + ["--help"], 10)
    t_py, _, _ = run_process([sys.executable, "-c", "pass"], 10)
    row("`phri --help` start-up", f"{t_help:.3f} s", f"{t_py:.3f} s (bare python)",
        f"{t_help / t_py:.1f}x", "<= 0.3 s", t_help <= 0.3)

    # 2-3. end to end: CSV, --arm rigid and Parquet taking turns, then the per-sample loop
    bench_simulate(phri, work, log_csv, log_pq, reps, 1 if args.quick else 3, row)

    # 3b. compare: figures against tables only
    bench_compare(phri, work, reps, row)

    # 4. longer logs: streaming in bounded memory, time linear in length. The 100-sample,
    # 1 h, 3 h and 10 h runs take turns (5 rounds after a warm-up round), so that a slow
    # spell of the machine does not fall on one length only.
    if not args.quick:
        sizes = {0: 100, 1: n1h, 3: 3 * n1h, 10: 10 * n1h}
        logs_h = {0: tiny, 1: log_csv}
        for hours, seed in ((3, 13), (10, 11)):
            logs_h[hours] = work / f"log_{hours}h.csv"
            make_log(logs_h[hours], sizes[hours], seed=seed)
        cmds = [phri + ["simulate", str(CONFIG), str(logs_h[h]), "-o",
                        str(work / f"forces_{h}h.csv"), "-q"] for h in sizes]
        timed = dict(zip(sizes, run_interleaved(cmds, 5)))
        t_tiny = timed[0][0]
        per = {h: (timed[h][0] - t_tiny) / sizes[h] * 1e6 for h in (1, 3, 10)}
        for hours in (3, 10):
            row(f"simulate {hours} h ({sizes[hours]:,} samples), CSV -> CSV",
                f"{timed[hours][0]:.1f} s",
                f"{timed[1][0]:.2f} s (1 h); {t_tiny:.2f} s start-up (100 samples)",
                f"{timed[hours][0] / timed[1][0]:.1f}x the 1 h time", "", True)
        spread = max(per.values()) / min(per.values())
        row("  time per sample beyond start-up, 1 h / 3 h / 10 h (runs taking turns)",
            " / ".join(f"{per[h]:.2f}" for h in (1, 3, 10)) + " us", "", f"max/min {spread:.2f}",
            "linear: max/min <= 1.25", spread <= 1.25)
        row("  peak memory, 1 h / 3 h / 10 h",
            " / ".join(f"{timed[h][1]:.0f}" for h in (1, 3, 10)) + " MB", "", "", "<= 500 MB",
            max(timed[h][1] for h in (1, 3, 10)) <= 500)
        # --plot on the 10 h log: memory against the run without it
        bench_plot(phri, work, row, logs_h[10])
        for hours in (3, 10):
            logs_h[hours].unlink()
        for h in sizes:
            (work / f"forces_{h}h.csv").unlink(missing_ok=True)

    # in-process scenarios: one core (pinned only now: child processes would inherit
    # the affinity, and forking a parent holding large arrays inflates a child's peak RSS)
    cpu = pin_one_cpu()
    from phri_spring.io.config import load_config
    from phri_spring.io.logs import read_wrench_log
    from phri_spring.physics.contact.solver import FactorCache, Solver, solve, solve_per_sample
    from phri_spring.workflows.common import cuff_wrench, model_from_config

    cfg = load_config(CONFIG)
    model = model_from_config(cfg)
    _, w_lc = read_wrench_log(log_pq)
    W = cuff_wrench(cfg, w_lc)

    # 5. solver alone (one factor cache kept across the calls, as a stream keeps it)
    cache = FactorCache()
    solve(model, W[:1000], cache=cache)
    t_solve = median_time(lambda: solve(model, W, cache=cache), reps)
    n_ref = 20_000
    t_ref = median_time(lambda: solve_per_sample(model, W[:n_ref]), 1 if args.quick else 3)
    rate, rate_ref = n1h / t_solve, n_ref / t_ref
    sol = solve(model, W)
    ref = solve_per_sample(model, W[:n_ref])
    same = float(np.max(np.abs(sol.forces[:n_ref] - ref.forces)))
    row(f"solver alone, 21 elements, 1 h log (CPU {cpu})", f"{rate:,.0f} samples/s",
        f"{rate_ref:,.0f} samples/s (per-sample loop)", f"{rate / rate_ref:.0f}x",
        ">= 1,000,000 samples/s", rate >= 1e6)
    row("  mean solves per sample; max |difference| to the per-sample loop",
        f"{sol.iterations.mean():.3f}", f"{same:.1e} N", "", "identical to round-off",
        same < 1e-9)

    # 6. single sample
    solver = Solver(model)
    ts = []
    for i in range(50_000):
        w = W[i]
        t0 = time.perf_counter_ns()
        solver.forces(w)
        ts.append(time.perf_counter_ns() - t0)
    med_us = statistics.median(ts) / 1000.0
    t_one = []
    for i in range(2000):
        w = W[i]
        t0 = time.perf_counter_ns()
        solve_per_sample(model, w[None])
        t_one.append(time.perf_counter_ns() - t0)
    med_one = statistics.median(t_one) / 1000.0
    row("single-sample call `Solver.forces` (control loop)", f"{med_us:.1f} us",
        f"{med_one:.1f} us (per-sample loop, 1 sample)", f"{med_one / med_us:.1f}x",
        "<= 50 us median", med_us <= 50)

    # 7. fine meshes
    from phri_spring.synthetic.wrench import smooth_random_log

    for (r_, a_, n_, target) in ((10, 36, 100_000, 100_000), (20, 72, 20_000, 20_000)):
        fm = fine_model(r_, a_)
        _, Wf = smooth_random_log(n_, seed=7)
        fcache = FactorCache()
        solve(fm, Wf[:500], cache=fcache)
        buf = np.empty((n_, fm.n))
        t_f = median_time(lambda: solve(fm, Wf, out=buf, cache=fcache), 3)  # streaming: buffer reused
        t_fresh = median_time(lambda: solve(fm, Wf, cache=fcache), 3)       # a fresh output array
        n_b = 1000
        t_fb = median_time(lambda: solve_per_sample(fm, Wf[:n_b]), 1)
        rate_f = n_ / t_f
        row(f"fine mesh {r_} x {a_} ({fm.n} elements), forces into a reused array",
            f"{rate_f:,.0f} samples/s", f"{n_b / t_fb:,.0f} samples/s (per-sample loop)",
            f"{rate_f / (n_b / t_fb):.0f}x", f">= {target:,} samples/s", rate_f >= target)
        row(f"  same, a fresh {n_ * fm.n * 8 / 1e6:.0f} MB output array each call",
            f"{n_ / t_fresh:,.0f} samples/s", "", "", "(page faults of the new array)", True)

    import numpy  # noqa: F401
    import pyarrow

    header = (f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python "
              f"{platform.python_version()}, numpy {np.__version__}, pyarrow {pyarrow.__version__}."
              f" {time.strftime('%Y-%m-%d')}.")
    lines = markdown()
    text = (f"{header}\n\nCommand: `python -m benchmarks.run_benchmarks"
            f"{' --quick' if args.quick else ''}`\n\n" + "\n".join(lines) + "\n")
    Path(args.out).write_text(text)
    print("\n" + text)
    print(json.dumps({"workdir": str(work)}))
    if args.workdir is None:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
