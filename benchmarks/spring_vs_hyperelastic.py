"""The spring model's exponential tissue law against the neo-Hookean continuum (human preset).

    OPENBLAS_NUM_THREADS=1 python -m benchmarks.spring_vs_hyperelastic --punch

(from the repository root) prints a markdown report to stdout: about 1 min with
``--punch``, 2 s without; it writes nothing unless ``--out FILE`` is given. It compares,
for the 36 load-control cases of ``benchmarks/HYPERELASTIC_REFERENCE.json`` (level 3: a
rigid cuff bonded over the 21 patches, strap preload, neo-Hookean layer at finite strain;
see benchmarks/HYPERELASTIC_REFERENCE.md):

  (a) the compliant spring arm, linear tissue law (``tissue.stiffening: 0``), rigid cuff
      (``cuff.stiffness: .inf``, as the reference's cuff);
  (b) the same with the preset's exponential law (``tissue.stiffening: 115`` 1/m);
  (c) the linear coupled model (rigid bonded cuff, same preload), from the JSON.

Metrics per case: RMSE and largest |difference| of the 21 patch normal forces, in % of
the reference's peak patch force, also against the reference clipped at 0 (the spring
elements lift off and report 0, the bonded FE plates pull); peaks; the cuff displacement
error |S (u - u_ref)| / |S u_ref|, S = diag(1, 1, 1, R, R, R), R = 45 mm.

Also: the push into the arm (+y, 0..150 N) of (a) and (b) against the reference's F+y
load cases; the largest beta d over the elements of (b); the stiffening of the whole
rigid cuff in the reference's push/pull (no preload) against the law's; and, with
``--punch``, flat bonded punches (the 9 mm indenter's radius, one element's area, the
whole cuff's area) on the same layer, Ogden alpha = 10 (the source of beta = 115) and
alpha = 2 (neo-Hookean), with the axisymmetric large-strain FE of
examples/make_human_stiffening.py (6 curves, 5-15 s each), to separate the material's
stiffening from the contact size's.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from contextlib import redirect_stdout  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import yaml  # noqa: E402

from benchmarks.common import ROOT  # noqa: E402

from phri_spring.io.config import yaml_loader  # noqa: E402
from phri_spring.io.config import config_from_dict  # noqa: E402
from phri_spring.physics.contact.solver import solve  # noqa: E402
from phri_spring.workflows.common import model_from_config  # noqa: E402

CONFIG = ROOT / "configs" / "human_upper_arm.yaml"
REFERENCE = ROOT / "benchmarks" / "HYPERELASTIC_REFERENCE.json"
PAPER_F = (11.1, 33.4, 55.6)


# --------------------------------------------------------------------------- models


def spring_model(path: Path, beta: float):
    """The compliant arm of the config with tissue.stiffening = beta and a rigid cuff."""
    raw = yaml.load(open(path), Loader=yaml_loader._StrictSafeLoader)
    raw["tissue"]["stiffening"] = float(beta)
    raw["cuff"]["stiffness"] = float("inf")
    cfg = config_from_dict(raw, path=path, base_dir=Path(path).parent)
    return cfg, model_from_config(cfg, "compliant")


def compressions(model, u):
    """Element compressions d = delta0 + b u (m, n) [m] (rigid cuff: all in the tissue)."""
    return model.delta0[None, :] + np.asarray(u) @ model.b.T


# --------------------------------------------------------------------------- metrics


def scaled(u, R):
    return np.asarray(u, float) * np.array([1, 1, 1, R, R, R])


def force_metrics(f, ref):
    peak = float(np.max(ref))
    d = np.asarray(f) - np.asarray(ref)
    return 100 * math.sqrt(float(np.mean(d * d))) / peak, 100 * float(np.max(np.abs(d))) / peak


def case_metrics(f, u, ref_f, ref_u, R, ref_u0):
    f, ref_f = np.asarray(f, float), np.asarray(ref_f, float)
    rmse, mx = force_metrics(f, ref_f)
    # clipped reference: its pulling plates count as lifted (0), as in the spring model;
    # still in % of the (unclipped) reference peak, which clipping does not change
    rmse_c, mx_c = force_metrics(np.maximum(f, 0.0), np.maximum(ref_f, 0.0))
    su, sr = scaled(u, R), scaled(ref_u, R)
    sr0 = scaled(np.asarray(ref_u) - np.asarray(ref_u0), R)
    return {
        "u_err0": 100 * float(np.linalg.norm(su - sr0) / np.linalg.norm(sr0)),
        "peak": float(np.max(f)), "rmse": rmse, "max": mx, "rmse_clip": rmse_c,
        "max_clip": mx_c, "n_neg": int(np.sum(f < 0)), "n_zero": int(np.sum(f <= 0)),
        "u_err": 100 * float(np.linalg.norm(su - sr) / np.linalg.norm(sr)),
        "t_mm": 1e3 * float(np.linalg.norm(np.asarray(u)[:3])),
        "w_mrad": 1e3 * float(np.linalg.norm(np.asarray(u)[3:])),
        "su": float(np.linalg.norm(su)),
    }


def mirror_label(label):
    return label.replace("+", "#").replace("-", "+").replace("#", "-")


def short(label):
    """'F+x 11.1 N' -> 'F+-x 11.1' for a symmetric pair, 'M+-z 1.946' for moments."""
    name, val = label.split()[:2]
    if name[1] in "+-" and name[2] in "xz" or name[0] == "M":
        name = name[0] + "+-" + name[2]
    return f"{name} {float(val):.4g}"


def fmt(x, nd=2):
    return f"{x:.{nd}f}"


# --------------------------------------------------------------------------- punch


def punch_curves(radii, alphas, depth_max):
    """Flat bonded punches on the preset's layer (phri_spring.physics.hyperelastic.punch_ogden).

    Ogden alpha = 2 is the neo-Hookean solid of the reference (same mu, K). Returns a
    list of dicts: radius, alpha, status, k0 (slope at contact), beta fitted on 0-5 mm
    and on 0-depth_max (or to the deepest converged step), secants / k0 there.
    """
    from phri_spring.physics.hyperelastic.punch_ogden import fit_stiffening as fit_beta
    from phri_spring.physics.hyperelastic.punch_ogden import punch_curve
    from phri_spring.physics.hyperelastic.punch_ogden import slope_at_contact as small_strain_slope

    h, E, nu = 0.025, 3.0e4, 0.45
    rows = []
    for alpha in alphas:
        for a in radii:
            t0 = time.time()
            with redirect_stdout(io.StringIO()):
                depth, force, status = punch_curve(a, h, E, nu, alpha)
                k0 = small_strain_slope(a, h, E, nu, alpha)
            d_end = min(float(depth[-1]), depth_max)
            row = {"radius": a, "alpha": alpha, "status": status, "k0": k0, "d_end": d_end,
                   "seconds": time.time() - t0, "depth": depth, "force": force}
            for key, dm in (("5", min(0.005, d_end)), ("end", d_end)):
                row["beta_" + key] = fit_beta(depth, force, k0, dm)[0]
                row["sec_" + key] = float(np.interp(dm, depth, force)) / dm / k0
                row["d_" + key] = dm
            rows.append(row)
    return rows


def fit_exp_rate(depth, force, k0, dmax):
    """beta of F = (k0/beta)(exp(beta d) - 1) on 0..dmax, k0 held (same fit as the example)."""
    from phri_spring.physics.hyperelastic.punch_ogden import fit_stiffening as fit_beta
    return fit_beta(np.asarray(depth), np.asarray(force), k0, dmax)[0]


# --------------------------------------------------------------------------- report


def report(args) -> str:
    t0 = time.time()
    ref_all = json.loads(Path(args.reference).read_text())
    level = next(lv for lv in ref_all["levels"] if lv["level"] == args.level)
    cases = level["load_control"]
    labels = ref_all["labels"]
    R = 0.045

    cfg_a, ma = spring_model(args.config, 0.0)
    cfg_b, mb = spring_model(args.config, 115.0)
    assert list(ma.labels) == list(labels), (ma.labels, labels)
    beta = float(np.unique(mb.law.params["stiffening"])[0])
    k0_el = float(np.unique(np.round(mb.law.k0, 6))[0])

    W = np.array([c["wrench"] for c in cases], float)
    sa, sb = solve(ma, W), solve(mb, W)
    assert sa.converged.all() and sb.converged.all()
    db = compressions(mb, sb.u)

    u0 = np.array(level["zero_wrench_u"], float)       # the reference under W_pre alone
    rows = {}
    for i, c in enumerate(cases):
        rf, ru = np.array(c["normal_forces"]), np.array(c["u"])
        rows[c["label"]] = {
            "ref": {"peak": float(rf.max()), "n_neg": int(np.sum(rf < 0)), "min": float(rf.min()),
                    "t_mm": 1e3 * float(np.linalg.norm(ru[:3])),
                    "w_mrad": 1e3 * float(np.linalg.norm(ru[3:])),
                    "su": float(np.linalg.norm(scaled(ru, R))), "uy_mm": 1e3 * ru[1]},
            "a": case_metrics(sa.forces[i], sa.u[i], rf, ru, R, u0),
            "b": case_metrics(sb.forces[i], sb.u[i], rf, ru, R, u0),
            "c": case_metrics(c["linear_bonded_forces"], c["linear_bonded_u"], rf, ru, R, u0),
            "b_vs_a": {
                "peak": 100 * (sb.forces[i].max() / sa.forces[i].max() - 1),
                "u": 100 * float(np.linalg.norm(scaled(sb.u[i] - sa.u[i], R))
                                 / np.linalg.norm(scaled(sa.u[i], R))),
                "su": 100 * (np.linalg.norm(scaled(sb.u[i], R))
                             / np.linalg.norm(scaled(sa.u[i], R)) - 1),
            },
            "ref_vs_c": {
                "peak": 100 * (rf.max() / max(c["linear_bonded_forces"]) - 1),
                "u": 100 * float(np.linalg.norm(scaled(ru - np.array(c["linear_bonded_u"]), R))
                                 / np.linalg.norm(scaled(c["linear_bonded_u"], R))),
                "su": 100 * (np.linalg.norm(scaled(ru, R))
                             / np.linalg.norm(scaled(c["linear_bonded_u"], R)) - 1),
            },
            "bd_max": beta * float(db[i].max()), "d_max_mm": 1e3 * float(db[i].max()),
            "uy_a": 1e3 * sa.u[i][1], "uy_b": 1e3 * sb.u[i][1],
            "uy_c": 1e3 * c["linear_bonded_u"][1],
        }

    # symmetry of the +- pairs, in every metric of every model
    keys = ("peak", "rmse", "max", "rmse_clip", "max_clip", "u_err", "u_err0", "t_mm",
            "w_mrad")
    pair_dev, pairs = 0.0, 0
    for lab in rows:
        m = mirror_label(lab)
        if m == lab or m not in rows or lab > m or lab.split()[0] in ("F+y", "F-y"):
            continue
        pairs += 1
        for arm in "abc":
            for k in keys:
                pair_dev = max(pair_dev, abs(rows[lab][arm][k] - rows[m][arm][k]))
        for k in ("peak", "t_mm", "w_mrad", "n_neg"):
            pair_dev = max(pair_dev, abs(rows[lab]["ref"][k] - rows[m]["ref"][k]))
    distinct = []
    for lab in rows:
        s = short(lab)
        if s not in [short(x) for x in distinct]:
            distinct.append(lab)

    out = []
    p = out.append
    p("# Spring model (linear and exponential tissue law) against the neo-Hookean continuum\n")
    p(f"Reference: `{Path(args.reference).relative_to(ROOT)}`, level {args.level} "
      f"({level['mesh']['n_dofs']} dofs), 36 load-control cases. Config: "
      f"`{Path(args.config).relative_to(ROOT)}` with `cuff.stiffness: .inf`.")
    p(f"Spring element: k0 = {k0_el:.1f} N/m (414 N/m x A_e / (pi D^2/4) = "
      f"{k0_el / 414.0:.2f}), beta = {beta:g} 1/m in (b); preload compression "
      f"{1e3 * ma.delta0.max():.3f} mm (a) / {1e3 * mb.delta0.max():.3f} mm (b) per element "
      f"(f0 = {ma.f0.max():.3f} N); W_pre = {ma.W_pre[1]:.2f} N along +y (reference "
      f"{level['preload']['W_pre'][1]:.2f} N).")
    p(f"Symmetry: {pairs} +- pairs (F+-x, F+-z, M+-x, M+-y, M+-z at 3 loads); every metric "
      f"below of (a), (b), (c) and the reference differs within a pair by at most "
      f"{pair_dev:.1e}, so one row per pair: {len(distinct)} distinct cases.\n")

    p("## 1. Patch normal forces, % of the reference's peak patch force\n")
    p("RMSE over the 21 patches and largest |model - reference|. *ref<0*: patches where the "
      "bonded reference pulls (negative normal force); *0 in (a)/(b)*: lifted elements. "
      "*clip*: against the reference clipped at 0 (the spring arms lift off, the bonded FE "
      "pulls; (c) is bonded and is compared unclipped only).\n")
    p("| case | ref peak [N] | ref min [N] | ref<0 | 0 in a/b | peak a | peak b | peak c "
      "| RMSE a | RMSE b | RMSE c | max a | max b | max c | RMSE clip a | RMSE clip b "
      "| max clip a | max clip b |")
    p("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for lab in distinct:
        r = rows[lab]
        a, b, c = r["a"], r["b"], r["c"]
        p(f"| {short(lab)} | {fmt(r['ref']['peak'])} | {fmt(r['ref']['min'])} | "
          f"{r['ref']['n_neg']} | {a['n_zero']}/{b['n_zero']} | {fmt(a['peak'])} | "
          f"{fmt(b['peak'])} | {fmt(c['peak'])} | {a['rmse']:.1f} | {b['rmse']:.1f} | "
          f"{c['rmse']:.1f} | {a['max']:.1f} | {b['max']:.1f} | {c['max']:.1f} | "
          f"{a['rmse_clip']:.1f} | {b['rmse_clip']:.1f} | {a['max_clip']:.1f} | "
          f"{b['max_clip']:.1f} |")
    agg = {arm: {k: [rows[x][arm][k] for x in rows] for k in keys} for arm in "abc"}
    p("")
    p("| over the 36 cases | (a) linear spring | (b) exponential spring | (c) linear coupled |")
    p("|---|---:|---:|---:|")
    for k, what in (("rmse", "RMSE, median / max"), ("max", "largest diff, median / max"),
                    ("rmse_clip", "RMSE vs clipped ref, median / max"),
                    ("u_err", "displacement error, median / max"),
                    ("u_err0", "displacement error, reference from its W = 0 state")):
        cells = []
        for arm in "abc":
            if arm == "c" and k == "rmse_clip":
                cells.append("-")
                continue
            v = np.array(agg[arm][k])
            cells.append(f"{np.median(v):.1f} / {v.max():.1f} %")
        p(f"| {what} | " + " | ".join(cells) + " |")

    p("\n## 2. Cuff displacement\n")
    p("t = |translation| [mm], w = |rotation| [mrad]; error = |S (u - u_ref)| / |S u_ref| [%], "
      "S = diag(1, 1, 1, R, R, R), R = 45 mm. The reference's u includes its 25 um backing "
      "off along -y under the preload alone (HYPERELASTIC_REFERENCE.md); the spring model's "
      "and (c)'s u are 0 at zero load.\n")
    p("| case | t ref | t a | t b | t c | w ref | w a | w b | w c | err a | err b | err c |")
    p("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for lab in distinct:
        r = rows[lab]
        p(f"| {short(lab)} | {r['ref']['t_mm']:.3f} | {r['a']['t_mm']:.3f} | "
          f"{r['b']['t_mm']:.3f} | {r['c']['t_mm']:.3f} | {r['ref']['w_mrad']:.1f} | "
          f"{r['a']['w_mrad']:.1f} | {r['b']['w_mrad']:.1f} | {r['c']['w_mrad']:.1f} | "
          f"{r['a']['u_err']:.0f} | {r['b']['u_err']:.0f} | {r['c']['u_err']:.0f} |")

    p("\n## 3. What the stiffening changes, against what the continuum's nonlinearity changes\n")
    p("(b) vs (a): the exponential law turned on in the spring model. ref vs (c): the "
      "neo-Hookean continuum against the linear one (same mesh, same bonded rigid cuff, same "
      "preload). *peak*: change of the peak patch force [%]; *S du*: |S (u1 - u2)| / "
      "|S u2| [%]; *Su*: change of |S u| [%] (negative: stiffer). Largest beta d and d over "
      "the elements of (b) (beta d < 0.1: the law's secant within 5.2 % of linear; its tangent is "
      "exp(beta d) times k0).\n")
    p("| case | peak b/a | S du b vs a | Su b/a | peak ref/c | S du ref vs c "
      "| Su ref/c | max d (b) [mm] | max beta d (b) |")
    p("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for lab in distinct:
        r = rows[lab]
        p(f"| {short(lab)} | {r['b_vs_a']['peak']:+.1f} | {r['b_vs_a']['u']:.1f} | "
          f"{r['b_vs_a']['su']:+.1f} | {r['ref_vs_c']['peak']:+.1f} | "
          f"{r['ref_vs_c']['u']:.1f} | {r['ref_vs_c']['su']:+.1f} | {r['d_max_mm']:.2f} | "
          f"{r['bd_max']:.3f} |")
    big = [lab for lab in rows if abs(rows[lab]["ref"]["peak"]) > 0 and
           (abs(W[[c["label"] for c in cases].index(lab)][:3]).max() >= 55.6 - 1e-9 or
            abs(W[[c["label"] for c in cases].index(lab)][3:]).max() >= 1.94)]
    p("")
    p(f"At the largest loads (55.6 N, 1.946 N*m; {len(big)} cases): beta d of (b) at most "
      f"{max(rows[x]['bd_max'] for x in big):.3f} (smallest "
      f"{min(rows[x]['bd_max'] for x in big):.3f}); at zero load (preload only) "
      f"{beta * mb.delta0.max():.3f}. |peak b/a| at most "
      f"{max(abs(rows[x]['b_vs_a']['peak']) for x in rows):.1f} % over all 36 cases, "
      f"|peak ref/c| at most {max(abs(rows[x]['ref_vs_c']['peak']) for x in rows):.1f} %.")

    # ---- push into the arm
    p("\n## 4. Push into the arm (+y) with the preload\n")
    Fy = np.linspace(0.0, 2.0 * args.push_max, int(round(2.0 * args.push_max / 2.5)) + 1)
    Wp = np.zeros((len(Fy), 6))
    Wp[:, 1] = Fy
    pa, pb = solve(ma, Wp), solve(mb, Wp)
    assert pa.converged.all() and pb.converged.all()
    dpb = compressions(mb, pb.u)
    uya, uyb = 1e3 * pa.u[:, 1], 1e3 * pb.u[:, 1]
    ref_y = {c["wrench"][1]: c for c in cases if c["label"].startswith("F+y")}
    u0y = 1e3 * u0[1]
    p("u_y [mm] under F_y [N] (the reference and (c) only at the paper's loads). *ref*: the "
      f"reference's u_y; *ref - u(0)*: from its own state at W = 0 (u_y(0) = {u0y * 1e3:.0f} "
      "um). *sec*: secant stiffness F / u_y [N/mm] (the reference's from its W = 0 state). "
      "*lifted*: elements of (b) at 0.\n")
    p("| F_y [N] | u_y a | u_y b | u_y ref | ref - u(0) | u_y c | sec a | sec b | sec ref "
      "| sec c | max d (b) [mm] | max beta d (b) | lifted (b) |")
    p("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    show = sorted(set(list(PAPER_F) + [100.0, args.push_max]))
    for F in show:
        w = np.array([[0.0, F, 0.0, 0.0, 0.0, 0.0]])
        ua_, ub_ = solve(ma, w), solve(mb, w)
        ua, ub = 1e3 * ua_.u[0][1], 1e3 * ub_.u[0][1]
        dmx = float(compressions(mb, ub_.u)[0].max())
        nl = int(np.sum(ub_.forces[0] <= 0))
        tail = f"| {1e3 * dmx:.2f} | {beta * dmx:.3f} | {nl} |"
        if F in ref_y:
            ur = 1e3 * ref_y[F]["u"][1]
            uc = 1e3 * ref_y[F]["linear_bonded_u"][1]
            p(f"| {F:g} | {ua:.3f} | {ub:.3f} | {ur:.3f} | {ur - u0y:.3f} | {uc:.3f} | "
              f"{F / ua:.1f} | {F / ub:.1f} | {F / (ur - u0y):.1f} | {F / uc:.1f} " + tail)
        else:
            p(f"| {F:g} | {ua:.3f} | {ub:.3f} | - | - | - | {F / ua:.1f} | {F / ub:.1f} "
              "| - | - " + tail)
    # stiffening at the same displacement
    p("")
    p("Stiffening at the same cuff displacement. Spring: the force (b) needs for the "
      "displacement (a) reaches under F, over F. Continuum: the reference's force over (c)'s "
      "at the reference's displacement from its W = 0 state (c is linear: F_c(u) = F u / "
      "u_c). The tangent of (b)'s most compressed element over k0 is exp(beta d).\n")
    p("| F [N] | u_y of (a) [mm] | F_b / F_a | exp(beta d_max) (b) | u_y of ref [mm] "
      "| F_ref / F_c |")
    p("|---:|---:|---:|---:|---:|---:|")
    for F in PAPER_F + (100.0, args.push_max):
        u_a = float(np.interp(F, Fy, uya))
        Fb = float(np.interp(u_a, uyb, Fy))
        i = int(np.argmin(np.abs(uyb - u_a)))
        tan = math.exp(beta * float(dpb[i].max()))
        if F in ref_y:
            ur = 1e3 * ref_y[F]["u"][1] - u0y
            uc = 1e3 * ref_y[F]["linear_bonded_u"][1]
            p(f"| {F:g} | {u_a:.3f} | {Fb / F:.3f} | {tan:.3f} | {ur:.3f} | "
              f"{F / (F * ur / uc):.3f} |")
        else:
            p(f"| {F:g} | {u_a:.3f} | {Fb / F:.3f} | {tan:.3f} | - | - |")

    # ---- the scale of the stiffening
    pp = level["push_pull"]
    dmm = np.array(pp["displacement_mm"], float)
    fnh = np.array([w[1] for w in pp["neo_hookean_push_wrench"]])
    fnh_pull = -np.array([w[1] for w in pp["neo_hookean_pull_wrench"]])
    flin = np.array([w[1] for w in pp["linear_push_wrench"]])
    k_cuff = flin[1] / 1e-3
    b_cuff10 = fit_exp_rate(dmm * 1e-3, fnh, k_cuff, 0.010)
    b_cuff5 = fit_exp_rate(dmm * 1e-3, fnh, k_cuff, 0.005)
    p("\n## 5. The stiffening rate: indenter scale against cuff scale\n")
    punches = []
    if args.punch:
        radii = (0.0045, math.sqrt(float(np.mean(ma.areas)) / math.pi),
                 math.sqrt(float(np.sum(ma.areas)) / math.pi))
        names = {radii[0]: "9 mm punch", radii[1]: "element-area punch",
                 radii[2]: "cuff-area punch"}
        punches = punch_curves(radii, (10.0, 2.0), 0.0093)
        for r in punches:
            r["name"] = (f"{names[r['radius']]} (a = {r['radius'] * 1e3:.1f} mm), "
                         + ("neo-Hookean" if r["alpha"] == 2.0 else "Ogden alpha = 10"))
    p("Secant over the slope at contact, F(d) / (k0 d), at the same depth d, no preload. "
      f"*law*: the spring element's (exp(beta d) - 1) / (beta d), beta = {beta:g} 1/m, the "
      "same for every element size. *NH cuff*: the reference's rigid cuff over its 21 patches "
      "pushed along +y, over its linear FE's force at the same d (`push_pull` in the JSON; "
      "*pull*: along -y). Flat punches (``--punch``): examples/make_human_stiffening.py's "
      "axisymmetric large-strain FE, face bonded, on the preset's layer (25 mm on rigid bone, "
      "E = 30 kPa, nu = 0.45); Ogden alpha = 10 is the source of beta = 115, alpha = 2 is "
      "the reference's neo-Hookean solid (same mu and K). Punch radii: the 9 mm indenter's, "
      "and the radii of discs with one element's area and the whole cuff's.\n")
    depths_mm = (1, 2, 3, 5, 9)
    p("| contact, material | " + " | ".join(f"{dm} mm" for dm in depths_mm) + " |")
    p("|---|" + "---:|" * len(depths_mm))
    p("| law, beta 115 (any element) | " + " | ".join(
        f"{math.expm1(beta * dm * 1e-3) / (beta * dm * 1e-3):.3f}" for dm in depths_mm) + " |")
    for r in punches:
        cells = []
        for dm in depths_mm:
            d = dm * 1e-3
            cells.append(f"{float(np.interp(d, r['depth'], r['force'])) / d / r['k0']:.3f}"
                         if d <= r["depth"][-1] + 1e-12 else "-")
        p(f"| {r['name']} | " + " | ".join(cells) + " |")
    if not punches:
        p("| (flat punches: run with --punch) |" + " |" * len(depths_mm))
    for what, f_ in (("NH cuff push (reference)", fnh), ("NH cuff pull (reference)", fnh_pull)):
        p(f"| {what} | " + " | ".join(
            f"{f_[list(dmm).index(dm)] / flin[list(dmm).index(dm)]:.3f}"
            for dm in depths_mm) + " |")
    p("")
    p("beta of F = (k0/beta)(exp(beta d) - 1) fitted with k0 held at the slope at contact "
      "(the fit of examples/make_human_stiffening.py), over 0-5 mm and over 0-9.3 mm (the "
      "preset's fit range: the depth at which the 9 mm punch reaches the pain threshold).\n")
    p("| contact | k0 [N/mm] | beta 0-5 mm [1/m] | beta 0-9.3 mm [1/m] | FE |")
    p("|---|---:|---:|---:|---|")
    for r in punches:
        end = (f"{r['beta_end']:.1f}" if r["d_end"] >= 0.0093 - 1e-9
               else f"- (to {r['d_end'] * 1e3:.1f} mm: {r['beta_end']:.1f})")
        p(f"| {r['name']} | {r['k0'] / 1e3:.3f} | {r['beta_5']:.1f} | {end} | "
          f"{r['status']}, {r['seconds']:.0f} s |")
    if not punches:
        p("| (run with --punch for the flat punches) | | | | |")
    p(f"| NH cuff push (reference JSON) | {k_cuff / 1e3:.2f} | {b_cuff5:.1f} | "
      f"{fit_exp_rate(dmm * 1e-3, fnh, k_cuff, 0.0093):.1f} (0-10 mm: {b_cuff10:.1f}) | - |")
    p("")
    p("The spring element with beta = 115 1/m has, at a compression d, the tangent "
      "exp(115 d) k0 whatever its size: x1.12 at 1 mm, x1.41 at 3 mm, x3.16 at 10 mm.")
    p(f"\n(report built in {time.time() - t0:.0f} s)")
    return "\n".join(out) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", type=Path, default=CONFIG)
    ap.add_argument("--reference", type=Path, default=REFERENCE)
    ap.add_argument("--level", type=int, default=3)
    ap.add_argument("--push-max", type=float, default=150.0,
                    help="largest +y force of the push sweep [N]")
    ap.add_argument("--punch", action="store_true",
                    help="also run the flat-punch FEs (6 curves, about 1 min)")
    ap.add_argument("--out", type=Path, help="also write the report to this file")
    args = ap.parse_args(argv)
    args.config, args.reference = args.config.resolve(), args.reference.resolve()
    text = report(args)
    sys.stdout.write(text)
    if args.out:
        args.out.write_text(text)


if __name__ == "__main__":
    main()
