"""The coupled model's patch normal forces against an FE that models the contact itself.

Run from the repository root (prints markdown; ``benchmarks/CONTACT_REFERENCE.md`` holds
a run and what it means)::

    OPENBLAS_NUM_THREADS=1 python -m benchmarks.contact_reference                # levels 2,3
    OPENBLAS_NUM_THREADS=1 python -m benchmarks.contact_reference --levels 2 --forces 11.1
    OPENBLAS_NUM_THREADS=1 python -m benchmarks.contact_reference --through centre

The reference (:mod:`references.contact_fe`) is the coupled model's own tissue FE
with every skin node under a plate a unilateral contact of its own, frictionless or with
Coulomb friction along a loading path, the cuff, its springs and the strap preload (delta,
W_pre) taken from the coupled model. Loads: the paper's horizontal (load-cell z) and
vertical (load-cell y) forces, both signs, in two families (``--through``):

* ``loadcell`` -- the force at the load cell: the reading turned into the cuff wrench by
  ``workflows.common.cuff_wrench``. The human preset's load cell sits 70 mm below the arm
  axis, so a horizontal force is also a torsion about the arm (0.07 m x F);
* ``centre`` -- the same force through the cuff centre (the cuff origin, on the arm's
  axis) with zero moment, as a push on the cuff; the load cell would read it with the
  moment -p x F (found by the inverse load-cell map). On the human preset the vertical
  force through the load cell already passes through the axis: the same wrench, solved
  once.

Variants:

* ``bonded`` -- the coupled model without friction (touching patches tied, lifted ones
  still tied tangentially) against the FE with mu = inf (touching nodes never slide);
* ``mu=0.5`` -- both with Coulomb friction (config ``interface.friction_coefficient``),
  along the same path: zero wrench, then ``--steps`` equal increments to the load;
* ``frictionless`` -- both with mu = 0 (nothing resists torsion about the arm: the
  horizontal loads through the load cell have no equilibrium).

The coupled model is the library's (``model_from_config(cfg, "coupled")``) with its
surface stiffness built at each mesh level of the reference (the shipped one is level 3;
at that level the script checks it against ``model_from_config`` as shipped).
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import copy  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402


from phri_spring.errors import ConvergenceError, PhriError  # noqa: E402
from phri_spring.io.config import config_from_dict, load_yaml  # noqa: E402
from references import contact_fe as fc  # noqa: E402
from phri_spring.physics.continuum.mesh import DEFAULT_LEVEL  # noqa: E402
from phri_spring.physics.contact.solver import solve  # noqa: E402
from phri_spring.workflows.common import (continuum_modulus, coupled_model,  # noqa: E402
                                          cuff_wrench, model_from_config)

VARIANTS = ("bonded", "mu", "frictionless")
FAMILY = {"loadcell": "through load cell", "centre": "through centre"}


def config(path, mu):
    raw = load_yaml(path)
    if mu is not None:
        raw = copy.deepcopy(raw)
        raw.setdefault("interface", {})["friction_coefficient"] = float(mu)
    return config_from_dict(raw, path=path, base_dir=Path(path).parent)


def cases(cfg, forces, through):
    """(family, label, cuff wrench) of the paper's loads: load-cell z horizontal, y vertical.

    ``loadcell``: the force acts at the load cell, ``workflows.common.cuff_wrench`` of the
    reading (with the moment of the force about the cuff origin: the load cell sits below
    the arm). ``centre``: the same force (cuff frame) through the cuff origin on the arm's
    axis, zero moment; the load cell would read it with the moment -p x F (the reading
    is found by the inverse of the load-cell map and checked against it)."""
    A = cuff_wrench(cfg, np.eye(6))              # row j: cuff wrench of unit reading j
    out = []
    for fam in through:
        for axis, name in ((2, "horizontal"), (1, "vertical")):
            for sign in (1, -1):
                for F in forces:
                    w = np.zeros(6)
                    w[axis] = sign * F
                    W = cuff_wrench(cfg, w[None])[0]
                    if fam == "centre":
                        W[3:] = 0.0
                        reading = np.linalg.solve(A.T, W)
                        if not np.allclose(cuff_wrench(cfg, reading[None])[0], W, rtol=0,
                                           atol=1e-12 * F):
                            raise RuntimeError("inverse load-cell map")  # pragma: no cover
                    out.append((fam, f"{name}, {FAMILY[fam]} {sign * F:+g} N", W))
    return out


def coupled_forces(model, W, steps):
    """Reported patch normal forces [N] (NaN: no converged answer) and patches pressing."""
    try:
        if getattr(model, "friction_coefficient", None) is None:
            sol = solve(model, W[None])
        else:   # a loading path: zero wrench, then equal increments
            sol = solve(model, np.outer(np.arange(steps + 1) / steps, W))
    except (PhriError, np.linalg.LinAlgError, ValueError) as exc:
        return np.full(model.n, np.nan), -1, str(exc)
    f = np.asarray(sol.forces)[-1]
    ok = bool(np.asarray(sol.converged).ravel()[-1]) and np.all(np.isfinite(f))
    return (f if ok else np.full(model.n, np.nan)), int(np.asarray(sol.contact)[-1].sum()), \
        None if ok else "not converged"


def fe_forces(fe, model, W, mu, steps, preload_steps):
    t0 = time.perf_counter()
    try:
        sol = fc.solve_contact(fe, model, W, friction_coefficient=mu, steps=steps,
                               preload_steps=preload_steps)
    except ConvergenceError as exc:
        return None, time.perf_counter() - t0, str(exc)
    return sol, time.perf_counter() - t0, None


def load_fe(cfg, level, fe_cache):
    """The contact FE at ``level`` (pickled in ``fe_cache`` when given)."""
    import pickle

    path = None
    if fe_cache:
        Path(fe_cache).mkdir(parents=True, exist_ok=True)
        path = Path(fe_cache) / f"contact-fe-{Path(cfg.path).stem}-L{level}.pkl"
        if path.exists():
            with open(path, "rb") as fh:
                return pickle.load(fh)
    fe = fc.build_contact_fe(cfg.geometry(), cfg.continuum_thickness,
                             float(np.mean(continuum_modulus(cfg))), cfg.poisson_ratio,
                             level=level, patch_gap=getattr(cfg, "continuum_patch_gap", None))
    if path is not None:
        with open(path, "wb") as fh:
            pickle.dump(fe, fh)
    return fe


def pct(x):
    return "n/a" if not np.isfinite(x) else f"{x:.2f}"


def variant_name(k, mu):
    return f"mu={mu:g}" if k == "mu" else k


def table_row(name, label, r):
    """One row of a results table (the FE's answer against the coupled model's)."""
    sol = r["sol"]
    if sol is None:
        c = "no answer" if r["why_c"] else "converged"
        return (f"| {name} | {label} | FE: no equilibrium | -- / {c} | -- | -- | -- | "
                f"{r['secs']:.1f} |")
    f = sol.normal_forces
    peak = f.max()
    d = r["coupled"] - f
    pe = np.array([np.any(sol.contact & (sol.plate == e)) for e in range(len(f))]).sum()
    return (f"| {name} | {label} | {peak:.2f} | {pe} / "
            f"{'no answer' if r['why_c'] else r['n_coupled']} | "
            f"{sol.contact.sum()} / {sol.slip.sum()} | "
            f"{pct(100 * np.sqrt(np.mean(d ** 2)) / peak)} | "
            f"{pct(100 * np.max(np.abs(d)) / peak)} | {r['secs']:.1f} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", default="configs/human_upper_arm.yaml")
    ap.add_argument("--levels", default="2,3", help="mesh levels, comma separated")
    ap.add_argument("--forces", default="11.1,33.4,55.6", help="load-cell forces [N]")
    ap.add_argument("--through", default="loadcell,centre",
                    help="where the forces act, comma separated: loadcell (at the load "
                         "cell, with its moment about the cuff origin) and/or centre "
                         "(through the cuff origin on the arm's axis, zero moment)")
    ap.add_argument("--mu", type=float, default=0.5, help="Coulomb coefficient [-]")
    ap.add_argument("--steps", type=int, default=8, help="load increments (friction)")
    ap.add_argument("--preload-steps", type=int, default=4, help="strap preload increments")
    ap.add_argument("--cache-dir", default=None, help="surface stiffness cache (default: "
                    "phri's own)")
    ap.add_argument("--fe-cache", default=None, help="keep the contact FE (pickles) here")
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    levels = [int(v) for v in args.levels.split(",")]
    forces = [float(v) for v in args.forces.split(",")]
    through = [v.strip() for v in args.through.split(",")]
    if not through or set(through) - set(FAMILY):
        ap.error(f"--through: expected a comma-separated subset of {', '.join(FAMILY)}, "
                 f"got {args.through!r}")
    mus = {"bonded": None, "mu": args.mu, "frictionless": 0.0}
    fe_mu = {"bonded": np.inf, "mu": args.mu, "frictionless": 0.0}
    cfgs = {k: config(args.config, v) for k, v in mus.items()}
    load = cases(cfgs["bonded"], forces, through)
    print(f"# Contact reference: `{args.config}`, mu = {args.mu:g}\n")
    cmd = " ".join(["OPENBLAS_NUM_THREADS=1 python -m benchmarks.contact_reference",
                    *(argv if argv is not None else sys.argv[1:])])
    print(f"Command: `{cmd}`\n")
    print(f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, numpy {np.__version__}\n")
    A = cuff_wrench(cfgs["bonded"], np.eye(6))
    print("Loads: the cuff wrench about the cuff origin (cuff frame) and the load cell's "
          "reading of it.\n")
    print("| case | F cuff [N] | M cuff [N*m] | load-cell moment [N*m] |")
    print("|---|---|---|---|")
    vec = lambda v: "(" + ", ".join(f"{x + 0.0:.3g}" for x in v) + ")"   # noqa: E731
    for fam, label, W in load:
        reading = np.linalg.solve(A.T, W)
        reading[np.abs(reading) < 1e-12 * np.abs(W).max()] = 0.0     # round-off
        print(f"| {label} | {vec(W[:3])} | {vec(W[3:])} | {vec(reading[3:])} |")
    # a case whose wrench an earlier case has already is solved once
    same = {}
    for i, (_, label, W) in enumerate(load):
        for _, lab0, W0 in load[:i]:
            if np.array_equal(W, W0):
                same[label] = lab0
                break
    if same:
        print("\nThe same cuff wrench, solved once: " + "; ".join(
            f"{a} = {b}" for a, b in same.items()) + ".")
    print()
    results = {}
    for level in levels:
        models = {}
        for k in VARIANTS:
            try:
                models[k] = coupled_model(cfgs[k], level=level, cache_dir=args.cache_dir)
            except (PhriError, ValueError, TypeError) as exc:
                models[k] = None
                print(f"- level {level}, {k}: coupled model not available ({exc})")
        if level == DEFAULT_LEVEL:
            shipped = model_from_config(cfgs["bonded"], "coupled", cache_dir=args.cache_dir)
            d = max(float(np.max(np.abs(solve(shipped, W[None]).forces
                                        - solve(models["bonded"], W[None]).forces)))
                    for _, label, W in load if label not in same)
            print(f"- level {level}: this script's coupled model against model_from_config: "
                  f"largest difference {d:.2e} N\n")
        t0 = time.perf_counter()
        fe = load_fe(cfgs["bonded"], level, args.fe_cache)
        print(f"- level {level}: contact FE {fe.info['n_dofs']} dofs, "
              f"{fe.info['n_nodes']} contact nodes, plates {fe.info['patch_gap'] * 1e3:g} mm "
              f"apart, built in {time.perf_counter() - t0:.0f} s "
              f"(condensation {fe.info['seconds']:.0f} s)\n", flush=True)
        for k in VARIANTS:
            for _, label, W in load:
                if label in same:
                    results[level, k, label] = results[level, k, same[label]]
                    continue
                fc_, nc_, why_c = (coupled_forces(models[k], W, args.steps) if models[k]
                                   is not None else (np.full(fe.geometry.n, np.nan), -1, "n/a"))
                sol, secs, why = fe_forces(fe, models["bonded"], W, fe_mu[k], args.steps,
                                           args.preload_steps)
                results[level, k, label] = dict(coupled=fc_, n_coupled=nc_, why_c=why_c,
                                                sol=sol, secs=secs, why=why)
        del fe
    print("\n## Patch normal forces: contact FE against the coupled model\n")
    print("RMSE and largest difference over the 21 patches in % of the FE's peak patch "
          "force; patches: those with a node touching (FE) / in contact (coupled); "
          "nodes: FE nodes touching / sliding; FE s: the FE's solve (0.0 for a case "
          "solved once before).\n")
    for level in levels:
        for fam in through:
            print(f"\n### Level {level}, {FAMILY[fam]}\n")
            print("| variant | case | FE peak [N] | patches FE / coupled | nodes touching / "
                  "sliding | RMSE % | max % | FE s |")
            print("|---|---|---:|---:|---:|---:|---:|---:|")
            for k in VARIANTS:
                for fam_, label, _ in load:
                    if fam_ == fam:
                        r = dict(results[level, k, label])
                        if label in same:
                            r["secs"] = 0.0
                        print(table_row(variant_name(k, args.mu), label, r))
    if len(levels) > 1:
        a, b = levels[-2], levels[-1]
        print(f"\n## Mesh convergence of the reference: level {a} -> {b}\n")
        print("Change of the FE's patch normal forces in % of its peak at level "
              f"{b} (largest patch, RMSE); the coupled model's own change alongside.\n")
        for fam in through:
            print(f"\n### {FAMILY[fam].capitalize()}\n")
            print("| variant | case | FE max % | FE RMSE % | coupled max % |")
            print("|---|---|---:|---:|---:|")
            for k in VARIANTS:
                for fam_, label, _ in load:
                    ra, rb = results[a, k, label], results[b, k, label]
                    if fam_ != fam or ra["sol"] is None or rb["sol"] is None:
                        continue
                    fa, fb = ra["sol"].normal_forces, rb["sol"].normal_forces
                    peak = fb.max()
                    dc = np.max(np.abs(rb["coupled"] - ra["coupled"])) / peak
                    print(f"| {variant_name(k, args.mu)} | {label} | "
                          f"{100 * np.max(np.abs(fb - fa)) / peak:.2f} | "
                          f"{100 * np.sqrt(np.mean((fb - fa) ** 2)) / peak:.2f} | "
                          f"{pct(100 * dc)} |")
    notes = sorted({(k, r["why_c"]) for (lv, k, lab), r in results.items() if r["why_c"]})
    if notes:
        print("\nCoupled model without an answer: " + "; ".join(
            f"{k}: {why}" for k, why in notes) + ".")
    # the finest level's forces, patch by patch, where the two models differ most
    top = levels[-1]
    geo = cfgs["bonded"].geometry()
    print(f"\n## Largest differences at level {top}, patch by patch [N]\n")
    for fam in through:
        for k in VARIANTS:
            rows = [(label, results[top, k, label]) for fam_, label, _ in load
                    if fam_ == fam and label not in same
                    and results[top, k, label]["sol"] is not None
                    and np.all(np.isfinite(results[top, k, label]["coupled"]))]
            if not rows:
                continue
            lab, r = max(rows, key=lambda t: np.sqrt(np.mean(
                (t[1]["coupled"] - t[1]["sol"].normal_forces) ** 2))
                / t[1]["sol"].normal_forces.max())
            n = r["sol"].normal_forces.shape[0]
            print(f"{variant_name(k, args.mu)}, {lab}:\n")
            print("| | " + " | ".join(geo.labels[:n]) + " |")
            print("|---|" + "---:|" * n)
            print("| FE | " + " | ".join(f"{v:.2f}" for v in r["sol"].normal_forces) + " |")
            print("| coupled | " + " | ".join(f"{v:.2f}" for v in r["coupled"]) + " |\n")
    mem = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"\nTotal {time.perf_counter() - t_start:.0f} s, peak memory {mem:.0f} MB.")


if __name__ == "__main__":
    main()
