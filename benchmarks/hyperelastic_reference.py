"""Hyperelastic (neo-Hookean or Ogden) reference FE of the human preset under a rigid bonded cuff.

Run from the repository root (progress on stderr, a markdown summary on stdout, every
number in the JSON; ``benchmarks/HYPERELASTIC_REFERENCE.md`` holds a run and what it
means)::

    OPENBLAS_NUM_THREADS=1 python -m benchmarks.hyperelastic_reference --levels 2,3,4

The FE is :mod:`phri_spring.physics.hyperelastic.fe` (felupe, extra ``hyper``) on the linear FE's
mesh. Per mesh level:

a. cross-check at small load: 1 N along and 0.1 N*m about each cuff axis, no preload,
   against the project's linear FE (``references.rigid_cuff_fe.direct_rigid_cuff_response``): patch
   normal forces, largest difference in % of the peak (the neo-Hookean FE, and felupe's
   linear law on the same mesh);
b. push/pull: the cuff moved 0..10 mm into the arm (+y: the patches sit on the -y side,
   around theta = 180 deg) and away from it, no preload: total force, neo-Hookean and linear;
c. load control with the strap's hoop preload (plates offset by the linear coupled
   model's delta, rigid cuff, same level), the paper's forces 11.1, 33.4, 55.6 N
   (``contact_reference.py``'s) along +-x, +-y, +-z through the cuff origin and moments
   F x 0.035 m = 0.39, 1.17, 1.95 N*m about +-x, +-y, +-z: patch normal forces, cuff
   displacement, iterations (each direction walked 0 -> 11.1 -> 33.4 -> 55.6 N from the
   preloaded zero-wrench state);
d. mesh convergence of c between successive levels (above ``--full-max-level`` only the
   55.6 N forces and 1.95 N*m moments are run).

``--law ogden --ogden-alpha A``: the one-term Ogden layer instead (docs/model.md 10.8); the
JSON's keys keep their ``neo_hookean`` names and hold that law's numbers (``material``
names the law).
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import copy  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402


from phri_spring.io.config import config_from_dict, load_yaml  # noqa: E402
from phri_spring.physics.hyperelastic import fe as fh  # noqa: E402
from phri_spring.physics.hyperelastic import mesh as fh_mesh  # noqa: E402
from references.rigid_cuff_fe import direct_rigid_cuff_response  # noqa: E402
from phri_spring.workflows.common import continuum_modulus, coupled_model  # noqa: E402

FORCES = (11.1, 33.4, 55.6)      # N, the paper's load levels (contact_reference.py)
ARM = 0.035                      # m: moment = force x 35 mm
AXES = "xyz"


def log(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def rigid_config(path):
    """The config with a rigid cuff (cuff.stiffness: inf): the FE's plates are rigid."""
    raw = copy.deepcopy(load_yaml(path))
    raw["cuff"]["stiffness"] = float("inf")
    return config_from_dict(raw, path=path, base_dir=Path(path).parent)


def load_cases(full):
    """(label, wrench) of the load-control cases, grouped in paths of increasing size."""
    paths = []
    for kind in ("F", "M"):
        for i, ax in enumerate(AXES):
            for sign in (1, -1):
                rows = []
                for F in (FORCES if full else FORCES[-1:]):
                    W = np.zeros(6)
                    mag = F if kind == "F" else round(F * ARM, 4)
                    W[i + (3 if kind == "M" else 0)] = sign * mag
                    unit = "N" if kind == "F" else "N*m"
                    rows.append((f"{kind}{'+' if sign > 0 else '-'}{ax} {mag:g} {unit}", W))
                paths.append(rows)
    return paths


