"""Speed of the coupled tissue model against the spring model, measured in the same run.

    python -m benchmarks.coupled_benchmark            # writes benchmarks/COUPLED_RESULTS.md

Targets: the coupled solve of a one-hour 100 Hz log (360,000 samples) runs
at >= 25 % of the spring model's samples/s; the single-sample ``Solver`` call takes
<= 100 us (median). The surface stiffness comes from the built-in FE (the ``fe``
extra), built once and cached; the first build and a cached reload are timed too.
Each solver figure is the median of 5 runs after a warm-up, on one core (BLAS single
threaded), spring and coupled taking turns so that the machine's drift falls on both.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    from phri_spring.io.config import config_from_dict, load_yaml
    from phri_spring.physics.contact.solver import FactorCache, Solver, solve
    from phri_spring.synthetic.wrench import smooth_random_log
    from phri_spring.workflows.common import cuff_wrench, model_from_config

    path = ROOT / "configs" / "harmony_upper_arm.yaml"
    raw = load_yaml(path)
    raw["tissue"]["continuum"] = {"thickness": 0.02, "young_modulus": 1.0e5}
    cfg = config_from_dict(raw, path=path, base_dir=path.parent)
    cache_dir = Path(tempfile.mkdtemp(prefix="phri-fe-cache-"))

    t0 = time.perf_counter()
    coupled = model_from_config(cfg, "coupled", cache_dir=cache_dir)
    t_build = time.perf_counter() - t0
    reloads = []
    for _ in range(5):
        t0 = time.perf_counter()
        model_from_config(cfg, "coupled", cache_dir=cache_dir)
        reloads.append(time.perf_counter() - t0)
    spring = model_from_config(cfg, "compliant")

    _, w_lc = smooth_random_log(360_000, seed=1)
    W = cuff_wrench(cfg, w_lc)
    caches = {"spring": FactorCache(), "coupled": FactorCache()}
    models = {"spring": spring, "coupled": coupled}
    times = {"spring": [], "coupled": []}
    for name in models:
        solve(models[name], W[:2000], cache=caches[name])
    for _ in range(5):
        for name in models:
            t0 = time.perf_counter()
            sol = solve(models[name], W, cache=caches[name])
            times[name].append(time.perf_counter() - t0)
            assert sol.converged.all()
    rate = {k: len(W) / statistics.median(v) for k, v in times.items()}
    ratio = rate["coupled"] / rate["spring"]

    single = {}
    for name, model in models.items():
        solver = Solver(model)
        ts = []
        for w in W[:20_000]:
            t0 = time.perf_counter_ns()
            solver.forces(w)
            ts.append(time.perf_counter_ns() - t0)
        single[name] = statistics.median(ts) / 1000.0

    lines = [
        "# Coupled tissue model: speed against the spring model",
        "",
        f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, numpy {np.__version__}. "
        f"{time.strftime('%Y-%m-%d')}. Command: `python -m benchmarks.coupled_benchmark`.",
        "Harmony config with `tissue.continuum: {thickness: 0.02, young_modulus: 1.0e5}`, "
        f"{coupled.dofs} dofs per patch; a one-hour 100 Hz synthetic log (360,000 samples).",
        "",
        "| scenario | result | baseline (same run) | ratio | target | met |",
        "|---|---|---|---|---|---|",
        f"| coupled solve, 1 h log | {rate['coupled']:,.0f} samples/s | "
        f"{rate['spring']:,.0f} samples/s (spring model) | {100 * ratio:.0f} % | >= 25 % | "
        f"{'yes' if ratio >= 0.25 else 'NO'} |",
        f"| single-sample `Solver.forces`, coupled | {single['coupled']:.1f} us | "
        f"{single['spring']:.1f} us (spring model) | {single['coupled'] / single['spring']:.1f}x | "
        f"<= 100 us | {'yes' if single['coupled'] <= 100 else 'NO'} |",
        f"| surface stiffness, first build (built-in FE) | {t_build:.1f} s | | | <= 60 s | "
        f"{'yes' if t_build <= 60 else 'NO'} |",
        f"| surface stiffness, cached reload (median of 5) | {statistics.median(reloads):.3f} s "
        f"| | | <= 0.5 s | {'yes' if statistics.median(reloads) <= 0.5 else 'NO'} |",
        "",
    ]
    text = "\n".join(lines)
    print(text)
    if "--no-write" not in sys.argv:
        (ROOT / "benchmarks" / "COUPLED_RESULTS.md").write_text(text)


if __name__ == "__main__":
    main()
