"""Time and memory of placing the cuff's elements on a limb scan (writes nothing but a temp file).

A tapered elliptic tube of about ``--triangles`` triangles is written as a binary STL in mm,
then read (trimesh) and the paper's 21 elements are computed on it
(``phri_spring.io.scan.scan_elements``). Prints the wall times of reading and of the elements,
and the peak resident memory (single runs: wall time on a shared machine is noisy). Run from
the repository root, e.g.

    /usr/bin/time -v python -m benchmarks.scan_benchmark --triangles 1000000

(numbers: benchmarks/SCAN.md).
"""

from __future__ import annotations

import argparse
import resource
import struct
import tempfile
import time
from pathlib import Path

import numpy as np

from phri_spring.io.scan import read_mesh, scan_elements


def tube(n_around: int, n_rings: int):
    xs = np.linspace(-0.13, 0.13, n_rings)
    u = 2 * np.pi * np.arange(n_around) / n_around
    shrink = xs[:, None] * np.tan(np.radians(4.0))
    y, z = (0.050 - shrink) * np.cos(u), (0.042 - shrink) * np.sin(u)
    v = np.stack([np.broadcast_to(xs[:, None], y.shape), y, z], -1).reshape(-1, 3)
    i = np.arange(n_around)
    j = (i + 1) % n_around
    r = np.arange(n_rings - 1)[:, None] * n_around
    a, b = (r + i).ravel(), (r + j).ravel()
    f = np.vstack([np.column_stack([a, b, b + n_around]),
                   np.column_stack([a, b + n_around, a + n_around])])
    return v, f


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, default=1_000_000)
    args = ap.parse_args()
    n_around = int(np.sqrt(args.triangles / 2 * 8))       # facets ~ 1/4 as long around as along
    n_rings = max(3, int(args.triangles / (2 * n_around)) + 1)
    v, f = tube(n_around, n_rings)
    rows = np.array([-0.025, 0.0, 0.025])
    theta = np.radians(75 + 35.0 * np.arange(7))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "tube.stl"
        tri = (1000 * v[f]).astype("<f4")
        with open(path, "wb") as fh:
            fh.write(b"benchmark".ljust(80) + struct.pack("<I", len(f)))
            rec = np.zeros(len(f), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
            rec["v"] = tri
            fh.write(rec.tobytes())
        cfg = {"file": str(path), "unit": "mm", "origin": [0, 0, 0], "axis": [1, 0, 0],
               "y_axis": [0, 1, 0], "max_triangles": max(len(f), 1)}
        t0 = time.perf_counter()
        read_mesh(path, max_triangles=len(f))
        t1 = time.perf_counter()
        g = scan_elements(cfg, rows, np.full(3, 0.025), theta, np.full(7, np.radians(35.0)))
        t2 = time.perf_counter()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"triangles {len(f)} ({n_around} around x {n_rings} rings); read {t1 - t0:.2f} s; "
          f"scan_elements (reads again, then computes) {t2 - t1:.2f} s; peak RSS {peak:.0f} MB; "
          f"sum of areas {g.areas.sum():.6e} m^2")


if __name__ == "__main__":
    main()