def add_linear_bonded(cfg, L, cache_dir):
    """The linear coupled model's bonded answer (rigid cuff, no lift-off) to each case of c:
    f = f0 + N_out T H^-1 W, u = H^-1 W with H = T^T C_t^-1 T (its preload carries W_pre)."""
    cm = coupled_model(cfg, level=L["level"], cache_dir=cache_dir)
    K = np.linalg.inv(cm.C_t)
    H = cm.T.T @ K @ cm.T
    for c in L["load_control"]:
        u = np.linalg.solve(H, np.array(c["wrench"]))
        f = cm.f0 + cm.N_out @ (cm.T @ u)
        c["linear_bonded_u"], c["linear_bonded_forces"] = u.tolist(), f.tolist()
        if c["converged"]:
            c["neo_hookean_vs_linear_pct"] = pct_of_peak(np.array(c["normal_forces"]), f)


def pct_of_peak(a, b):
    return float(100 * np.max(np.abs(a - b)) / np.max(np.abs(b)))


def run_level(cfg, level, args):
    g = cfg.geometry()
    t, nu = cfg.continuum_thickness, cfg.poisson_ratio
    E = float(np.mean(continuum_modulus(cfg)))
    out = dict(level=level)
    t0 = time.perf_counter()
    cm = coupled_model(cfg, level=level, cache_dir=args.cache_dir)
    out["coupled_seconds"] = time.perf_counter() - t0
    log(f"level {level}: linear coupled model (rigid cuff) in {out['coupled_seconds']:.0f} s")
    cross_on, push_on = level <= args.cross_max_level, level <= args.push_max_level
    if cross_on:
        Kc, Fn, info = direct_rigid_cuff_response(g, t, nu, level=level)
        out["linear_fe_seconds"] = info["seconds"]
    nh = fh.build_hyper_cuff(g, t, E, nu, level=level, delta=cm.delta, law=args.law,
                             ogden_alpha=args.ogden_alpha)
    lin = fh.build_hyper_cuff(g, t, E, nu, level=level, law="linear", delta=cm.delta) \
        if cross_on or push_on else None
    out["mesh"] = {k: v for k, v in nh.info.items() if k != "seconds"}
    log(f"level {level}: {nh.info['n_dofs']} dofs, {nh.info['n_elements']} hexahedra, "
        f"{nh.info['n_plate_nodes']} plate nodes")
    # a. cross-check at small load, no preload
    t0 = time.perf_counter()
    cross = []
    for j, scale in [(j, sc) for sc in args.cross_scales for j in range(6) if cross_on]:
        W = np.zeros(6)
        W[j] = scale * (1.0 if j < 3 else 0.1)
        u_lin = np.linalg.solve(E * Kc, W)
        f_lin = E * Fn @ u_lin
        s_nh = fh.solve_wrench(nh, W, preload=False)
        s_hl = fh.solve_wrench(lin, W, preload=False)
        cross.append(dict(wrench=W.tolist(), f_linear_fe=f_lin.tolist(),
                          f_neo_hookean=s_nh.normal_forces.tolist(),
                          f_felupe_linear=s_hl.normal_forces.tolist(),
                          u_linear_fe=u_lin.tolist(), u_neo_hookean=s_nh.u.tolist(),
                          diff_neo_hookean_pct=pct_of_peak(s_nh.normal_forces, f_lin),
                          diff_neo_hookean_n=float(np.max(np.abs(s_nh.normal_forces - f_lin))),
                          peak_linear_fe=float(np.max(np.abs(f_lin))),
                          diff_felupe_linear_pct=pct_of_peak(s_hl.normal_forces, f_lin)))
        log(f"level {level}: cross-check {W.tolist()}: {args.law} "
            f"{cross[-1]['diff_neo_hookean_pct']:.3f} %, felupe linear "
            f"{cross[-1]['diff_felupe_linear_pct']:.1e} % of peak")
    out["cross_check"] = cross
    out["cross_check_seconds"] = time.perf_counter() - t0
    # preload at zero displacement and zero wrench
    t0 = time.perf_counter()
    p_lin = fh.patch_forces(lin, np.zeros(6)) if lin is not None else None
    p_nh = fh.patch_forces(nh, np.zeros(6))
    z_nh = fh.solve_wrench(nh, np.zeros(6), W_pre=cm.W_pre)
    out["preload"] = dict(f0=cm.f0.tolist(), W_pre=cm.W_pre.tolist(),
                          delta=fh.preload_offsets(cm).tolist(),
                          f_felupe_linear_u0=None if p_lin is None else
                          p_lin.normal_forces.tolist(),
                          f_neo_hookean_u0=p_nh.normal_forces.tolist(),
                          wrench_neo_hookean_u0=p_nh.wrench.tolist(),
                          f_neo_hookean_W0=z_nh.normal_forces.tolist(),
                          u_neo_hookean_W0=z_nh.u.tolist(),
                          seconds=time.perf_counter() - t0)
    log(f"level {level}: preload: f0 {cm.f0[0]:.3f} N; {args.law} at u = 0 "
        f"{p_nh.normal_forces.min():.3f}..{p_nh.normal_forces.max():.3f} N")
    # b. push / pull, no preload
    t0 = time.perf_counter()
    args_push = args.push_mm if push_on else 0
    d_mm = np.arange(0, args_push + 1) if args_push else np.arange(0)
    push = dict(displacement_mm=d_mm.tolist())
    for name, mdl in (("neo_hookean", nh), ("linear", lin)) if push_on else ():
        for sense, sign in (("push", 1), ("pull", -1)):
            mdl.restore({})
            Wy, Fn_ = [], []
            for d in d_mm:
                s = fh.patch_forces(mdl, [0, sign * d * 1e-3, 0, 0, 0, 0], preload=False)
                Wy.append(s.wrench.tolist())
                Fn_.append(s.normal_forces.tolist())
            push[f"{name}_{sense}_wrench"] = Wy
            push[f"{name}_{sense}_normal_forces"] = Fn_
            if Wy:
                log(f"level {level}: {name} {sense} {args_push} mm: F_y {Wy[-1][1]:+.2f} N")
    out["push_pull"] = push
    out["push_pull_seconds"] = time.perf_counter() - t0
    # c. load control with the preload (neo-Hookean)
    t0 = time.perf_counter()
    nh.restore({})
    z = fh.solve_wrench(nh, np.zeros(6), W_pre=cm.W_pre)
    zero = nh.checkpoint()
    cases = []
    full = level <= args.full_max_level
    for path in load_cases(full):
        if args.paths and path[-1][0].split()[0] not in args.paths:
            continue
        nh.restore(zero)
        for label, W in path:
            tc = time.perf_counter()
            try:
                s = fh.solve_wrench(nh, W, W_pre=cm.W_pre)
            except fh.ConvergenceError as exc:
                log(f"level {level}: {label}: {exc}")
                cases.append(dict(label=label, wrench=W.tolist(), converged=False))
                break
            cases.append(dict(label=label, wrench=W.tolist(), converged=True,
                              normal_forces=s.normal_forces.tolist(),
                              patch_forces=s.patch_forces.tolist(), u=s.u.tolist(),
                              resultant=s.wrench.tolist(), iterations=s.iterations,
                              steps=s.steps, seconds=time.perf_counter() - tc))
            log(f"level {level}: {label}: peak {s.normal_forces.max():.2f} N, min "
                f"{s.normal_forces.min():.2f} N, |t| {1e3 * np.linalg.norm(s.u[:3]):.2f} mm,"
                f" |w| {1e3 * np.linalg.norm(s.u[3:]):.1f} mrad, {s.iterations} it")
    out["zero_wrench_u"] = z.u.tolist()
    out["load_control"] = cases
    out["load_control_full"] = full
    out["load_control_seconds"] = time.perf_counter() - t0
    out["solver_stats"] = dict(nh._fe["stats"])
    return out


