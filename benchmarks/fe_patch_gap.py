"""Patch gaps (``tissue.continuum.patch_gap``): mesh convergence of the coupled model.

Tiled patches that move independently impose a displacement jump at their shared edges;
the energy of a jump is unbounded, so the condensed stiffness of such motions grows
without limit as the mesh is refined (slowly: like the log of the element size). A strip
of free skin between neighbouring plates removes the jump. Two studies:

``three``
    Three patches on one row (R = 45 mm, 25 mm wide, 35 deg apart, t = 10 mm,
    nu = 0.45, E = 1 Pa): the middle one pushed along its normal by 1 m, its neighbours
    held. The normal force n . F on it at mesh levels 2..5, tiled (gap 0), with the
    issue's narrower 30-deg cells (their own gap of 5 deg, patch_gap 0), and with
    patch_gap 1, 2 and 4 mm in the 35-deg cells.
``presets``
    ``configs/human_upper_arm.yaml`` and ``configs/harmony_upper_arm.yaml`` through the
    config's own coupled-model builder (``coupled_model(cfg, level=...)``, the builder of
    ``model_from_config(cfg, 'coupled')``, its FE built at each mesh level), with their own
    compliant cuff and with a rigid one
    (``cuff.stiffness: .inf``): the patch normal forces under the paper's loads (load
    cell z = horizontal and y = vertical, both signs, 11.1, 33.4 and 55.6 N, through
    ``cuff_wrench``, solved by ``solver.solve``), lift-off included. The figure of merit
    is the largest change of a patch force between successive levels, in % of that
    load's peak patch force, the worst over the 12 loads. ``--friction MU``: the same with
    Coulomb friction (``interface.friction_coefficient``: a patch out of contact is
    released entirely), each load ramped from the strap's state in 20 steps; loads with
    no equilibrium at that mu are listed and left out.

Run from the repository root (K builds are cached on disk, so a second run, or one with
more gaps, costs only the new builds)::

    OPENBLAS_NUM_THREADS=1 python -m benchmarks.fe_patch_gap three --levels 2,3,4,5
    OPENBLAS_NUM_THREADS=1 python -m benchmarks.fe_patch_gap presets \\
        --presets human_upper_arm --levels 2,3,4,5 --gaps 0,1,1.5,2,3,4
    OPENBLAS_NUM_THREADS=1 python -m benchmarks.fe_patch_gap presets \\
        --presets harmony_upper_arm --levels 2,3,4,5 --gaps 0,1.5,2,3
    # the same with Coulomb friction, patches out of contact fully released:
    OPENBLAS_NUM_THREADS=1 python -m benchmarks.fe_patch_gap presets --friction 1.2 ...   # 0.5, 2.0

Level 5 of a full cuff takes 3-5 minutes and 7.6 GB per FE build on 2 cores: run one
command at a time, with the same ``--cache`` so that later runs reuse the builds.

Each prints a markdown table (``--json FILE`` also keeps the raw numbers); the tables of
``benchmarks/FE_CONVERGENCE.md`` section 7 come from these commands.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.common import ROOT  # noqa: E402

from phri_spring.io.config import load_config  # noqa: E402
from phri_spring.physics.continuum import tissue as fe  # noqa: E402
from phri_spring.physics.cuff.geometry import cuff_geometry  # noqa: E402
from phri_spring.physics.contact.solver import solve, solve_segments  # noqa: E402
from phri_spring.workflows import common  # noqa: E402

PRESETS = ("human_upper_arm", "harmony_upper_arm")
#: the paper's loads: load-cell z (horizontal) and y (vertical), both signs [N]
MAGNITUDES = (11.1, 33.4, 55.6)


def paper_loads():
    """(12, 6) load-cell readings and their names."""
    rows, names = [], []
    for axis, name in ((2, "z"), (1, "y")):
        for sign in (1.0, -1.0):
            for F in MAGNITUDES:
                w = np.zeros(6)
                w[axis] = sign * F
                rows.append(w)
                names.append(f"{'+' if sign > 0 else '-'}{F:g} N {name}")
    return np.array(rows), names


# ------------------------------------------------------------------ three patches

THREE_CASES = (
    ("tiled 35-deg cells, gap 0", 35.0, 0.0),
    ("30-deg cells 35 deg apart (own 5-deg gap), patch_gap 0", 30.0, 0.0),
    ("35-deg cells, patch_gap 1 mm", 35.0, 0.001),
    ("35-deg cells, patch_gap 2 mm", 35.0, 0.002),
    ("35-deg cells, patch_gap 4 mm", 35.0, 0.004),
)


def three_patch_force(width_deg, gap, level, thickness=0.01, nu=0.45):
    """n . F on the middle of three patches pushed by 1 m along its normal (E = 1 Pa)."""
    g = cuff_geometry([0.0], 0.045, 0.025, 55.0, 35.0, 3, angle_width_deg=width_deg)
    t0 = time.perf_counter()
    ops = fe.condensed_surface_operators(g, thickness, 1.0, nu, level=level, patch_gap=gap)
    q = np.zeros(18)
    q[6:9] = g.normals[1]
    return dict(nF=float((ops.K @ q)[6:9] @ g.normals[1]), N=float((ops.N @ q)[1]),
                dofs=ops.info["n_dofs"], seconds=time.perf_counter() - t0)


def run_three(levels, state):
    res = state.setdefault("three", {})
    for name, width, gap in THREE_CASES:
        for L in levels:
            key = f"{name}|{L}"
            if key not in res:
                res[key] = three_patch_force(width, gap, L)
                print(f"{name}, level {L}: {res[key]}", file=sys.stderr, flush=True)
    lines = ["| case | " + " | ".join(f"level {L}" for L in levels) + " | "
             + " | ".join(f"{a} -> {b} [%]" for a, b in zip(levels[:-1], levels[1:])) + " |",
             "|---|" + "---|" * (2 * len(levels) - 1)]
    for name, _, _ in THREE_CASES:
        v = [res[f"{name}|{L}"]["nF"] for L in levels]
        ch = [100 * (b - a) / b for a, b in zip(v[:-1], v[1:])]
        lines.append(f"| {name} | " + " | ".join(f"{x:.4f}" for x in v) + " | "
                     + " | ".join(f"{c:+.2f}" for c in ch) + " |")
    return "\n".join(lines)


# ------------------------------------------------------------------------ presets

#: with friction, each load is reached by a ramp of this many equal steps from zero
RAMP_STEPS = 20


def preset_forces(cfg, gap, level, cache_dir, rigid=False, mu=None):
    """Patch normal forces (12, n) under the paper's loads, and the number of patches out
    of contact per load. ``mu``: Coulomb friction (``interface.friction_coefficient``;
    patches out of contact fully released), each load its own ramp from the strap's state;
    a load with no equilibrium at that mu gives NaN forces."""
    kw = dict(continuum_patch_gap=gap)
    if rigid:
        kw["cuff_stiffness"] = np.full_like(np.asarray(cfg.cuff_stiffness, float), np.inf)
    if mu is not None:
        kw["friction_coefficient"] = mu
    c = dataclasses.replace(cfg, **kw)
    model = common.coupled_model(c, level=level, cache_dir=cache_dir)
    W_lc, _ = paper_loads()
    if mu is None:
        sol = solve(model, common.cuff_wrench(c, W_lc))
        if not np.all(sol.converged):
            raise RuntimeError(f"solver did not converge ({c.name}, gap {gap}, level {level})")
        return sol.forces, (~sol.contact).sum(axis=1)
    frac = np.arange(1, RAMP_STEPS + 1) / RAMP_STEPS
    ramps = np.concatenate([np.outer(frac, w) for w in W_lc])
    bounds = np.arange(0, len(ramps) + 1, RAMP_STEPS)
    sol = solve_segments(model, common.cuff_wrench(c, ramps), bounds)
    last = bounds[1:] - 1
    f = np.where(sol.converged[last][:, None], sol.forces[last], np.nan)
    return f, (~sol.contact[last]).sum(axis=1)


def change_pct(fine, coarse):
    """Per load: max |fine - coarse| over patches, % of the fine peak |force| (NaN for a load
    without equilibrium at either level)."""
    return 100 * np.max(np.abs(fine - coarse), axis=1) / np.max(np.abs(fine), axis=1)


def run_presets(levels, gaps, cache_dir, state, presets=PRESETS, mu=None):
    res = state.setdefault("presets" if mu is None else f"presets-mu{mu:g}", {})
    for p in presets:
        cfg = load_config(ROOT / "configs" / f"{p}.yaml")
        for gap in gaps:
            for L in levels:
                for cuff in ("own", "rigid"):
                    key = f"{p}|{gap:g}|{L}|{cuff}"
                    if key in res:
                        continue
                    t0 = time.perf_counter()
                    f, off = preset_forces(cfg, gap, L, cache_dir, rigid=cuff == "rigid",
                                           mu=mu)
                    res[key] = dict(f=f.tolist(), off=off.tolist(),
                                    seconds=time.perf_counter() - t0)
                    print(f"{p}, gap {gap * 1e3:g} mm, level {L}, {cuff} cuff: "
                          f"{res[key]['seconds']:.1f} s", file=sys.stderr, flush=True)
    _, names = paper_loads()
    pairs = list(zip(levels[:-1], levels[1:]))
    lines = ["| preset | cuff | gap [mm] | " + " | ".join(f"{a} -> {b}" for a, b in pairs)
             + " | worst load (finest pair) | patches off (55.6 N loads) |"
             + (" loads without equilibrium |" if mu is not None else ""),
             "|---|---|---|" + "---|" * (len(pairs) + 2 + (mu is not None))]
    for p in presets:
        for cuff in ("own", "rigid"):
            for gap in gaps:
                F = {L: np.array(res[f"{p}|{gap:g}|{L}|{cuff}"]["f"]) for L in levels}
                ch = [change_pct(F[b], F[a]) for a, b in pairs]
                fin = res[f"{p}|{gap:g}|{levels[-1]}|{cuff}"]
                off = [o if np.isfinite(fl).all() else "-" for o, fl in zip(fin["off"], fin["f"])]
                big = [o for o, nm in zip(off, names) if nm.startswith(("+55.6", "-55.6"))]
                none = [nm for k, nm in enumerate(names)
                        if any(np.isnan(F[L][k]).any() for L in levels)]
                lines.append(f"| {p} | {cuff} | {gap * 1e3:g} | "
                             + " | ".join(f"{np.nanmax(c):.2f}" for c in ch)
                             + f" | {names[int(np.nanargmax(ch[-1]))]} | "
                             + ", ".join(str(o) for o in big) + " |"
                             + (f" {', '.join(none) or 'none'} |" if mu is not None else ""))
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("study", choices=("three", "presets"))
    ap.add_argument("--levels", default="2,3,4", help="mesh levels, comma-separated")
    ap.add_argument("--gaps", default="0,1,2",
                    help="presets: patch gaps [mm], comma-separated")
    ap.add_argument("--presets", default=",".join(PRESETS))
    ap.add_argument("--friction", type=float, default=None, metavar="MU",
                    help="presets: Coulomb friction mu (patches out of contact fully "
                         "released), each load ramped from zero in 20 steps")
    ap.add_argument("--cache", default=None,
                    help="cache folder of the FE builds (default: phri-spring's own)")
    ap.add_argument("--json", default=None,
                    help="JSON file to keep the raw numbers in (and resume from)")
    args = ap.parse_args(argv)
    levels = tuple(int(v) for v in args.levels.split(","))
    state = {}
    if args.json and Path(args.json).exists():
        state = json.loads(Path(args.json).read_text())
    t0 = time.perf_counter()
    try:
        if args.study == "three":
            table = run_three(levels, state)
        else:
            gaps = tuple(float(v) * 1e-3 for v in args.gaps.split(","))
            table = run_presets(levels, gaps, args.cache, state,
                                tuple(args.presets.split(",")), args.friction)
    finally:
        if args.json:
            Path(args.json).write_text(json.dumps(state))
    print(f"<!-- {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
          f"{time.perf_counter() - t0:.0f} s, {os.cpu_count()} cores, "
          f"scikit-fem {__import__('skfem').__version__} -->")
    print(table)


if __name__ == "__main__":
    main()
