"""The QLV force of an elastic response history by the hereditary integral, written out
independently of the recursion the code uses (docs/model.md section 15; Fung 1993, ch. 7):
the reference of the relaxation tests."""

from __future__ import annotations

import numpy as np


def hereditary_force(prony, t, Fe) -> np.ndarray:
    """The QLV force at every sample of an elastic response history, by the exact integral.

    F(t_n) = G_inf F^e_n + sum_i g_i sum_{k=1}^{n} (F^e_k - F^e_{k-1}) / dt_k
             * int_{t_{k-1}}^{t_k} exp(-(t_n - s) / tau_i) ds,

    F^e linear between samples and rested at F^e_0 before t_0. O(m^2) work: the tests' reference
    for the solver's recursion (:func:`phri_spring.physics.history.relaxation.step_coefficients`).

    Parameters
    ----------
    t : array_like, shape (m,)
        Increasing sample times [s].
    Fe : array_like, shape (m, ...)
        Elastic response F^e at every sample (any trailing shape).
    """
    t = np.asarray(t, dtype=float)
    Fe = np.asarray(Fe, dtype=float)
    out = prony.relaxed * Fe.copy()
    for n in range(1, len(t)):
        for g, tau in zip(prony.g, prony.tau):
            acc = np.zeros(Fe.shape[1:])
            for k in range(1, n + 1):
                dt = t[k] - t[k - 1]
                w = (tau * (np.exp(-(t[n] - t[k]) / tau) - np.exp(-(t[n] - t[k - 1]) / tau)) / dt
                     if dt > 0 else np.exp(-(t[n] - t[k]) / tau))
                acc = acc + w * (Fe[k] - Fe[k - 1])
            out[n] = out[n] + g * acc
    return out
