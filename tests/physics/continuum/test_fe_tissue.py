"""The built-in tissue FE (phri_spring.physics.continuum.tissue) against closed forms,
an independent integral-equation solution and the symmetries of the problem.

Coarse mesh levels only: the convergence study is benchmarks/fe_convergence.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from hypothesis import given, settings
from hypothesis import strategies as st

from phri_spring.physics.continuum import tissue as fe
from support.reference_layer import kappa_integral_equation
from references import rigid_cuff_fe
from phri_spring.physics.cuff.geometry import cuff_geometry
from support.helpers import harmony_geometry  # noqa: E402

pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")

HARMONY = harmony_geometry()


@pytest.fixture(scope="module")
def harmony_l1():
    """Harmony geometry, t = 20 mm, nu = 0.45, level 1 (E = 1 Pa)."""
    return fe.condensed_surface_operators(HARMONY, 0.02, 1.0, 0.45, level=1)


# ----------------------------------------------------------------- closed form: Lame

def lame_ring(a, b, delta, nu, E=1.0):
    """Plane-strain annulus a < r < b, u(a) = 0, u(b) = delta: u(r) and sigma_rr(b).

    u = A r + B / r; sigma_rr = 2 (lam + mu) A - 2 mu B / r^2 (derived by hand from
    eps_rr = A - B/r^2, eps_tt = A + B/r^2, eps_zz = 0).
    """
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    A = delta * b / (b * b - a * a)
    B = -A * a * a
    return (lambda r: A * r + B / r), 2 * (lam + mu) * A - 2 * mu * B / b ** 2


@pytest.mark.parametrize("nu", [0.3, 0.45])
def test_full_ring_radial_expansion_matches_lame(nu):
    """Whole skin pushed out by delta, bone fixed, axial rollers at the ends: plane strain.

    Quadratic elements on a curved mesh at nu = 0.45 (no locking), the periodic seam
    and the assembly are all exercised.
    """
    R, t, delta = 0.04, 0.015, 1e-4
    g = cuff_geometry([0.0], R, 0.02, 0.0, 45.0, 8)            # full circle of patches
    tm = fe.build_mesh(g, t, 1, 0.5)
    ib, Kf = fe.assemble(tm, nu, "free")
    gmap, n_red = fe.periodic_map(tm.comp, t)
    K = fe.reduce_matrix(Kf, gmap, n_red).tocsr()
    xyz = np.zeros((3, 3 * n_red))
    xyz[:, gmap] = np.repeat(tm.mesh.doflocs, 3, axis=1)
    comp = np.zeros(3 * n_red, int)
    comp[gmap] = np.tile(np.arange(3), tm.mesh.doflocs.shape[1])
    r = np.hypot(xyz[1], xyz[2])
    x = xyz[0]
    u = np.zeros(3 * n_red)
    skin = np.abs(r - R) < 1e-9
    bone = np.abs(r - (R - t)) < 1e-9
    ends = ((np.abs(x - x.min()) < 1e-12) | (np.abs(x - x.max()) < 1e-12)) & (comp == 0)
    radial = skin & (comp > 0)
    u[radial & (comp == 1)] = delta * xyz[1][radial & (comp == 1)] / R
    u[radial & (comp == 2)] = delta * xyz[2][radial & (comp == 2)] / R
    D = skin | bone | ends
    free = np.nonzero(~D)[0]
    Dix = np.nonzero(D)[0]
    u[free] = spla.spsolve(K[free][:, free].tocsc(), -(K[free][:, Dix] @ u[Dix]))
    ur_exact, srr = lame_ring(R - t, R, delta, nu)
    # radial displacement at every node
    ury = u[comp == 1]
    urz = u[comp == 2]
    yy, zz = xyz[1][comp == 1], xyz[2][comp == 2]
    rr = np.hypot(yy, zz)
    ur = (ury * yy + urz * zz) / rr
    np.testing.assert_allclose(ur, ur_exact(rr), atol=2e-3 * delta)
    assert np.max(np.abs(u[comp == 0])) < 1e-3 * delta          # no axial motion
    # total radial force on the skin = sigma_rr(R) * 2 pi R * length
    f = K @ u
    sk = skin & (comp > 0)
    F = np.sum(f[sk & (comp == 1)] * xyz[1][sk & (comp == 1)] / R) + \
        np.sum(f[sk & (comp == 2)] * xyz[2][sk & (comp == 2)] / R)
    length = x.max() - x.min()
    assert F == pytest.approx(srr * 2 * np.pi * R * length, rel=2e-3)


# ------------------------------------------------------------------ condensed K

def test_k_is_symmetric_positive_definite(harmony_l1):
    K = harmony_l1.K
    n = HARMONY.n
    assert K.shape == (6 * n, 6 * n) and harmony_l1.N.shape == (n, 6 * n)
    assert harmony_l1.info["asymmetry"] < 1e-10      # symmetric before symmetrisation
    np.testing.assert_array_equal(K, K.T)
    ev = np.linalg.eigvalsh(K)
    assert ev[0] > 1e-9 * ev[-1]
    assert np.all(np.isfinite(K))


def test_k_is_linear_in_e(harmony_l1):
    K3 = fe.condensed_surface_stiffness(HARMONY, 0.02, 3.5e4, 0.45, level=1)
    np.testing.assert_allclose(K3, 3.5e4 * harmony_l1.K, rtol=1e-13, atol=0)


def test_rigid_cuff_motions_match_the_direct_fe(harmony_l1):
    """T^T K T equals the stiffness of the cuff imposed directly on the patches' plates.

    The L2 projection reproduces a field that is one rigid motion over all patches
    exactly (isoparametric quadratic mesh), so both are the same FE problem on the same
    mesh, computed through different operators.
    """
    Kc, Fn, _ = rigid_cuff_fe.direct_rigid_cuff_response(HARMONY, 0.02, 0.45, level=1,
                                              length_factor=fe.DEFAULT_LENGTH_FACTOR)
    T = rigid_cuff_fe.rigid_cuff_map(HARMONY.points)
    KT = T.T @ harmony_l1.K @ T
    np.testing.assert_allclose(KT, Kc, rtol=0, atol=1e-9 * np.max(np.abs(Kc)))
    np.testing.assert_allclose(harmony_l1.N @ T, Fn, rtol=0, atol=1e-9 * np.max(np.abs(Fn)))


def test_patch_forces_balance_the_cuff_wrench():
    """Full-circle two-row cuff: the patch forces and moments sum to the applied wrench."""
    g = cuff_geometry([-0.01, 0.01], 0.04, 0.02, 0.0, 45.0, 8)
    ops = fe.condensed_surface_operators(g, 0.012, 1.0, 0.3, level=1)
    W = np.diag([1.0, 2.0, 3.0, 0.1, 0.2, 0.3])
    T = rigid_cuff_fe.rigid_cuff_map(g.points)
    u = np.linalg.solve(T.T @ ops.K @ T, W)
    F = ops.K @ T @ u
    np.testing.assert_allclose(T.T @ F, W, atol=1e-10)


def mirror_matrix(g, plane):
    """S with q_mirror = S q for a reflection of the geometry (x -> -x or z -> -z)."""
    n = g.n
    P = g.points
    if plane == "x":
        target = P * np.array([-1, 1, 1])
        sig = np.array([-1, 1, 1, 1, -1, -1])   # translation polar, rotation axial vector
    else:
        target = P * np.array([1, 1, -1])
        sig = np.array([1, 1, -1, -1, -1, 1])
    perm = [int(np.argmin(np.linalg.norm(P - target[e], axis=1))) for e in range(n)]
    assert np.allclose(P[perm], target)
    S = np.zeros((6 * n, 6 * n))
    for e in range(n):
        S[6 * perm[e]:6 * perm[e] + 6, 6 * e:6 * e + 6] = np.diag(sig)
    return S


@pytest.mark.parametrize("plane", ["x", "z"])
def test_mirror_symmetry_of_the_harmony_cuff(harmony_l1, plane):
    """Mirrored patch motions give mirrored patch forces: S K S^T = K.

    x -> -x swaps rows A and C; z -> -z maps the angle 180 + a to 180 - a (locations j and
    6 - j), both symmetries of the Harmony geometry (and of the built mesh).
    """
    S = mirror_matrix(HARMONY, plane)
    K = harmony_l1.K
    np.testing.assert_allclose(S @ K @ S.T, K, rtol=0, atol=1e-9 * np.max(np.abs(K)))


def test_full_circle_cuff_is_cyclically_symmetric():
    """Eight 45-degree patches closing the circle: K is invariant under a turn by one patch.

    The circumference is closed by tying the mesh seam; turning the motions of patch e
    onto patch e + 1 (both vectors of each patch rotated about the arm axis by 45 deg)
    must turn the forces the same way: K[e+1, f+1] = Q K[e, f] Q^T.
    """
    n = 8
    g = cuff_geometry([0.0], 0.04, 0.02, 10.0, 360.0 / n, n)
    K = fe.condensed_surface_stiffness(g, 0.015, 1.0, 0.45, level=1)
    a = 2 * np.pi / n
    Rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    Q = np.kron(np.eye(2), Rx)
    B = K.reshape(n, 6, n, 6).transpose(0, 2, 1, 3)          # B[e, f] 6 x 6 blocks
    scale = np.max(np.abs(K))
    for e in range(n):
        for f in range(n):
            np.testing.assert_allclose(B[(e + 1) % n, (f + 1) % n], Q @ B[e, f] @ Q.T,
                                       rtol=0, atol=1e-9 * scale)
    # a uniform radial push of every patch: equal normal forces, no net force
    q = np.zeros(6 * n)
    for e in range(n):
        q[6 * e:6 * e + 3] = g.normals[e]
    F = (K @ q).reshape(n, 6)[:, :3]
    fn = np.einsum("ej,ej->e", F, g.normals)
    np.testing.assert_allclose(fn, fn[0], rtol=1e-9)
    np.testing.assert_allclose(F.sum(axis=0), 0.0, atol=1e-9 * np.abs(fn).max())


def test_rigid_cuff_patch_forces_shapes_and_equilibrium(harmony_l1):
    W = np.eye(6)
    f = rigid_cuff_fe.rigid_cuff_patch_forces(harmony_l1.K, HARMONY, W)
    assert f.shape == (6, HARMONY.n)
    assert rigid_cuff_fe.rigid_cuff_patch_forces(harmony_l1.K, HARMONY, W[2]).shape == (HARMONY.n,)
    # a +y force on the cuff is carried mostly by the patches whose inward normal is +y
    # (location 3, at 180 deg), in compression (on this coarse mesh the gapped plates of
    # the outer rows, wider than the middle row's, take a little more than B3)
    fy = rigid_cuff_fe.rigid_cuff_patch_forces(harmony_l1.K, HARMONY, W[1], N=harmony_l1.N)
    assert HARMONY.labels[int(np.argmax(fy))][1:] == "3" and fy.max() > 0


def test_translational_block_is_the_schur_complement():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(12, 12))
    K = a @ a.T + 12 * np.eye(12)
    t = rng.normal(size=6)
    Kf = fe.translational_block(K, "free")
    # forces with free rotations: solve the full system with zero moments
    it = np.r_[0:3, 6:9]
    ir = np.r_[3:6, 9:12]
    w = -np.linalg.solve(K[np.ix_(ir, ir)], K[np.ix_(ir, it)] @ t)
    q = np.zeros(12)
    q[it], q[ir] = t, w
    np.testing.assert_allclose(Kf @ t, (K @ q)[it], rtol=1e-12)
    np.testing.assert_array_equal(fe.translational_block(K, "fixed"), K[np.ix_(it, it)])
    with pytest.raises(ValueError):
        fe.translational_block(K[:5, :5])


@pytest.mark.parametrize("kw, word", [
    (dict(thickness=0.045), "thickness"), (dict(thickness=-0.01), "thickness"),
    (dict(young_modulus=0.0), "young_modulus"), (dict(poisson_ratio=0.5), "poisson_ratio"),
    (dict(poisson_ratio=float("nan")), "poisson_ratio"), (dict(level=0), "level"),
])
def test_bad_parameters(kw, word):
    args = dict(thickness=0.02, young_modulus=1.0, poisson_ratio=0.45, level=1)
    args.update(kw)
    with pytest.raises(ValueError, match=word):
        fe.condensed_surface_stiffness(HARMONY, args["thickness"], args["young_modulus"],
                                       args["poisson_ratio"], level=args["level"])


def test_overlapping_patches_are_refused():
    # (rows of different radii are meshed: tests/physics/continuum/test_fe_shapes.py)
    g = cuff_geometry([0.0], 0.045, 0.025, 0.0, 30.0, 3, angle_width_deg=40.0)
    with pytest.raises(ValueError, match="overlap"):
        fe.condensed_surface_stiffness(g, 0.02, 1.0, 0.45, level=1)
    g = cuff_geometry([0.0, 0.02], 0.045, 0.025, 0.0, 30.0, 3)
    with pytest.raises(ValueError, match="overlap"):
        fe.condensed_surface_stiffness(g, 0.02, 1.0, 0.45, level=1)


def test_patches_with_gaps_between_them():
    """Patches narrower than their spacing (free skin between them) still give an SPD K."""
    g = cuff_geometry([-0.02, 0.02], 0.04, 0.02, 90.0, 40.0, 4, angle_width_deg=30.0)
    ops = fe.condensed_surface_operators(g, 0.015, 1.0, 0.4, level=1)
    assert np.linalg.eigvalsh(ops.K)[0] > 0
    S = mirror_matrix(g, "x")
    np.testing.assert_allclose(S @ ops.K @ S.T, ops.K, atol=1e-9 * np.max(np.abs(ops.K)))


# ---------------------------------------------------------------------------- punch

def test_integral_equation_reference_limits():
    assert kappa_integral_equation(1e-4, 0.3) == pytest.approx(1.0, abs=1e-3)
    # thin compressible layer: confined compression k = pi a^2 M / h, M = 2G(1-nu)/(1-2nu),
    # dominates; over Sneddon's 4 G a / (1 - nu): pi (a/h) (1-nu)^2 / (2 (1-2nu))
    nu, ah = 0.3, 10.0
    confined = math.pi * ah * (1 - nu) ** 2 / (2 * (1 - 2 * nu))
    kap = kappa_integral_equation(ah, nu, m=128, nx=2000)
    assert kap == pytest.approx(confined, rel=0.15) and kap > confined


def test_thick_layer_punch_tends_to_sneddon():
    E, nu, a = 2.0e4, 0.45, fe.PUNCH_RADIUS
    k = fe.flat_punch_stiffness(100 * a, E, nu, level=1)
    sneddon = 2 * a * E / (1 - nu ** 2)
    assert fe.sneddon_punch_stiffness(E, nu) == pytest.approx(sneddon, rel=1e-15)
    assert 1.0 < k / sneddon < 1.02          # a bonded base only stiffens it (a/h = 0.01)


@pytest.mark.parametrize("nu", [0.3, 0.45])
@pytest.mark.parametrize("a_over_h", [0.1, 0.45, 2.0])
def test_punch_matches_the_layer_integral_equation(nu, a_over_h):
    a = fe.PUNCH_RADIUS
    k = fe.flat_punch_stiffness(a / a_over_h, 1.0, nu, level=1)
    kappa = k * (1 - nu ** 2) / (2 * a)
    assert kappa == pytest.approx(kappa_integral_equation(a_over_h, nu), rel=3e-3)


def test_modulus_from_indenter_inverts_the_punch():
    t, nu = 0.02, 0.45
    k1 = fe.flat_punch_stiffness(t, 1.0, nu, level=1)
    E = np.array([[1.0e4, 5.0e4], [2.0e5, 3.3e3]])
    k = np.array([[fe.flat_punch_stiffness(t, e, nu, level=1) for e in row] for row in E])
    np.testing.assert_allclose(k, E * k1, rtol=1e-14)
    back = fe.modulus_from_indenter(k, t, nu, level=1)
    assert back.shape == E.shape
    np.testing.assert_allclose(back, E, rtol=1e-13)
    assert isinstance(fe.modulus_from_indenter(4242.0, t, nu, level=1), float)
    # a thinner layer over the bone needs a softer tissue for the same indenter stiffness
    thin = fe.modulus_from_indenter(4242.0, 0.01, nu, level=1)
    assert thin < fe.modulus_from_indenter(4242.0, t, nu, level=1)
    for bad in (0.0, -1.0, float("nan"), [1.0, float("inf")]):
        with pytest.raises(ValueError, match="k_indenter"):
            fe.modulus_from_indenter(bad, t, nu, level=1)


@settings(max_examples=15, deadline=None)
@given(E=st.floats(1e2, 1e7), nu=st.sampled_from([0.0, 0.3, 0.4, 0.45]),
       t=st.sampled_from([0.005, 0.02]))
def test_punch_is_linear_in_e_and_above_sneddon(E, nu, t):
    k = fe.flat_punch_stiffness(t, E, nu, level=1)
    assert k == pytest.approx(E * fe.flat_punch_stiffness(t, 1.0, nu, level=1), rel=1e-12)
    assert k > fe.sneddon_punch_stiffness(E, nu)
