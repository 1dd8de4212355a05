"""The reduced hyperelastic (neo-Hookean or Ogden) coupled model against its FE, and its speed.

Run from the repository root (progress on stderr, the markdown report on stdout or
``--out``)::

    OPENBLAS_NUM_THREADS=1 python -m benchmarks.hyperelastic_rom --levels 1,2 \
        --cache-dir /tmp/phri_cache --out benchmarks/HYPERELASTIC_ROM.md

The config is ``configs/human_upper_arm.yaml`` with a rigid cuff (``cuff.stiffness: inf``)
and ``tissue.continuum.law: neo_hookean`` (range 70 N / 4 N*m, the defaults), the set-up of
``benchmarks/HYPERELASTIC_REFERENCE.json``. For each identification mesh level it
identifies (or reads from the cache) the corrections with the shipped ray count, then
solves the reference's 36 load-controlled cases (the paper's 11.1 / 33.4 / 55.6 N along
and 0.39 / 1.17 / 1.95 N*m about every cuff axis, with the strap preload) with the linear
part at the shipped mesh level 3, and compares with the FE at levels 3 (and 4, where the
JSON has it): RMSE over the 21 patches of the normal forces in % of the case's peak, the
largest patch difference, and the cuff displacement error |S (u - u_FE)| / |S u_FE|, S =
diag(1, 1, 1, R, R, R) (rotations as the arc they move the skin, R = 45 mm). Then the
speed, in this process: ``solve`` on one-hour 100 Hz logs (360,000 samples; a smooth random
wrench scaled so that 99 % of it lies within 80 % of the identified range, and the paper's
loading repeated, as cuff wrenches) for the linear coupled model
of the same config and the reduced one taking turns, medians of samples/s and of the
pairwise ratios; and ``Solver.forces`` one sample at a time (the live path), median us.

``--law ogden --ogden-alpha A --reference JSON``: the same for the Ogden layer, against a
reference made by ``hyperelastic_reference.py --law ogden --ogden-alpha A``.
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import yaml  # noqa: E402

from benchmarks.common import ROOT  # noqa: E402

from phri_spring.io.cache import hyper_reduction as store  # noqa: E402
from phri_spring.io.config import config_from_dict  # noqa: E402
from phri_spring.io.config.yaml_loader import _StrictSafeLoader  # noqa: E402
from phri_spring.physics.hyperelastic.coupled import HyperCoupledModel  # noqa: E402
from phri_spring.physics.contact.solver import Solver, solve  # noqa: E402
from phri_spring.synthetic.wrench import smooth_random_log  # noqa: E402
from phri_spring.workflows.common import _linear_coupled_model, continuum_modulus  # noqa: E402
from phri_spring.workflows.hyper_arm import strap_settings  # noqa: E402

PRESET = ROOT / "configs" / "human_upper_arm.yaml"
REFERENCE = ROOT / "benchmarks" / "HYPERELASTIC_REFERENCE.json"
COLS = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
SAMPLES = 360_000
R_ARM = 0.045
S = np.array([1, 1, 1, R_ARM, R_ARM, R_ARM])


def log(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def config(law="neo_hookean", alpha=None, max_force=None, max_moment=None):
    raw = yaml.load(PRESET.read_text(), Loader=_StrictSafeLoader)
    raw["cuff"]["stiffness"] = float("inf")
    raw["tissue"]["continuum"]["law"] = law
    if alpha is not None:
        raw["tissue"]["continuum"]["ogden_alpha"] = float(alpha)
    # the identified range (the law's default where not given)
    if max_force is not None:
        raw["tissue"]["continuum"]["max_force"] = float(max_force)
    if max_moment is not None:
        raw["tissue"]["continuum"]["max_moment"] = float(max_moment)
    return config_from_dict(raw, path=PRESET, base_dir=PRESET.parent)


def reduced(cfg, linear3, level, cache_dir):
    """The reduced model with its corrections identified at FE mesh ``level``."""
    ident = _linear_coupled_model(cfg, cache_dir=cache_dir, level=level)
    t0 = time.perf_counter()

    def progress(done, total):
        if done % 8 == 0 or done == total:
            log(f"identification level {level}: ray {done}/{total} "
                f"({time.perf_counter() - t0:.0f} s)")

    red = store.load_or_identify(
        cfg.geometry(), cfg.continuum_thickness, float(np.mean(continuum_modulus(cfg))),
        cfg.poisson_ratio, ident, max_force=cfg.continuum_max_force,
        max_moment=cfg.continuum_max_moment, strap=strap_settings(cfg), cache_dir=cache_dir,
        level=level,
        rays=store.IDENTIFY_RAYS, patch_gap=cfg.continuum_patch_gap, progress=progress,
        law=cfg.continuum_law, ogden_alpha=cfg.continuum_ogden_alpha)
    log(f"identification level {level}: {red.info['source']} "
        f"({red.info.get('seconds_identify', red.info['seconds']):.0f} s)")
    return HyperCoupledModel(linear=linear3, reduction=red, continuum_law=cfg.continuum_law,
                             pain_threshold_kpa=cfg.pain_threshold_kpa)


def compare_cases(model, cases, answers=None):
    """Per case metrics of a model's answers (or of given (forces, u, iterations))."""
    if answers is None:
        sol = solve(model, np.array([c["wrench"] for c in cases]))
        answers = zip(sol.forces, sol.u, sol.iterations)
        ok_all = sol.converged
    else:
        ok_all = np.ones(len(cases), dtype=bool)
    rows = []
    for c, (f, u, its), ok in zip(cases, answers, ok_all):
        f, u = np.asarray(f, float), np.asarray(u, float)
        fr, ur = np.array(c["normal_forces"]), np.array(c["u"])
        peak = np.abs(fr).max()
        primary = slice(0, 3) if c["label"].startswith("F") else slice(3, 6)
        rows.append(dict(
            label=c["label"], converged=bool(ok), iterations=int(its),
            rmse_pct=100 * np.sqrt(np.mean((f - fr) ** 2)) / peak,
            max_pct=100 * np.abs(f - fr).max() / peak, peak_fe=peak, peak_rom=np.abs(f).max(),
            u_pct=100 * np.linalg.norm((u - ur) * S) / np.linalg.norm(ur * S),
            primary_pct=100 * np.linalg.norm(u[primary] - ur[primary])
            / np.linalg.norm(ur[primary]),
            u_fe=ur.tolist(), u_rom=u.tolist(), forces_rom=f.tolist()))
    return rows


