"""The human preset's stiffening rate ``tissue.stiffening`` from a published Ogden fit.

    python examples/make_human_stiffening.py            # about 30 s
    python examples/make_human_stiffening.py --checks   # + mesh and friction checks (+20 s)

Source. Fougeron, Rohan, Haering, Rose, Bonnet and Pillet, "Combining Freehand
Ultrasound-Based Indentation and Inverse Finite Element Modeling for the Identification
of Hyperelastic Material Properties of Thigh Soft Tissues", J. Biomech. Eng. 142(9),
2020, doi:10.1115/1.4046444: in-vivo indentation of the thigh of 7 asymptomatic
subjects (a freehand ultrasound probe with a force sensor), inverse FE with a one-term
Ogden law in large displacement; relaxed muscles: shear modulus 3.2 +- 1.3 kPa and
alpha = 10 +- 1; contracted: 13.7 +- 6.5 kPa and alpha = 9 +- 4.

Conversion (no parameter is tuned to any interface data):

1. The preset's own indenter test, simulated: a rigid flat 9 mm punch
   (``tissue.indenter_diameter``) on the preset's layer (``tissue.continuum``: 25 mm,
   bonded to a rigid bone, nu = 0.45), large-deformation axisymmetric FE (9-node
   quadrilaterals, scikit-fem: the package's ``fe`` extra;
   ``phri_spring.physics.hyperelastic.punch_ogden``, which also has the inverse, alpha from an
   indenter curve's beta: ``ogden_alpha_from_stiffening``), compressible one-term Ogden
   solid W = (2 mu / alpha^2) (l1^alpha + l2^alpha + l3^alpha - 3) + (K/2)(J - 1)^2
   (isochoric stretches l_i = J^(-1/3) lambda_i), alpha = 10 (relaxed), K / mu fixed by
   nu = 0.45, the punch face bonded (a frictionless face carries 19 % less force at
   10 mm: ``--checks``).
2. The stiffening does not depend on mu: at fixed alpha and nu the energy, and so the
   force at every depth, is proportional to mu. Only alpha is taken from the study; mu is
   set so that the small-strain modulus is the preset's E = 30 kPa, whose indenter
   stiffness is ``tissue.stiffness`` = 414 N/m (the study's relaxed thigh, 3.2 kPa, would
   only scale the curve).
3. Fit range: from contact to the depth at which the mean pressure under the punch reaches
   the preset's pressure pain threshold (``interface.pain_threshold_kpa``, 120 kPa: 7.6 N
   on the 9 mm punch), as far as an indenter test on a person would go.
4. Fit: beta of the tissue law's own formula F = (k0/beta)(exp(beta d) - 1)
   (``phri_spring.physics.indentation.exponential.law_force``) by least squares, with k0
   the FE curve's own slope at contact and the contact point at d = 0, so that beta
   describes the curve's shape and pairs with the preset's k0. The package's free fit
   (``fit_branches``: k0, beta and a contact offset) is printed too; it trades k0 for beta
   (see the output) and is not used.

Printed as well: alpha at +-1 SD, other fit ranges, and the same fit for punches the size
of one Harmony element and of the whole cuff (equivalent radii), over the same depths.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from phri_spring.io.config import load_config  # noqa: E402
from phri_spring.physics.continuum.punch import flat_punch_stiffness  # noqa: E402
from phri_spring.physics.hyperelastic.punch_ogden import (fit_stiffening, punch_curve,  # noqa: E402
                                                slope_at_contact)
from phri_spring.physics.indentation.exponential import fit_branches, law_force  # noqa: E402

CONFIG = ROOT / "configs" / "human_upper_arm.yaml"
#: Fougeron et al. 2020 (J. Biomech. Eng. 142(9), doi:10.1115/1.4046444), relaxed thigh
ALPHA, ALPHA_SD = 10.0, 1.0
MU_STUDY = 3.2e3           # Pa, reported, not used (the stiffening does not depend on it)
DEPTH_MAX = 0.010          # m, deepest indentation simulated
STEPS = 50                 # load steps to DEPTH_MAX (0.2 mm each)
RUN = dict(depth=DEPTH_MAX, steps=STEPS)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--checks", action="store_true",
                    help="also a finer mesh and a frictionless punch face")
    args = ap.parse_args(argv)
    t0 = time.time()

    cfg = load_config(CONFIG)
    a = cfg.indenter_diameter / 2.0
    h, E, nu = cfg.continuum_thickness, cfg.continuum_young_modulus, cfg.poisson_ratio
    k_preset = float(np.unique(cfg.tissue_stiffness)[0])
    f_pain = cfg.pain_threshold_kpa * 1e3 * math.pi * a * a
    print(f"preset: {cfg.indenter_diameter * 1e3:g} mm punch, layer {h * 1e3:g} mm, "
          f"E = {E / 1e3:g} kPa, nu = {nu:g}, tissue.stiffness = {k_preset:g} N/m")
    print(f"source: Fougeron et al. 2020, relaxed thigh: Ogden alpha = {ALPHA:g} +- {ALPHA_SD:g} "
          f"(mu = {MU_STUDY / 1e3:g} kPa, not used: the force scales with mu)")

    k_lin = flat_punch_stiffness(h, E, nu, a)
    k_bonded = slope_at_contact(a, h, E, nu, ALPHA)
    k_slip = slope_at_contact(a, h, E, nu, ALPHA, bonded=False)
    print(f"slope at contact: this FE {k_bonded:.1f} N/m bonded face, {k_slip:.1f} N/m "
          f"frictionless; the package's linear punch FE (frictionless) {k_lin:.1f} N/m")

    depth, force, status = punch_curve(a, h, E, nu, ALPHA, **RUN)
    d_pain = float(np.interp(f_pain, force, depth))
    if status != "ok" or force[-1] < f_pain:
        raise SystemExit(f"the FE did not reach the pain-threshold force: {status}")
    print(f"\nforce-depth curve, alpha = {ALPHA:g} (every 1 mm):")
    for d, f in zip(depth[::5], force[::5]):
        tangent = np.interp(d, 0.5 * (depth[1:] + depth[:-1]), np.diff(force) / np.diff(depth))
        print(f"  {d * 1e3:5.1f} mm  {f:6.3f} N  secant {f / d if d else k_bonded:6.1f} N/m"
              f"  tangent {tangent if d else k_bonded:6.1f} N/m")
    print(f"pain threshold {cfg.pain_threshold_kpa:g} kPa on the punch = {f_pain:.2f} N, "
          f"reached at {d_pain * 1e3:.2f} mm: the fit range")

    beta, r2, worst = fit_stiffening(depth, force, k_bonded, d_pain)
    free = fit_branches([depth[depth <= d_pain]], [force[depth <= d_pain]])
    over = float(np.ravel(law_force(d_pain, k_preset, free["stiffening"]))[0]) / f_pain - 1.0
    print(f"\nbeta (k0 = slope at contact, contact at 0): {beta:.1f} 1/m "
          f"(1/beta = {1e3 / beta:.1f} mm), R^2 {r2:.4f}, largest force error {worst:.0%}")
    print(f"  the package's free fit (k0, beta, contact offset): k0 {free['k0']:.0f} N/m, "
          f"beta {free['stiffening']:.0f} 1/m, offset {free['offset'][0] * 1e3:.2f} mm, "
          f"R^2 {free['r2'][0]:.5f}: it lowers k0 to follow the first millimetres, where the "
          f"curve softens slightly; its beta with the preset's k0 = {k_preset:g} N/m would put "
          f"{over:+.0%} on the force at {d_pain * 1e3:.1f} mm")

    print("\nsensitivity (same fit):")
    out = {"beta": beta, "depth_range_m": d_pain, "k0_fe": k_bonded}
    for alpha in (ALPHA - ALPHA_SD, ALPHA + ALPHA_SD):
        d2, f2, st = punch_curve(a, h, E, nu, alpha, **RUN)
        k2 = slope_at_contact(a, h, E, nu, alpha)
        dp2 = float(np.interp(f_pain, f2, d2))
        b2 = fit_stiffening(d2, f2, k2, dp2)[0]
        out[f"beta_alpha{alpha:g}"] = b2
        print(f"  alpha = {alpha:g}: beta {b2:.1f} 1/m (range 0-{dp2 * 1e3:.2f} mm) [{st}]")
    for dmax in (0.006, 0.008, DEPTH_MAX):
        print(f"  alpha = {ALPHA:g}, range 0-{dmax * 1e3:g} mm: "
              f"beta {fit_stiffening(depth, force, k_bonded, dmax)[0]:.1f} 1/m")

    g = cfg.geometry()
    sizes = {"one Harmony element": math.sqrt(float(np.mean(g.areas)) / math.pi),
             "the whole cuff (21 elements)": math.sqrt(float(np.sum(g.areas)) / math.pi)}
    print("\nscale: punches of the same area, same tissue, same depth range "
          f"0-{d_pain * 1e3:.2f} mm")
    print(f"  {cfg.indenter_diameter * 1e3:g} mm indenter (radius {a * 1e3:.1f} mm): "
          f"beta {beta:.1f} 1/m")
    for what, radius in sizes.items():
        d3, f3, st = punch_curve(radius, h, E, nu, ALPHA, **RUN)
        k3 = slope_at_contact(radius, h, E, nu, ALPHA)
        b3 = fit_stiffening(d3, f3, k3, d_pain)[0]
        out[f"beta_radius_{radius * 1e3:.1f}mm"] = b3
        sec = float(np.interp(d_pain, d3, f3)) / d_pain / k3
        print(f"  {what} (radius {radius * 1e3:.1f} mm): beta {b3:.1f} 1/m, secant at "
              f"{d_pain * 1e3:.2f} mm {sec:.2f} x the slope at contact [{st}]")
    print(f"  (indenter: secant at {d_pain * 1e3:.2f} mm "
          f"{f_pain / d_pain / k_bonded:.2f} x the slope at contact)")

    if args.checks:
        print("\nchecks:")
        d4, f4, st = punch_curve(a, h, E, nu, ALPHA, edge_size=a / 20, **RUN)
        n = min(len(d4), len(depth))
        print(f"  edge elements a/20 instead of a/8: force differs by at most "
              f"{np.max(np.abs(f4[1:n] / force[1:n] - 1)):.2%} to {d4[n - 1] * 1e3:.1f} mm [{st}]")
        d5, f5, st = punch_curve(a, h, E, nu, ALPHA, bonded=False, **RUN)
        n = min(len(d5), len(depth))
        print(f"  frictionless face: force {f5[n - 1] / force[n - 1] - 1:+.1%} against the "
              f"bonded face at {d5[n - 1] * 1e3:.1f} mm [{st}]")

    print(f"\ntissue.stiffening for configs/human_upper_arm.yaml: {beta:.0f}  "
          f"({time.time() - t0:.0f} s)")
    return out


if __name__ == "__main__":
    main()
