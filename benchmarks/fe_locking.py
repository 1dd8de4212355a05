"""Volumetric locking of the built-in tissue FE as the Poisson ratio approaches 0.5.

Rigid-cuff stiffness magnitudes diag(T^T K T) (translations [N/mm], rotations
[N*m/deg]) of 2 rows x 7 Harmony-like patches on a 25 mm layer (E = 30 kPa), at mesh
levels 1-3 and nu in {0.30, 0.45, 0.49, 0.499}, and the change from level 2 to 3 in %.
A converged discretisation changes little between the two finest levels; a locking
one stays too stiff and converges slowly from above. This is why the built-in FE
refuses nu > 0.45 (``phri_spring.physics.continuum.mesh.MAX_POISSON_RATIO``); the study calls
the FE's unit-modulus builder directly, past that check, to show what it would give.

Run from the repository root (about 2 minutes on 2 cores)::

    OPENBLAS_NUM_THREADS=1 python -m benchmarks.fe_locking
"""

from __future__ import annotations

import time

import numpy as np


from phri_spring.physics.continuum import tissue as fe  # noqa: E402
from references import rigid_cuff_fe  # noqa: E402
from phri_spring.physics.cuff.geometry import cuff_geometry  # noqa: E402

E = 3.0e4
THICKNESS = 0.025
LEVELS = (1, 2, 3)
NUS = (0.30, 0.45, 0.49, 0.499)
AXES = ("Kx", "Ky", "Kz", "Krx", "Kry", "Krz")


def stiffness(g, nu, level):
    K1, _, _, _, info = fe._build_unit_operators(g, THICKNESS, nu, level, fe.DEFAULT_LENGTH_FACTOR,
                                           "fixed")
    T = rigid_cuff_fe.rigid_cuff_map(g.points)
    H = E * np.diag(T.T @ K1 @ T)
    scale = np.array([1e-3] * 3 + [np.pi / 180.0] * 3)       # N/mm and N*m/deg
    return H * scale, info


def main():
    g = cuff_geometry([-0.0125, 0.0125], 0.045, 0.025, 75.0, 35.0, 7)
    lines = ["| nu | level | " + " | ".join(AXES) + " | build [s] |",
             "|---|---|" + "---|" * (len(AXES) + 1)]
    change = []
    for nu in NUS:
        res = {}
        for level in LEVELS:
            t0 = time.perf_counter()
            res[level], _ = stiffness(g, nu, level)
            lines.append(f"| {nu:g} | {level} | " + " | ".join(f"{v:.4g}" for v in res[level])
                         + f" | {time.perf_counter() - t0:.1f} |")
            print(lines[-1], flush=True)
        d = 100.0 * (res[2] - res[3]) / res[3]
        change.append(f"| {nu:g} | " + " | ".join(f"{v:+.2f}" for v in d) + " |")
    print("\nchange from level 2 to level 3 [% of level 3]")
    print("| nu | " + " | ".join(AXES) + " |")
    print("|---|" + "---|" * len(AXES))
    print("\n".join(change))


if __name__ == "__main__":
    main()
