"""Many 6x6 symmetric positive definite systems solved at once (the spring solvers' step)."""

from __future__ import annotations

import numpy as np

__all__ = ["spd_solve_batched"]


def spd_solve_batched(Hf: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve many 6x6 SPD systems at once by a vectorised Cholesky factorisation.

    Hf has shape (36, m) (row-major 6x6 entries, samples last), rhs (m, 6).
    numpy's batched ``linalg.solve`` calls LAPACK once per matrix; this does
    about 150 array operations over all samples instead.
    """
    L = {}
    for j in range(6):
        d = Hf[7 * j].copy()
        for k in range(j):
            d -= L[j, k] * L[j, k]
        L[j, j] = np.sqrt(d)
        inv = 1.0 / L[j, j]
        L[j, j, "inv"] = inv
        for i in range(j + 1, 6):
            v = Hf[6 * i + j].copy()
            for k in range(j):
                v -= L[i, k] * L[j, k]
            L[i, j] = v * inv
    y = []
    for i in range(6):
        v = rhs[:, i].copy()
        for k in range(i):
            v -= L[i, k] * y[k]
        y.append(v * L[i, i, "inv"])
    x = [None] * 6
    for i in range(5, -1, -1):
        v = y[i]
        for k in range(i + 1, 6):
            v = v - L[k, i] * x[k]
        x[i] = v * L[i, i, "inv"]
    return np.stack(x, axis=1)
