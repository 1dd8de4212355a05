"""Cost of a muscle activation column along a loading path (docs/model.md section 15.2).

The coupled arm and the spring arm with friction solve an activation column by giving each
distinct activation value its own compliance form: a held level costs nothing more, a
channel that changes at every sample one factorisation per sample. This runs
``phri simulate`` on the bundled example log (4,600 samples) three ways -- no column, a
column of four levels (the activation rounded to quarters), a continuous column (a
0.33 Hz sine) -- for both arms, the commands in turn (A B C A B C ...), and prints the
median wall time of each and its ratio to the run without the column, pair by pair.

Usage (from the repository root, after ``pip install -e ".[fe]"``):

    python -m benchmarks.activation_benchmark               # 5 rounds
    python -m benchmarks.activation_benchmark --repeats 9
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
HUMAN = REPO / "configs" / "human_upper_arm.yaml"
LOG = REPO / "examples" / "wrench_log.csv"


def logs(folder: Path) -> dict:
    """The example log without, with a four-level and with a continuous activation."""
    header = [ln for ln in LOG.read_text().splitlines() if not ln.startswith("#")][0]
    data = np.loadtxt(LOG, delimiter=",", comments="#", skiprows=2)
    a = np.clip(0.5 + 0.5 * np.sin(2 * np.pi * data[:, 0] / 3.0), 0.0, 1.0)
    out = {}
    for name, col in (("none", None), ("levels", np.round(4 * a) / 4), ("continuous", a)):
        path = folder / f"{name}.csv"
        rows, head = (data, header) if col is None else (np.column_stack([data, col]),
                                                         header + ",activation")
        np.savetxt(path, rows, delimiter=",", header=head, comments="", fmt="%.9g")
        out[name] = path
    return out


def friction_config(folder: Path) -> Path:
    import yaml

    raw = yaml.safe_load(HUMAN.read_text())
    raw.setdefault("interface", {})["friction_coefficient"] = 0.5
    path = folder / "human_friction.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        paths = logs(folder)
        arms = {"coupled (human preset)": (HUMAN, ["--arm", "coupled"]),
                "compliant, friction 0.5": (friction_config(folder), [])}
        cmds = {}
        for arm, (cfg, extra) in arms.items():
            for name, log in paths.items():
                cmds[(arm, name)] = [sys.executable, "-m", "phri_cli.main", "simulate",
                                     str(cfg), str(log), "-o", str(folder / "out.csv"), "-q",
                                     *extra]
        times = {k: [] for k in cmds}
        for _ in range(a.repeats + 1):              # the first round warms the caches
            for k, cmd in cmds.items():
                t0 = time.perf_counter()
                subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL)
                times[k].append(time.perf_counter() - t0)
        print("| arm | activation column | median wall [s] | / no column (median of pairs) |")
        print("| --- | --- | --- | --- |")
        for (arm, name), v in times.items():
            ref = times[(arm, "none")][1:]
            ratio = statistics.median(x / r for x, r in zip(v[1:], ref))
            print(f"| {arm} | {name} | {statistics.median(v[1:]):.2f} | {ratio:.2f} |")


if __name__ == "__main__":
    main()
