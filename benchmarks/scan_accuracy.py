"""How a scan's noise reaches the elements' normals, turnings and areas (no files written).

A cylinder of radius 45 mm (360 facets around, rings 2.5 mm apart) has every vertex moved by
Gaussian noise of standard deviation sigma in each coordinate (fixed seeds); the paper's 21
elements are computed on it (``scan_element_geometry``, default smoothing and a larger one)
and compared with the circle's closed forms: the largest normal error [rad], and the largest
relative errors of the turnings and the areas over the 21 elements, as the mean over the seeds.
Run from the repository root:

    python -m benchmarks.scan_accuracy

(numbers: benchmarks/SCAN.md).
"""

from __future__ import annotations

import numpy as np

from phri_spring.physics.limb.scan_sections import scan_element_geometry

R = 0.045
ROWS = np.array([-0.025, 0.0, 0.025])
THETA = np.radians(75.17 + 35.0 * np.arange(7))
SPAN = np.full(7, np.radians(35.0))


def cylinder(n_around=360, n_rings=57):
    xs = np.linspace(-0.07, 0.07, n_rings)
    u = 2 * np.pi * np.arange(n_around) / n_around
    v = np.stack([np.broadcast_to(xs[:, None], (n_rings, n_around)),
                  np.broadcast_to(R * np.cos(u), (n_rings, n_around)),
                  np.broadcast_to(R * np.sin(u), (n_rings, n_around))], -1).reshape(-1, 3)
    i = np.arange(n_around)
    j = (i + 1) % n_around
    r = np.arange(n_rings - 1)[:, None] * n_around
    a, b = (r + i).ravel(), (r + j).ravel()
    f = np.vstack([np.column_stack([a, b, b + n_around]),
                   np.column_stack([a, b + n_around, a + n_around])])
    return v, f


def main() -> None:
    v, f = cylinder()
    th = np.tile(THETA, 3)
    want = -np.column_stack([np.zeros_like(th), np.cos(th), np.sin(th)])
    print("| noise sigma [um] | smoothing h [mm] | normal [rad] | turning [%] | area [%] |")
    print("|---:|---:|---:|---:|---:|")
    for sigma in (0.0, 10e-6, 20e-6, 50e-6, 100e-6):
        for h in (None, 0.008):
            errs = []
            for seed in range(5):
                noisy = v + np.random.default_rng(seed).normal(0.0, sigma, v.shape)
                g = scan_element_geometry(noisy, f, ROWS, np.full(3, 0.025), THETA, SPAN,
                                          smoothing=h)
                errs.append([np.abs(g.normals - want).max(),
                             100 * np.abs(g.turning / SPAN[0] - 1).max(),
                             100 * np.abs(g.areas / (0.025 * R * SPAN[0]) - 1).max()])
            e = np.mean(errs, axis=0)
            print(f"| {sigma * 1e6:g} | {1e3 * g.smoothing[0]:.1f} | {e[0]:.4f} | {e[1]:.1f} | "
                  f"{e[2]:.2f} |")


if __name__ == "__main__":
    main()
