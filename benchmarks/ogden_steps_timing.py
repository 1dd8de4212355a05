"""Time of ``fe_punch_ogden.punch_stiffening`` on the human preset (alpha = 10) with a given
number of load steps per 10 mm, and the beta it finds. Run from the repository root:

    python -m benchmarks.ogden_steps_timing --steps 20
    python -m benchmarks.ogden_steps_timing --steps 50

(benchmarks/STIFFENING.md gives the figures and how they were timed; needs the fe extra).
"""

import argparse
import time

from phri_spring.physics.hyperelastic.punch_ogden import punch_stiffening

if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20)
    ns = ap.parse_args()
    # the human preset: 9 mm punch on a 25 mm layer, E = 30 kPa, nu = 0.45, up to the pain
    # threshold's 120 kPa on the punch face
    t0 = time.perf_counter()
    beta = punch_stiffening(10.0, 0.0045, 0.025, 3.0e4, 0.45, 120e3 * 3.141592653589793
                            * 0.0045 ** 2, steps=ns.steps)
    print(f"steps {ns.steps}: beta {beta:.3f} 1/m in {time.perf_counter() - t0:.2f} s")
