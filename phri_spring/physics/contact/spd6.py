"""Many 6x6 symmetric positive definite systems solved at once (the spring solvers' step)."""

from __future__ import annotations

import numpy as np

__all__ = ["spd_factor_batched", "spd_solve_batched", "spd_solve_factored", "SYM6_UPPER",
           "SYM6_FULL"]

#: the 21 upper-triangle entries of a symmetric 6x6 (row-major flat indices), and for each
#: of its 36 entries the place of that entry's value among those 21
SYM6_UPPER = np.array([6 * i + j for i in range(6) for j in range(i, 6)])
SYM6_FULL = np.array([[list(SYM6_UPPER).index(6 * min(i, j) + max(i, j)) for j in range(6)]
                      for i in range(6)]).ravel()


def spd_factor_batched(Hf: np.ndarray) -> dict:
    """Cholesky factors of many 6x6 SPD matrices at once.

    Hf has shape (36, ...) (row-major 6x6 entries first, the matrices after). Returns the
    factor as a dict: ``L[i, j]`` (i >= j) and ``L[i, i, "inv"]`` = 1 / L[i, i], each an
    array of the matrices' shape. numpy's batched ``linalg`` calls LAPACK once per
    matrix; this does about 80 array operations over all of them instead.
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
    return L


def spd_solve_factored(L: dict, rhs) -> list:
    """Solve with factors from :func:`spd_factor_batched`: rhs is six arrays (the
    right-hand sides' components), each broadcastable against the factors' shape (so one
    factor can serve several right-hand sides). Returns the six components of x."""
    y = []
    for i in range(6):
        v = rhs[i].copy()
        for k in range(i):
            v -= L[i, k] * y[k]
        y.append(v * L[i, i, "inv"])
    x = [None] * 6
    for i in range(5, -1, -1):
        v = y[i]
        for k in range(i + 1, 6):
            v = v - L[k, i] * x[k]
        x[i] = v * L[i, i, "inv"]
    return x


def spd_solve_batched(Hf: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve many 6x6 SPD systems at once by a vectorised Cholesky factorisation.

    Hf has shape (36, m) (row-major 6x6 entries, samples last), rhs (m, 6).
    """
    x = spd_solve_factored(spd_factor_batched(Hf), [rhs[:, i] for i in range(6)])
    return np.stack(x, axis=1)
