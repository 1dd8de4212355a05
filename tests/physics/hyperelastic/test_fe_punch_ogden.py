"""Large-deformation Ogden punch (phri_spring.physics.hyperelastic.punch_ogden): stress, slope, inverse.

References are written here independently of the module: the compressible neo-Hookean
stress in closed form, the Ogden energy from the eigenvalues of the full 3 x 3 C, the
package's linear punch FE (phri_spring.physics.continuum.punch) and the exponential law.
"""

import math

import numpy as np
import pytest

pytest.importorskip("skfem")

from phri_spring.errors import ConvergenceError  # noqa: E402
from phri_spring.physics.continuum.punch import flat_punch_stiffness  # noqa: E402
from phri_spring.physics.hyperelastic.punch_ogden import (  # noqa: E402
    fit_stiffening, ogden_alpha_from_stiffening, ogden_stress, punch_stiffening,
    slope_at_contact)

# the human preset (configs/human_upper_arm.yaml): 9 mm indenter, 25 mm layer
A, H, E, NU = 0.0045, 0.025, 30e3, 0.45
F_MAX = 120e3 * math.pi * A * A          # pain threshold 120 kPa on the punch: 7.63 N
MU, KAPPA = E / (2 * (1 + NU)), E / (3 * (1 - 2 * NU))
FAST = dict(steps=10)                    # 1 mm load steps: beta within 0.8 % of 50 steps


def _random_g(n=40, seed=1):
    """Axisymmetric displacement gradients (5, n): F_rr-1, F_rz, F_zr, F_zz-1, F_tt-1."""
    rng = np.random.default_rng(seed)
    g = np.empty((5, n))
    g[[0, 3, 4]] = rng.uniform(-0.4, 0.5, (3, n))
    g[[1, 2]] = rng.uniform(-0.35, 0.35, (2, n))
    det = (1 + g[0]) * (1 + g[3]) - g[1] * g[2]
    return g[:, det > 0.2]


def _full(gk):
    """3 x 3 F of one column of the 5-component layout."""
    return np.array([[1 + gk[0], gk[1], 0.0], [gk[2], 1 + gk[3], 0.0], [0.0, 0.0, 1 + gk[4]]])


def _to5(P):
    return np.array([P[0, 0], P[0, 1], P[1, 0], P[1, 1], P[2, 2]])


def test_alpha_2_is_the_compressible_neo_hookean_stress():
    g = _random_g()
    P, J = ogden_stress(g, MU, 2.0, KAPPA)
    for k in range(g.shape[1]):
        F = _full(g[:, k])
        Jk = np.linalg.det(F)
        Finv_T = np.linalg.inv(F).T
        I1 = np.sum(F * F)
        P_nh = MU * Jk ** (-2 / 3) * (F - I1 / 3 * Finv_T) + KAPPA * (Jk - 1) * Jk * Finv_T
        assert J[k] == pytest.approx(Jk, rel=1e-12)
        np.testing.assert_allclose(P[:, k], _to5(P_nh), rtol=1e-9, atol=1e-9 * MU)


def _ogden_energy(F, alpha):
    lam = np.sqrt(np.linalg.eigvalsh(F.T @ F))
    J = np.linalg.det(F)
    return (2 * MU / alpha ** 2 * (np.sum((J ** (-1 / 3) * lam) ** alpha) - 3)
            + KAPPA / 2 * (J - 1) ** 2)


def test_alpha_10_stress_is_the_derivative_of_the_ogden_energy():
    g = _random_g(n=25, seed=2)
    P, _ = ogden_stress(g, MU, 10.0, KAPPA)
    eps = 1e-6
    for k in range(g.shape[1]):
        fd = np.empty(5)
        for i in range(5):
            gp, gm = g[:, k].copy(), g[:, k].copy()
            gp[i] += eps
            gm[i] -= eps
            fd[i] = (_ogden_energy(_full(gp), 10.0) - _ogden_energy(_full(gm), 10.0)) / (2 * eps)
        np.testing.assert_allclose(P[:, k], fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


def test_fit_recovers_the_exponential_law():
    k0, beta = 400.0, 120.0
    d = np.linspace(0, 0.009, 46)
    f = k0 / beta * np.expm1(beta * d)
    b, r2, worst = fit_stiffening(d, f, k0, 0.008)
    assert b == pytest.approx(beta, rel=1e-6) and r2 == pytest.approx(1.0) and worst < 1e-6
    # resampled by the spline up to a depth between two samples: the same law
    b2, _, _ = fit_stiffening(d, f, k0, 0.00833, samples=101)
    assert b2 == pytest.approx(beta, rel=1e-4)


@pytest.mark.parametrize("thickness", [0.025, 0.010])
def test_slope_at_contact_matches_the_linear_punch_fe(thickness):
    """Frictionless face: the small-strain slope is the linear layer's, to the mesh.

    Measured against flat_punch_stiffness (its own converged FE): edge elements a/8,
    a/16, a/32 are 1.31 / 0.58 / 0.22 % stiff on the 25 mm layer, 1.68 / 0.74 / 0.28 %
    on the 10 mm layer (first order in the edge size).
    """
    k_lin = flat_punch_stiffness(thickness, E, NU, A)
    errs = [slope_at_contact(A, thickness, E, NU, 10.0, bonded=False, edge_size=A / n) / k_lin
            - 1 for n in (16, 32)]
    assert abs(errs[0]) < 0.01 and abs(errs[1]) < 0.004
    assert abs(errs[1]) < 0.6 * abs(errs[0])             # converging with the mesh


def test_round_trip_alpha_from_stiffening():
    beta = punch_stiffening(6.0, A, H, E, NU, F_MAX, **FAST)
    assert 55 < beta < 80                                  # 66.5 1/m, measured
    alpha = ogden_alpha_from_stiffening(beta, A, H, E, NU, F_MAX, bracket=(4.0, 9.0),
                                        rtol=2e-3, **FAST)
    assert alpha == pytest.approx(6.0, rel=0.02)


def test_beta_beyond_the_bracket_is_refused_in_one_line():
    b9 = punch_stiffening(9.0, A, H, E, NU, F_MAX, **FAST)
    with pytest.raises(ValueError) as e:
        ogden_alpha_from_stiffening(1.5 * b9, A, H, E, NU, F_MAX, bracket=(4.0, 9.0), **FAST)
    msg = str(e.value)
    assert "\n" not in msg and "1/m" in msg and f"{b9:.4g}" in msg


def test_curve_below_force_max_is_a_convergence_error():
    with pytest.raises(ConvergenceError) as e:
        punch_stiffening(10.0, A, H, E, NU, F_MAX, max_depth=0.002, **FAST)
    assert "\n" not in str(e.value) and "force_max" in str(e.value)
