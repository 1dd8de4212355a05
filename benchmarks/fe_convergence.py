"""Convergence and validation study of the built-in tissue FE (docs/coupled-fe.md).

Writes ``benchmarks/FE_CONVERGENCE.md``. Run from the repository root::

    OPENBLAS_NUM_THREADS=1 python -m benchmarks.fe_convergence            # full (~40 min)
    OPENBLAS_NUM_THREADS=1 python -m benchmarks.fe_convergence --quick    # smoke run

Parts (geometry: configs/harmony_upper_arm.yaml, R = 45 mm, 21 tiled cells, each patch a
plate in its cell with the default patch gap between neighbours, section 7):

1. Mesh convergence of the condensed model: rigid-cuff patch normal forces (six unit
   wrenches about the cuff origin) at levels 1..3 and the level-4 direct reference, change
   between levels in % of the peak patch force.
2. Validation: the shipped level's condensed model (K with the local-normal output N)
   against a finer direct FE (rigid cuff imposed on all the plates, level 4,
   twice the modelled length, traction-free ends), RMSE over the 21 patches in % of the
   peak, for t in {10, 20, 30} mm x nu in {0.30, 0.45}; the same for n_e . F_e instead of
   N, and for the 3n x 3n translations-only reductions (do patch rotations matter?).
3. Modelled length and end condition.
4. Build time (cold, fresh process; median of runs) and cached reload time.
5. Flat punch: FE against an independent Nystrom solution of the layer integral equation.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.common import ROOT, harmony_geometry
from phri_spring.physics.continuum import tissue as fe
from references import rigid_cuff_fe
from tests.support.reference_layer import kappa_integral_equation  # independent of the FE

WRENCHES = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")


def harmony():
    return harmony_geometry()


def model_forces(g, t, nu, level, length_factor=fe.DEFAULT_LENGTH_FACTOR, ends="fixed"):
    ops = fe.condensed_surface_operators(g, t, 1.0, nu, level=level,
                                         length_factor=length_factor, ends=ends)
    W = np.eye(6)
    return {
        "N": rigid_cuff_fe.rigid_cuff_patch_forces(ops.K, g, W, N=ops.N),
        "ne": rigid_cuff_fe.rigid_cuff_patch_forces(ops.K, g, W),
        "3free": rigid_cuff_fe.rigid_cuff_patch_forces(fe.translational_block(ops.K, "free"), g, W),
        "3fixed": rigid_cuff_fe.rigid_cuff_patch_forces(fe.translational_block(ops.K, "fixed"), g, W),
        "info": ops.info,
    }


def direct_forces(g, t, nu, level, length_factor, ends):
    Kc, Fn, info = rigid_cuff_fe.direct_rigid_cuff_response(g, t, nu, level=level,
                                                 length_factor=length_factor, ends=ends)
    return (Fn @ np.linalg.solve(Kc, np.eye(6))).T, info


def rmse_pct(f, ref):
    peak = np.max(np.abs(ref), axis=1)
    return np.sqrt(np.mean((f - ref) ** 2, axis=1)) / peak * 100


def maxdiff_pct(f, ref):
    peak = np.max(np.abs(ref), axis=1)
    return np.max(np.abs(f - ref), axis=1) / peak * 100


# ------------------------------------------------------------------ punch reference

# ------------------------------------------------------------------------- timing

_TIME_BUILD = """
import os, sys, time, tempfile
from benchmarks.common import harmony_geometry
from phri_spring.io.cache.surface_stiffness import load_or_build
g = harmony_geometry()
t0 = time.perf_counter()
K, info = load_or_build(g, {t}, 1.0e5, {nu}, cache_dir={cache!r})
print(time.perf_counter() - t0, info["source"])
"""


def time_build(t, nu, runs, cache_root):
    build, reload_ = [], []
    for k in range(runs):
        cache = str(Path(cache_root) / f"run{k}-{t}-{nu}")
        code = _TIME_BUILD.format(t=t, nu=nu, cache=cache)
        for dest in (build, reload_):
            out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                 check=True, env=dict(os.environ), cwd=ROOT)
            sec, src = out.stdout.split()
            assert src == ("built" if dest is build else "cache"), src
            dest.append(float(sec))
    return build, reload_


# ---------------------------------------------------------------------------- main

def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="coarse smoke run (levels 1-2, one thickness; figures not converged)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "FE_CONVERGENCE.md"))
    ap.add_argument("--state", default=None,
                    help="JSON file to keep finished parts in (resume after interruption)")
    ap.add_argument("--runs", type=int, default=3, help="timing runs (median)")
    args = ap.parse_args(argv)

    quick = args.quick
    thick = (0.02,) if quick else (0.01, 0.02, 0.03)
    nus = (0.45,) if quick else (0.30, 0.45)
    levels = (1, 2) if quick else (1, 2, 3)
    shipped = 2 if quick else fe.DEFAULT_LEVEL
    ref_level = 2 if quick else 4
    ref_lf = 2 * fe.DEFAULT_LENGTH_FACTOR
    state = {}
    if args.state and Path(args.state).exists():
        state = json.loads(Path(args.state).read_text())

    def keep(key, fn):
        if key not in state:
            state[key] = fn()
            if args.state:
                Path(args.state).write_text(json.dumps(state))
        return state[key]

    g = harmony()
    conv, val, variants, infos = {}, {}, {}, {}
    for t in thick:
        for nu in nus:
            tag = f"{t}-{nu}"
            print(f"t = {t * 1e3:.0f} mm, nu = {nu}", file=sys.stderr, flush=True)
            ref = keep(f"direct-{tag}", lambda: (lambda r: {
                "f": r[0].tolist(), "info": r[1]})(direct_forces(g, t, nu, ref_level, ref_lf,
                                                                  "free")))
            ref_f = np.array(ref["f"])
            per_level = {}
            for L in levels:
                r = keep(f"model-{tag}-{L}", lambda L=L: {
                    k: (v.tolist() if isinstance(v, np.ndarray) else v)
                    for k, v in model_forces(g, t, nu, L).items()})
                per_level[L] = r
            conv[tag] = [maxdiff_pct(np.array(per_level[a]["N"]), np.array(per_level[b]["N"]))
                         for a, b in zip(levels[:-1], levels[1:])]
            conv[tag].append(maxdiff_pct(np.array(per_level[levels[-1]]["N"]), ref_f))
            sh = per_level[shipped]
            val[tag] = rmse_pct(np.array(sh["N"]), ref_f)
            variants[tag] = {k: rmse_pct(np.array(sh[k]), ref_f) for k in
                             ("N", "ne", "3free", "3fixed")}
            infos[tag] = {"shipped": sh["info"], "ref": ref["info"]}

    # length study (level 2: cheap, the effect is geometric)
    length = {}
    lfs = (2, 4, 6, 8) if not quick else (2, 4)
    for t in (0.01, 0.03):
        res = {}
        for lf in lfs:
            for ends in ("fixed", "free"):
                res[(lf, ends)] = np.array(keep(f"len-{t}-{lf}-{ends}", lambda lf=lf, ends=ends:
                                                model_forces(g, t, 0.45, 2, lf, ends)["N"]
                                                .tolist()))
        refl = res[(lfs[-1], "free")]
        length[t] = {k: maxdiff_pct(v, refl) for k, v in res.items()}

    # punch
    punch = []
    for nu in nus:
        for ah in (0.01, 0.1, 0.225, 0.45, 1.0, 2.0):
            h = fe.PUNCH_RADIUS / ah
            k_fe = fe.flat_punch_stiffness(h, 1.0, nu)
            kap_fe = k_fe / float(fe.sneddon_punch_stiffness(1.0, nu))
            punch.append((nu, ah, h, kap_fe, kappa_integral_equation(ah, nu)))

    # timing
    timing = {}
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        for t in ((0.02,) if quick else (0.02, 0.03)):
            timing[t] = keep(f"time-{t}", lambda t=t: time_build(t, 0.45, args.runs, tmp))

    write_report(args.out, quick, levels, shipped, ref_level, ref_lf, conv, val, variants,
                 infos, length, punch, timing)
    print(f"wrote {args.out}", file=sys.stderr)


def _row(vals, fmt="{:.2f}"):
    return " | ".join(fmt.format(v) for v in vals)


def write_report(out, quick, levels, shipped, ref_level, ref_lf, conv, val, variants, infos,
                 length, punch, timing):
    L = []
    cmd = "OPENBLAS_NUM_THREADS=1 python -m benchmarks.fe_convergence" + (" --quick" if quick
                                                                          else "")
    L.append("# Built-in tissue FE: convergence and validation")
    L.append("")
    L.append(f"Generated by `{cmd}` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} "
             f"(scikit-fem {__import__('skfem').__version__}, numpy {np.__version__}, "
             f"{os.cpu_count()} cores shared with other jobs). Geometry: "
             "`configs/harmony_upper_arm.yaml` (R = 45 mm, 3 x 7 tiled cells). Forces are "
             "the rigid-cuff patch normal-force increments for the six unit wrenches about "
             "the cuff origin (docs/coupled-fe.md, \"Validation\"); % are of the peak |patch "
             "force| of each wrench.")
    L.append("")
    L.append(f"Shipped level: {shipped}; modelled length beyond each cuff edge: "
             f"{fe.DEFAULT_LENGTH_FACTOR:g} t, ends clamped; patch gap "
             f"{fe.DEFAULT_PATCH_GAP * 1e3:g} mm (the default, section 7): every patch is a "
             "plate in its cell, a strip of free skin that wide between neighbours.")
    L.append("")
    L.append("## 1. Mesh convergence (max |change| over patches and wrenches, % of peak)")
    L.append("")
    pairs = [f"{a} -> {b}" for a, b in zip(levels[:-1], levels[1:])]
    pairs.append(f"{levels[-1]} -> reference (direct, level {ref_level})")
    L.append("| t [mm] | nu | " + " | ".join(pairs) + " |")
    L.append("|---|---|" + "---|" * len(pairs))
    for tag, cs in conv.items():
        t, nu = tag.split("-")
        L.append(f"| {float(t) * 1e3:.0f} | {nu} | " + _row([np.max(c) for c in cs]) + " |")
    L.append("")
    L.append(f"## 2. Validation against a finer direct FE (level {ref_level}, length "
             f"{ref_lf:g} t beyond each edge, free ends)")
    L.append("")
    L.append("RMSE over the 21 patches, % of the peak patch force; condensed model at the "
             "shipped level with the local-normal output N.")
    L.append("")
    L.append("| t [mm] | nu | " + " | ".join(WRENCHES) + " | max |")
    L.append("|---|---|" + "---|" * 7)
    for tag, v in val.items():
        t, nu = tag.split("-")
        L.append(f"| {float(t) * 1e3:.0f} | {nu} | " + _row(v) + f" | {np.max(v):.2f} |")
    L.append("")
    L.append("Variants (max RMSE over the six wrenches, % of peak): `N` the shipped output; "
             "`n_e.F_e` the patch force along the patch-centre normal; `3n free` / `3n fixed` "
             "the translations-only 3n x 3n reductions (patch rotations free / held at zero), "
             "normal force n_e.F_e.")
    L.append("")
    L.append("| t [mm] | nu | N | n_e.F_e | 3n free | 3n fixed |")
    L.append("|---|---|---|---|---|---|")
    for tag, v in variants.items():
        t, nu = tag.split("-")
        L.append(f"| {float(t) * 1e3:.0f} | {nu} | " +
                 _row([np.max(v[k]) for k in ("N", "ne", "3free", "3fixed")]) + " |")
    L.append("")
    L.append("Per wrench, worst configuration (% of peak):")
    L.append("")
    L.append("| variant | " + " | ".join(WRENCHES) + " |")
    L.append("|---|" + "---|" * 6)
    for k, name in (("N", "N"), ("ne", "n_e.F_e"), ("3free", "3n free"), ("3fixed", "3n fixed")):
        worst = np.max(np.array([v[k] for v in variants.values()]), axis=0)
        L.append(f"| {name} | " + _row(worst) + " |")
    L.append("")
    L.append("Mesh sizes:")
    L.append("")
    L.append("| t [mm] | nu | shipped dofs | build [s] | reference dofs | reference [s] |")
    L.append("|---|---|---|---|---|---|")
    for tag, inf in infos.items():
        t, nu = tag.split("-")
        L.append(f"| {float(t) * 1e3:.0f} | {nu} | {inf['shipped']['n_dofs']} | "
                 f"{inf['shipped']['seconds']:.1f} | {inf['ref']['n_dofs']} | "
                 f"{inf['ref']['seconds']:.1f} |")
    L.append("")
    L.append("## 3. Modelled length and end condition (level 2, nu = 0.45)")
    L.append("")
    L.append("Max |change| of the patch forces against the longest tissue with free ends, "
             "% of peak, worst wrench:")
    L.append("")
    L.append("| t [mm] | length beyond edge [t] | clamped ends | free ends |")
    L.append("|---|---|---|---|")
    for t, res in length.items():
        for lf in sorted({k[0] for k in res}):
            L.append(f"| {t * 1e3:.0f} | {lf} | {np.max(res[(lf, 'fixed')]):.3f} | "
                     f"{np.max(res[(lf, 'free')]):.3f} |")
    L.append("")
    L.append("## 4. Build and reload time (Harmony geometry, shipped level, nu = 0.45)")
    L.append("")
    L.append("Each run is a fresh Python process calling "
             "`phri_spring.io.cache.surface_stiffness.load_or_build` with an empty cache folder "
             "(first build), then again (cached reload); the time of the call only.")
    L.append("")
    L.append("| t [mm] | first build: median [s] | runs [s] | cached reload: median [s] |")
    L.append("|---|---|---|---|")
    for t, (b, r) in timing.items():
        L.append(f"| {float(t) * 1e3:.0f} | {statistics.median(b):.1f} | "
                 f"{', '.join(f'{x:.1f}' for x in b)} | {statistics.median(r):.3f} |")
    L.append("")
    L.append("## 5. Flat punch (9 mm) on a bonded layer: FE against the integral equation")
    L.append("")
    L.append("kappa = k (1 - nu^2) / (2 a E); 1 is Sneddon's half-space. `integral eq.`: "
             "Nystrom solution of the layer's Fredholm equation (formulation of Hayes et al. "
             "1972), independent of the FE.")
    L.append("")
    L.append("| nu | a/h | h [mm] | kappa FE | kappa integral eq. | difference [%] |")
    L.append("|---|---|---|---|---|---|")
    for nu, ah, h, kf, ki in punch:
        L.append(f"| {nu} | {ah} | {h * 1e3:.2f} | {kf:.4f} | {ki:.4f} | "
                 f"{(kf / ki - 1) * 100:+.3f} |")
    L.append("")
    # sections 6 on come from other scripts (fe_locking.py, fe_patch_gap.py): kept
    old = Path(out).read_text() if Path(out).exists() else ""
    tail = old.find("\n## 6.")
    Path(out).write_text("\n".join(L) + (old[tail:] if tail >= 0 else ""))


if __name__ == "__main__":
    main()
