"""Speed of Coulomb friction (docs/model.md section 12) on a one-hour log.

    python -m benchmarks.friction_benchmark [--repeats 3] [--mu 0.5] [--arms compliant,rigid]
        [--out benchmarks/FRICTION.md]

The one-hour log is ``examples/wrench_log.csv`` (the paper's horizontal I-Act loading at
100 Hz, 46 s) repeated to 360,000 samples, times running on: a realistic load history
with lift-off at every 55.6 N step. For each preset and arm it times, in this process,
``solve`` on the whole log bonded (no key) and with ``interface.friction_coefficient``
(median of ``--repeats``, the two interleaved), with the preset's own tissue law and, for
a preset whose law is not linear (the human preset's ``tissue.stiffening``), with the
linear law too; counts the samples that needed an event solve and the ones that did not
converge, and times ``phri simulate`` end to end with friction (CSV in, CSV out) on the
human preset with its law, compliant and rigid arms. Writes a markdown table.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.common import ROOT  # noqa: E402

from phri_spring.io.config import load_config  # noqa: E402
from phri_spring.physics.contact.solver import solve  # noqa: E402
from phri_spring.physics.laws import LinearLaw  # noqa: E402
from phri_spring.workflows.common import cuff_wrench, model_from_config  # noqa: E402

COLS = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
SAMPLES = 360_000


def one_hour_log():
    df = pd.read_csv(ROOT / "examples" / "wrench_log.csv", comment="#")
    reps = -(-SAMPLES // len(df))
    W = np.tile(df[COLS].to_numpy(), (reps, 1))[:SAMPLES]
    t = np.round(np.arange(SAMPLES) / 100.0, 2)
    return t, W


def timed(fn, repeats):
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = fn()
        out.append(time.perf_counter() - t0)
    return statistics.median(out), res


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--mu", type=float, default=0.5)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--coupled-minutes", type=float, default=5.0,
                    help="minutes of the log the coupled arm is timed on")
    ap.add_argument("--arms", default="compliant,rigid,coupled",
                    help="comma-separated arms to time (default: all three)")
    args = ap.parse_args()
    arms = [a.strip() for a in args.arms.split(",") if a.strip()]
    t, W_lc = one_hour_log()
    rows = []
    for preset in ("human_upper_arm", "harmony_upper_arm"):
        base = load_config(ROOT / "configs" / f"{preset}.yaml")
        # friction with the preset's own tissue law and, where that law is not linear (the
        # human preset's tissue.stiffening), with the linear law too, for comparison
        variants = [(base.tissue_law, base)]
        if base.tissue_law != "linear":
            variants.append(("linear", dataclasses.replace(
                base, tissue_law="linear", tissue_law_class=LinearLaw,
                tissue_law_parameters={})))
        W = cuff_wrench(base, W_lc)
        for arm in arms:
            for law, cfg in variants:
                if arm == "rigid" and law != base.tissue_law:
                    continue                  # no tissue on the rigid arm: one law
                bonded_model = model_from_config(cfg, arm)
                fric_model = model_from_config(
                    dataclasses.replace(cfg, friction_coefficient=args.mu), arm)
                solve(fric_model, W[:2000])      # warm: imports, FE cache
                # the coupled arm's events are dense solves: timed on the first minutes only
                m = SAMPLES if arm != "coupled" else int(args.coupled_minutes * 6000)
                Wm = W[:m]
                tb, tf = [], []
                sol = None
                for _ in range(args.repeats):     # interleaved: drift touches both alike
                    tb.append(timed(lambda: solve(bonded_model, Wm), 1)[0])
                    dt, sol = timed(lambda: solve(fric_model, Wm), 1)
                    tf.append(dt)
                tb, tf = statistics.median(tb), statistics.median(tf)
                events = int((sol.iterations > 1).sum())
                law_name = law if arm != "rigid" else "(none)"
                rows.append((preset, arm, law_name, m, tb, tf, events,
                             int((~sol.converged).sum())))
                print(rows[-1], flush=True)
    # end to end: phri simulate with friction, human preset with its law, CSV -> CSV
    e2e = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        log = tmp / "log_1h.csv"
        df = pd.DataFrame(W_lc, columns=COLS)
        df.insert(0, "time", t)
        df.to_csv(log, index=False)
        import yaml

        raw = yaml.safe_load((ROOT / "configs" / "human_upper_arm.yaml").read_text())
        raw.setdefault("interface", {})["friction_coefficient"] = args.mu
        cfg = tmp / "human_mu.yaml"
        cfg.write_text(yaml.safe_dump(raw))
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        for arm in [a for a in ("compliant", "rigid") if a in arms]:
            cmd = [sys.executable, "-c", "from phri_cli.main import phri; phri()", "simulate",
                   str(cfg), str(log), "-o", str(tmp / "out.csv"), "--arm", arm]
            walls = []
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
                walls.append(time.perf_counter() - t0)
            e2e[arm] = statistics.median(walls)
    lines = [
        f"One-hour log: {SAMPLES:,} samples (examples/wrench_log.csv repeated), mu = {args.mu}, "
        f"median of {args.repeats}, bonded and friction interleaved. Machine: "
        f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"numpy {np.__version__}.",
        "",
        "| preset | arm | tissue law | samples | bonded `solve` [s] | friction `solve` [s] | "
        "friction samples/s | one hour with friction [s] | friction / bonded time | "
        "event samples | not converged |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for preset, arm, law, m, tb, tf, ev, nc in rows:
        lines.append(f"| {preset} | {arm} | {law} | {m:,} | {tb:.2f} | {tf:.2f} | "
                     f"{m / tf:,.0f} | "
                     f"{tf * SAMPLES / m:.1f}{'' if m == SAMPLES else ' (scaled)'} | "
                     f"{tf / tb:.1f}x | {ev:,} ({100 * ev / m:.1f} %) | {nc} |")
    for arm, wall in e2e.items():
        lines += ["", f"`phri simulate` end to end with friction (human preset with its "
                  f"tissue law, {arm} arm, CSV in and out, 1 h): {wall:.1f} s "
                  f"(median of {args.repeats})."]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        args.out.write_text(args.out.read_text() + "\n" + text if args.out.exists() else text)


if __name__ == "__main__":
    main()
