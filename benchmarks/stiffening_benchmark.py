"""Speed of the exponential tissue law (docs/model.md 11.3) against the linear one.

    OPENBLAS_NUM_THREADS=1 python -m benchmarks.stiffening_benchmark [--repeats 5] \
        [--out benchmarks/STIFFENING.md]

Two one-hour 100 Hz logs (360,000 samples each): a smooth random wrench
(``phri_spring.synthetic.wrench.smooth_random_log``, seed 7, scaled by 3: |F| 160 N at
the median and up to 300 N, moments up to 6.8 N*m, far beyond the paper's loads) and ``examples/wrench_log.csv`` (the paper's loading, with lift-off at every 55.6 N
step) repeated. For the Harmony and the human preset's compliant arm, the linear law and
the exponential law at several stiffening rates beta, it times ``solve`` on the whole log
in this process, the two laws taking turns (linear, exponential, linear, ...), and reports
the median samples/s of each and the median of the pairwise ratios: the machine's speed
drifts, a ratio of neighbours does not. It also counts the samples the mixed iteration
handed to the damped one. Then ``phri simulate`` end to end (CSV in, CSV out) for both
laws on the Harmony preset, same pairing. Writes a markdown table.
"""

from __future__ import annotations

import argparse
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
import yaml

from benchmarks.common import ROOT  # noqa: E402

from phri_spring.io.config import load_config  # noqa: E402
from phri_spring.io.config.yaml_loader import _StrictSafeLoader  # noqa: E402
from phri_spring.physics.springs import newton as spring_newton  # noqa: E402
from phri_spring.physics.contact.solver import solve  # noqa: E402
from phri_spring.synthetic.wrench import smooth_random_log  # noqa: E402
from phri_spring.workflows.common import model_from_config  # noqa: E402

COLS = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
SAMPLES = 360_000
PRESETS = {"harmony": "configs/harmony_upper_arm.yaml", "human": "configs/human_upper_arm.yaml"}
BETAS = (30.0, 100.0, 300.0)


def logs():
    _, W = smooth_random_log(SAMPLES, seed=7)
    df = pd.read_csv(ROOT / "examples" / "wrench_log.csv", comment="#")
    reps = -(-SAMPLES // len(df))
    return {"random": 3.0 * W,
            "paper": np.tile(df[COLS].to_numpy(), (reps, 1))[:SAMPLES]}


def config_with(path, beta, folder):
    """The preset with tissue.stiffening = beta (0: the key removed, the linear law)."""
    raw = yaml.load((ROOT / path).read_text(), Loader=_StrictSafeLoader)
    raw["tissue"].pop("stiffening", None)
    raw["tissue"].pop("law", None)
    if beta:
        raw["tissue"]["stiffening"] = float(beta)
    out = Path(folder) / f"{Path(path).stem}_{beta:g}.yaml"
    out.write_text(yaml.safe_dump(raw))
    return out


def paired(fa, fb, repeats):
    """Alternate fa, fb; median seconds of each and the median of the ratios b/a."""
    ta, tb = [], []
    fa(), fb()                      # warm-up: caches, first-touch pages
    for _ in range(repeats):
        t0 = time.perf_counter()
        fa()
        t1 = time.perf_counter()
        fb()
        t2 = time.perf_counter()
        ta.append(t1 - t0)
        tb.append(t2 - t1)
    return statistics.median(ta), statistics.median(tb), statistics.median(
        [a / b for a, b in zip(ta, tb)])


def handed_rows(model, W):
    count = [0]
    inner = spring_newton._newton_rows

    def spy(m, r, u, steps):
        count[0] += len(r)
        return inner(m, r, u, steps)

    spring_newton._newton_rows = spy
    try:
        sol = solve(model, W)
    finally:
        spring_newton._newton_rows = inner
    return count[0], int((~sol.converged).sum())


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "STIFFENING.md"))
    args = ap.parse_args()
    folder = tempfile.mkdtemp()
    W_all = logs()
    rows = []
    for preset, path in PRESETS.items():
        lin = model_from_config(load_config(config_with(path, 0.0, folder)), "compliant")
        for beta in BETAS:
            exp = model_from_config(load_config(config_with(path, beta, folder)), "compliant")
            for name, W in W_all.items():
                t_lin, t_exp, ratio = paired(lambda: solve(lin, W), lambda: solve(exp, W),
                                             args.repeats)
                handed, failed = handed_rows(exp, W)
                rows.append((preset, beta, name, SAMPLES / t_lin, SAMPLES / t_exp, ratio,
                             handed, failed))
                print(f"{preset} beta {beta:g} {name}: linear {SAMPLES / t_lin:,.0f}/s, "
                      f"exponential {SAMPLES / t_exp:,.0f}/s, ratio {ratio:.3f}, "
                      f"damped {handed}, not converged {failed}", file=sys.stderr)

    # whole process, CSV in and out
    log_csv = Path(folder) / "log1h.csv"
    df = pd.DataFrame(np.round(W_all["random"], 4), columns=COLS)
    df.insert(0, "time", np.round(np.arange(SAMPLES) / 100, 2))
    df.to_csv(log_csv, index=False)
    cfg_lin = config_with(PRESETS["harmony"], 0.0, folder)
    cfg_exp = config_with(PRESETS["harmony"], 100.0, folder)

    def run(cfg):
        return lambda: subprocess.run([sys.executable, "-m", "phri_cli.main", "simulate", str(cfg),
                                       str(log_csv), "-o", str(Path(folder) / "f.csv"), "-q"],
                                      check=True, cwd=ROOT)

    e_lin, e_exp, e_ratio = paired(run(cfg_lin), run(cfg_exp), args.repeats)

    lines = [
        "# The exponential tissue law's speed against the linear law's",
        "",
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores "
        "(shared and noisy: read the ratios, each the median of neighbouring pairs).",
        "Command:",
        "",
        "```bash",
        "OPENBLAS_NUM_THREADS=1 python -m benchmarks.stiffening_benchmark "
        f"--repeats {args.repeats}",
        "```",
        "",
        "`solve` on one-hour 100 Hz logs (360,000 samples), compliant arm, in process; "
        "median of "
        f"{args.repeats} alternating runs each. *damped*: samples the mixed iteration handed "
        "to the damped Newton (docs/model.md 11.1).",
        "",
        "| preset | beta [1/m] | log | linear [samples/s] | exponential [samples/s] | "
        "exponential / linear | damped | not converged |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for preset, beta, name, sl, se, ratio, handed, failed in rows:
        lines.append(f"| {preset} | {beta:g} | {name} | {sl:,.0f} | {se:,.0f} | "
                     f"{100 * ratio:.0f} % | {handed} | {failed} |")
    lines += [
        "",
        "`phri simulate` end to end (Harmony preset, the random log as CSV in, CSV out, "
        "beta = 100 1/m), whole processes:",
        "",
        "| law | wall [s] (median) |",
        "|---|---|",
        f"| linear | {e_lin:.2f} |",
        f"| exponential | {e_exp:.2f} |",
        f"| exponential / linear samples/s | {100 * e_ratio:.0f} % |",
        "",
    ]
    Path(args.out).write_text("\n".join(lines))
    print(f"wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
