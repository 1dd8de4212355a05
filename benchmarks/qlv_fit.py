"""Accuracy and cost of ``phri fit-stiffness --law qlv`` on synthetic ramp-hold trials.

Per seed, one synthetic trial (:mod:`phri_spring.synthetic.indenter_qlv`: rest 3.5 s, ramp
1 s to 4 mm, hold 20 s, release 1 s, 100 Hz, k = 4000 N/m, g = (0.30, 0.20),
tau = (0.4, 5.0) s) with force noise of 0.5 % of the peak, a sensor offset and 0.025 mm
encoder steps, is fitted with two Prony terms; the worst and mean errors over the seeds are
printed, with the fit's wall time per trial.

Run from the repository root:  python -m benchmarks.qlv_fit [--seeds 20]
"""

from __future__ import annotations

import argparse
import time

import numpy as np  # noqa: E402

from phri_spring.physics.indentation.qlv import fit_qlv  # noqa: E402
from phri_spring.physics.indentation.qlv_window import qlv_window  # noqa: E402
from phri_spring.synthetic.indenter_qlv import synth_qlv_trial  # noqa: E402

K, G, TAU = 4000.0, np.array([0.30, 0.20]), np.array([0.4, 5.0])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    args = ap.parse_args()
    for elastic, beta in (("linear", 0.0), ("exponential", 250.0)):
        errs, secs = [], []
        for seed in range(args.seeds):
            tr = synth_qlv_trial(K, G, TAU, stiffening=beta, noise=0.005, offset=0.3,
                                 encoder=True, seed=seed)
            w = qlv_window(tr.time, tr.displacement, tr.force)
            t0 = time.perf_counter()
            fit = fit_qlv([w], terms=2, elastic=elastic)
            secs.append(time.perf_counter() - t0)
            errs.append([abs(fit.stiffness / K - 1), *np.abs(fit.times_s / TAU - 1),
                         *np.abs(fit.fractions - G),
                         abs(fit.stiffening / beta - 1) if beta else abs(fit.stiffening)])
        e = np.array(errs)
        names = ["k rel", "tau1 rel", "tau2 rel", "g1 abs", "g2 abs",
                 "beta rel" if beta else "beta [1/m]"]
        print(f"{elastic} elastic part, {args.seeds} seeds:")
        for j, n in enumerate(names):
            print(f"  {n:10s} mean {e[:, j].mean():.4f}  max {e[:, j].max():.4f}")
        print(f"  fit time per trial: median {np.median(secs):.3f} s, max {max(secs):.3f} s")


if __name__ == "__main__":
    main()