def paired(fa, fb, repeats):
    """Median samples/s of fa and fb (taking turns) and the median of the ratios b/a."""
    a, b = [], []
    for _ in range(repeats):
        a.append(fa())
        b.append(fb())
    return statistics.median(a), statistics.median(b), statistics.median(
        [y / x for x, y in zip(a, b)])


def rate(model, W):
    t0 = time.perf_counter()
    sol = solve(model, W)
    dt = time.perf_counter() - t0
    rate.converged[id(model)] = float(np.mean(sol.converged))
    return len(W) / dt


rate.converged = {}


def single_us(model, W):
    solver = Solver(model)
    out = []
    for w in W:
        t0 = time.perf_counter()
        solver.forces(w)
        out.append(time.perf_counter() - t0)
    return 1e6 * statistics.median(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--levels", default="1,2", help="identification mesh levels")
    ap.add_argument("--cache-dir", default=None)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=None)
    ap.add_argument("--json", default=None, help="also write every number here")
    ap.add_argument("--law", default="neo_hookean", choices=["neo_hookean", "ogden"])
    ap.add_argument("--ogden-alpha", type=float, default=None)
    ap.add_argument("--reference", default=str(REFERENCE), help="the FE reference's JSON")
    ap.add_argument("--max-force", type=float, default=None,
                    help="tissue.continuum.max_force [N] (default: the law's)")
    ap.add_argument("--max-moment", type=float, default=None,
                    help="tissue.continuum.max_moment [N*m] (default: the law's)")
    args = ap.parse_args(argv)
    ref = json.loads(Path(args.reference).read_text())
    cfg = config(args.law, args.ogden_alpha, args.max_force, args.max_moment)
    linear3 = _linear_coupled_model(cfg, cache_dir=args.cache_dir, level=3)
    levels = [int(v) for v in args.levels.split(",")]
    models = {L: reduced(cfg, linear3, L, args.cache_dir) for L in levels}
    result = dict(command=" ".join(["python"] + sys.argv), machine=platform.platform(),
                  python=platform.python_version(), numpy=np.__version__,
                  rays=store.IDENTIFY_RAYS, law=args.law, ogden_alpha=args.ogden_alpha,
                  identification={}, accuracy={}, speed={})
    for L, m in models.items():
        result["identification"][L] = {k: v for k, v in m.reduction.info.items()
                                       if isinstance(v, (int, float, str))}
        for ref_level in ref["levels"]:
            if ref_level["level"] < 3:
                continue
            cases = [c for c in ref_level["load_control"] if c.get("converged")]
            result["accuracy"][f"{L}->{ref_level['level']}"] = compare_cases(m, cases)
    # the linear bonded model of the same config against the same reference (what the
    # corrections add to; the JSON holds its answers: linear_bonded_forces / _u)
    for ref_level in ref["levels"]:
        if ref_level["level"] == 3:
            cases = [c for c in ref_level["load_control"] if c.get("converged")]
            result["accuracy"]["linear bonded->3"] = compare_cases(
                None, cases, answers=[(c["linear_bonded_forces"], c["linear_bonded_u"], 0)
                                      for c in cases])
    # speed
    _, W = smooth_random_log(SAMPLES, seed=7)
    # scaled into the identified range: its 99th percentile at 80 % of max_force/max_moment
    box = np.maximum(np.linalg.norm(W[:, :3], axis=1) / cfg.continuum_max_force,
                     np.linalg.norm(W[:, 3:], axis=1) / cfg.continuum_max_moment)
    W = W * (0.8 / np.percentile(box, 99))
    df = pd.read_csv(ROOT / "examples" / "wrench_log.csv", comment="#")
    logs_ = {"random": W,
             "paper": np.tile(df[COLS].to_numpy(), (-(-SAMPLES // len(df)), 1))[:SAMPLES]}
    rom = models[max(levels)]
    for name, Wl in logs_.items():
        log(f"speed: {name} log")
        lin_rate, rom_rate, ratio = paired(lambda: rate(linear3, Wl), lambda: rate(rom, Wl),
                                           args.repeats)
        result["speed"][name] = dict(linear=lin_rate, reduced=rom_rate, ratio=ratio,
                                     converged_linear=rate.converged[id(linear3)],
                                     converged_reduced=rate.converged[id(rom)])
    Ws = logs_["random"][:3000]
    lin_us, rom_us = [], []
    for _ in range(args.repeats):
        lin_us.append(single_us(linear3, Ws))
        rom_us.append(single_us(rom, Ws))
    result["speed"]["single_us"] = dict(linear=statistics.median(lin_us),
                                        reduced=statistics.median(rom_us))
    text = report(result, levels)
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
    if args.out:
        Path(args.out).write_text(text)
    print(text)


def _table(rows):
    out = ["| case | RMSE, % of peak | largest patch diff, % | peak FE / reduced [N] | "
           "displacement error, % | along the load, % | Newton it. |",
           "|---|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        out.append(f"| {r['label']} | {r['rmse_pct']:.2f} | {r['max_pct']:.2f} | "
                   f"{r['peak_fe']:.2f} / {r['peak_rom']:.2f} | {r['u_pct']:.2f} | "
                   f"{r['primary_pct']:.2f} | {r['iterations']} |")
    return out


def report(res, levels):
    acc = res["accuracy"]
    lines = ["## Accuracy summary", "",
             "| identified at level -> FE level | cases | worst RMSE, % of peak | worst patch, "
             "% of peak | worst displacement, % | worst along the load, % | all converged |",
             "|---|---:|---:|---:|---:|---:|---|"]
    for key, rows in acc.items():
        lines.append(f"| {key} | {len(rows)} | {max(r['rmse_pct'] for r in rows):.2f} | "
                     f"{max(r['max_pct'] for r in rows):.2f} | "
                     f"{max(r['u_pct'] for r in rows):.2f} | "
                     f"{max(r['primary_pct'] for r in rows):.2f} | "
                     f"{all(r['converged'] for r in rows)} |")
    for key, rows in acc.items():
        lines += ["", f"### {key}", ""] + _table(rows)
    lines += ["", "## Identification", "", "| level | rays | samples | FE iterations | "
              "seconds | fit RMS: wrench [N, N*m] / normal [N] |", "|---:|---:|---:|---:|---:|---|"]
    for L, inf in res["identification"].items():
        lines.append(f"| {L} | {inf.get('rays')} | {inf.get('samples')} | "
                     f"{inf.get('fe_iterations')} | {inf.get('seconds_identify', float('nan')):.0f} | "
                     f"{inf.get('fit_rms_wrench', float('nan')):.4f} / "
                     f"{inf.get('fit_rms_normal', float('nan')):.4f} |")
    sp = res["speed"]
    lines += ["", "## Speed (this process, medians)", "",
              "| log | linear coupled [samples/s] | reduced hyperelastic [samples/s] | "
              "ratio (median of pairs) | converged: linear / reduced |",
              "|---|---:|---:|---:|---|"]
    for name in ("random", "paper"):
        s = sp[name]
        lines.append(f"| {name} | {s['linear']:,.0f} | {s['reduced']:,.0f} | {s['ratio']:.3f} | "
                     f"{s['converged_linear']:.4f} / {s['converged_reduced']:.4f} |")
    lines += ["", f"Single sample (`Solver.forces`, 3,000 samples of the random log): linear "
              f"{sp['single_us']['linear']:.1f} us, reduced {sp['single_us']['reduced']:.1f} us "
              "(medians).", "", f"Command: `{res['command']}`; {res['machine']}, Python "
              f"{res['python']}, numpy {res['numpy']}."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