def convergence(levels_out):
    """Per case, change between successive levels: max |df| in % of the finer peak, |du|."""
    rows = []
    for a, b in zip(levels_out[:-1], levels_out[1:]):
        ca = {c["label"]: c for c in a["load_control"] if c["converged"]}
        for c in b["load_control"]:
            if not c["converged"] or c["label"] not in ca:
                continue
            fa, fb = np.array(ca[c["label"]]["normal_forces"]), np.array(c["normal_forces"])
            ua, ub = np.array(ca[c["label"]]["u"]), np.array(c["u"])
            rows.append(dict(levels=[a["level"], b["level"]], label=c["label"],
                             df_pct=float(100 * np.max(np.abs(fb - fa)) / np.max(fb)),
                             dt_mm=float(1e3 * np.linalg.norm(ub[:3] - ua[:3])),
                             dw_mrad=float(1e3 * np.linalg.norm(ub[3:] - ua[3:])),
                             t_mm=float(1e3 * np.linalg.norm(ub[:3])),
                             w_mrad=float(1e3 * np.linalg.norm(ub[3:]))))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", default="configs/human_upper_arm.yaml")
    ap.add_argument("--levels", default="2,3,4", help="mesh levels, comma separated")
    ap.add_argument("--out", default="benchmarks/HYPERELASTIC_REFERENCE.json")
    ap.add_argument("--full-max-level", type=int, default=3,
                    help="levels above this run only the largest loads of c")
    ap.add_argument("--push-mm", type=int, default=10, help="push/pull range [mm]")
    ap.add_argument("--push-max-level", type=int, default=3,
                    help="levels above this skip the push/pull curves")
    ap.add_argument("--cross-max-level", type=int, default=3,
                    help="levels above this skip the cross-check against the linear FE")
    ap.add_argument("--cross-scales", default="1,0.1",
                    help="cross-check loads: 1 N and 0.1 N*m times these, comma separated")
    ap.add_argument("--max-level-minutes", type=float, default=25.0,
                    help="add no further level once a level took longer")
    ap.add_argument("--cache-dir", default=None, help="surface stiffness cache")
    ap.add_argument("--paths", default=None,
                    help="only these load paths of c, comma separated (e.g. F-y,M+x)")
    ap.add_argument("--law", default="neo_hookean", choices=["neo_hookean", "ogden"])
    ap.add_argument("--ogden-alpha", type=float, default=None, help="the Ogden exponent")
    ap.add_argument("--merge", nargs="+", default=None, metavar="JSON",
                    help="only merge the levels of earlier runs' JSON files into --out")
    args = ap.parse_args(argv)
    args.cross_scales = [float(v) for v in args.cross_scales.split(",")]
    args.paths = set(args.paths.split(",")) if args.paths else None
    if args.merge:
        runs = [json.loads(Path(p).read_text()) for p in args.merge]
        res = runs[0]
        res["levels"] = sorted((L for r in runs for L in r["levels"]),
                               key=lambda L: L["level"])
        res["command"] = " ; ".join(r["command"] for r in runs)
        res["convergence"] = convergence(res["levels"])
        cfg = rigid_config(res["config"])
        for L in res["levels"]:
            add_linear_bonded(cfg, L, args.cache_dir)
        Path(args.out).write_text(json.dumps(res, indent=1))
        summary(res)
        return
    cmd = " ".join(["OPENBLAS_NUM_THREADS=1 python -m benchmarks.hyperelastic_reference",
                    *(argv if argv is not None else sys.argv[1:])])
    cfg = rigid_config(args.config)
    levels = [int(v) for v in args.levels.split(",")]
    felupe = fh_mesh._felupe()

    res = dict(command=cmd, config=args.config, machine=dict(
        machine=platform.machine(), cores=os.cpu_count(), python=platform.python_version(),
        numpy=np.__version__, felupe=felupe.__version__),
        material=dict(law="felupe NeoHooke(mu, bulk)" if args.law == "neo_hookean" else
                      f"felupe Hyperelastic(ogden, mu, alpha={args.ogden_alpha:g}) & "
                      "Volumetric(bulk)", young_modulus=float(np.mean(
            continuum_modulus(cfg))), poisson_ratio=cfg.poisson_ratio,
            thickness=cfg.continuum_thickness),
        labels=list(cfg.labels), forces=FORCES, moment_arm=ARM, levels=[])
    for level in levels:
        t0 = time.perf_counter()
        out = run_level(cfg, level, args)
        add_linear_bonded(cfg, out, args.cache_dir)
        out["seconds"] = time.perf_counter() - t0
        out["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        res["levels"].append(out)
        res["convergence"] = convergence(res["levels"])
        Path(args.out).write_text(json.dumps(res, indent=1))
        log(f"level {level} done in {out['seconds'] / 60:.1f} min, peak RSS "
            f"{out['peak_rss_mb']:.0f} MB; wrote {args.out}")
        if out["seconds"] > 60 * args.max_level_minutes and level != levels[-1]:
            log(f"level {level} took over {args.max_level_minutes:g} min: no finer level")
            break
    summary(res)


def summary(res):
    """Markdown tables of the run (stdout)."""
    print(f"Command: `{res['command']}`\n")
    for L in res["levels"]:
        lv = L["level"]
        print(f"\n## Level {lv}: {L['mesh']['n_dofs']} dofs, {L['seconds'] / 60:.1f} min, "
              f"peak RSS {L['peak_rss_mb']:.0f} MB\n")
        print("| wrench | peak [N] | NH - linear FE [N] | % of peak | felupe linear, % |")
        print("|---|---:|---:|---:|---:|")
        for c in L["cross_check"]:
            print(f"| {c['wrench']} | {c['peak_linear_fe']:.4f} | {c['diff_neo_hookean_n']:.2e} "
                  f"| {c['diff_neo_hookean_pct']:.3f} | {c['diff_felupe_linear_pct']:.1e} |")
        p = L["push_pull"]
        if p["displacement_mm"]:
            print("\n| d [mm] | push NH [N] | push lin [N] | ratio | pull NH [N] | pull lin [N] "
                  "| ratio |")
            print("|---:|---:|---:|---:|---:|---:|---:|")
        for i, d in enumerate(p["displacement_mm"]):
            a, b = p["neo_hookean_push_wrench"][i][1], p["linear_push_wrench"][i][1]
            c, e = -p["neo_hookean_pull_wrench"][i][1], -p["linear_pull_wrench"][i][1]
            ra = f"{a / b:.3f}" if b else "--"
            rc = f"{c / e:.3f}" if e else "--"
            print(f"| {d} | {a:.2f} | {b:.2f} | {ra} | {c:.2f} | {e:.2f} | {rc} |")
        pre = L["preload"]
        print(f"\nPreload: f0 = {pre['f0'][0]:.3f} N per patch; hyperelastic at u = 0: "
              f"{min(pre['f_neo_hookean_u0']):.3f}..{max(pre['f_neo_hookean_u0']):.3f} N; "
              f"at zero wrench {min(pre['f_neo_hookean_W0']):.3f}.."
              f"{max(pre['f_neo_hookean_W0']):.3f} N\n")
        print("| case | peak [N] | min [N] | |t| [mm] | |w| [mrad] | iterations | s | "
              "linear bonded: peak [N] | |w| [mrad] | max |NH - lin|, % of peak |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for c in L["load_control"]:
            if not c["converged"]:
                print(f"| {c['label']} | no convergence | | | | | |")
                continue
            f, u = np.array(c["normal_forces"]), np.array(c["u"])
            fl, ul = np.array(c["linear_bonded_forces"]), np.array(c["linear_bonded_u"])
            print(f"| {c['label']} | {f.max():.2f} | {f.min():.2f} | "
                  f"{1e3 * np.linalg.norm(u[:3]):.2f} | {1e3 * np.linalg.norm(u[3:]):.1f} | "
                  f"{c['iterations']} | {c['seconds']:.0f} | {fl.max():.2f} | "
                  f"{1e3 * np.linalg.norm(ul[3:]):.1f} | {c['neo_hookean_vs_linear_pct']:.1f} |")
    if res.get("convergence"):
        print("\n## Mesh convergence\n")
        print("| levels | case | max df, % of peak | |dt| [mm] | |dw| [mrad] |")
        print("|---|---|---:|---:|---:|")
        for r in res["convergence"]:
            print(f"| {r['levels'][0]} -> {r['levels'][1]} | {r['label']} | "
                  f"{r['df_pct']:.2f} | {r['dt_mm']:.3f} | {r['dw_mrad']:.2f} |")


if __name__ == "__main__":
    main()
