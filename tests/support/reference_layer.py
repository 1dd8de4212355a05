"""An independent reference for the flat-punch stiffness of a bonded layer, for tests
and benchmarks only: it never imports phri_spring (nothing shared with the FE).
"""

from __future__ import annotations

import numpy as np

__all__ = ["kappa_integral_equation"]


def kappa_integral_equation(a_over_h, nu, m=64, xmax=40.0, nx=600):
    """Independent reference: kappa of a frictionless flat punch on a bonded layer.

    Provenance: the mixed boundary-value problem of Hayes, Keer, Herrmann & Mockros
    (1972), "A mathematical analysis for indentation tests of articular cartilage",
    J. Biomech. 5:541-551 (layer bonded to a rigid half-space, rigid frictionless
    plane-ended punch), reduced by Copson's representation to a Fredholm equation of the
    second kind phi(s) + int_0^1 k(s, r) phi(r) dr = 1 with
    k(s, r) = (2/pi) (a/h) int_0^inf (L(x) - 1) cos(x s a/h) cos(x r a/h) dx and the
    bonded-layer kernel L(x) = (2 al sinh 2x - 4x)/(2 al cosh 2x + 1 + al^2 + 4x^2),
    al = 3 - 4 nu; kappa = int_0^1 phi. Checks of L: L -> 1 for a thick layer (Boussinesq)
    and L ~ x (1 - 2nu) / (2 (1 - nu)^2) for a thin one (confined compression). Solved
    here by Gauss-Legendre Nystrom, nothing shared with the FE.
    (The printed table of Hayes et al. was not available to us; their kappa at
    a/h = 1, nu = 0.45 is reported around 3, consistent with the 3.09 computed here.)
    """
    al = 3.0 - 4.0 * nu
    s, w = np.polynomial.legendre.leggauss(m)
    s, w = 0.5 * (s + 1), 0.5 * w
    X, WX = np.polynomial.legendre.leggauss(nx)
    x, wx = 0.5 * (X + 1) * xmax, 0.5 * WX * xmax
    e = np.exp(-2 * x)
    Lm1 = (al * (1 - e * e) - 4 * x * e) / (al * (1 + e * e) + (1 + al * al + 4 * x * x) * e) - 1
    C = np.cos(np.outer(s, x) * a_over_h)
    k = (2 / np.pi) * a_over_h * (C * (Lm1 * wx)) @ C.T
    phi = np.linalg.solve(np.eye(m) + k * w[None, :], np.ones(m))
    return float(phi @ w)
