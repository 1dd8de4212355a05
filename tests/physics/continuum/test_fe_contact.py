"""The contact reference FE (references.contact_fe): node-by-node unilateral
contact of rigid plates on the tissue, frictionless and with Coulomb friction.

Expected values come from independent routes: the bonded rigid-cuff FE of
references.rigid_cuff_fe (imposed displacements, its own solve), the coupled model's condensation
(L2-projected plates), and conditions the tests evaluate from the geometry themselves
(equilibrium, no penetration, no pull, the friction cone, mirror symmetry). A coarse
mesh (level 1, a short tube) on a small full-circle cuff keeps the file fast.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from phri_spring.errors import ConvergenceError, ModelInputError
from phri_spring.physics.cuff.geometry import cuff_geometry, rigid_body_map

pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")

from references import contact_fe as fc  # noqa: E402
from references import rigid_cuff_fe  # noqa: E402
from phri_spring.physics.continuum import tissue as fe_tissue  # noqa: E402

#: two rows x four 90-degree patches round the whole arm: mirror symmetric in x and z
GEOM = cuff_geometry([-0.0125, 0.0125], 0.04, 0.025, 45.0, 90.0, 4)
T_TISSUE, E, NU, LF = 0.012, 2.0e4, 0.4, 2.0
D0 = 5e-4          # preload: every plate pressed 0.5 mm in along its normal [m]


def frames(normals):
    """Rows n, a = +x, c = n x a (the patches' and nodes' local axes), from the normals."""
    a = np.broadcast_to([1.0, 0.0, 0.0], normals.shape)
    return np.stack([normals, a, np.cross(normals, a)], axis=1)


def cuff_model(k_cuff):
    """A cuff as the contact FE reads a coupled model: T, delta, W_pre, k_cuff, eta."""
    F = frames(GEOM.normals)
    R = np.zeros((GEOM.n, 6, 6))
    R[:, :3, :3] = R[:, 3:, 3:] = F
    T = (R @ rigid_body_map(GEOM.points, rotations=True)).reshape(-1, 6)
    delta = np.zeros((GEOM.n, 6))
    delta[:, 0] = D0
    return SimpleNamespace(T=T, delta=delta.ravel(), W_pre=np.zeros(6), dofs=6,
                           k_cuff=np.full(GEOM.n, k_cuff), shear_ratio=0.35)


@pytest.fixture(scope="module")
def fe():
    return fc.build_contact_fe(GEOM, T_TISSUE, E, NU, level=1, length_factor=LF)


RIGID = cuff_model(np.inf)
SOFT = cuff_model(400.0)


def node_axes(points):
    r = np.hypot(points[:, 1], points[:, 2])
    n = -np.column_stack([np.zeros(len(r)), points[:, 1] / r, points[:, 2] / r])
    return frames(n)


def plate_points(fe, sol):
    """Local (node axes) displacement of every plate's point at every node, (m, n, 3)."""
    F = frames(GEOM.normals)
    t = np.einsum("eji,ej->ei", F, sol.plates[:, :3])          # cuff frame
    w = np.einsum("eji,ej->ei", F, sol.plates[:, 3:])
    d = t[None] + np.cross(w[None], fe.points[:, None] - GEOM.points[None])
    return np.einsum("ikj,iej->iek", node_axes(fe.points), d)


def check_state(fe, model, sol, mu):
    """Equilibrium, unilateral contact, friction cone and cuff springs, from scratch."""
    r, x = sol.reactions, sol.displacements
    scale = np.abs(r).max()
    f = np.einsum("ikj,ik->ij", node_axes(fe.points), r)        # cuff frame
    wrench = np.concatenate([f.sum(0), np.cross(fe.points, f).sum(0)])
    np.testing.assert_allclose(wrench, sol.wrench, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(sol.residual, wrench - sol.wrench, rtol=0, atol=1e-10 * scale)
    # no pull, no penetration, and the gap closed where a node presses
    assert r[:, 0].min() >= -1e-9 * scale
    pp = np.where(fe.incidence, plate_points(fe, sol)[:, :, 0], -np.inf).max(axis=1)
    gap = x[:, 0] - pp
    xs = np.abs(x).max()
    assert gap.min() >= -1e-8 * xs
    np.testing.assert_allclose(gap[sol.contact], 0.0, atol=1e-8 * xs)
    np.testing.assert_allclose(r[~sol.contact], 0.0, atol=1e-9 * scale)
    rt = np.linalg.norm(r[:, 1:], axis=1)
    if mu == 0:
        assert np.all(r[:, 1:] == 0.0)
    elif np.isfinite(mu):
        assert np.all(rt <= mu * r[:, 0] * (1 + 1e-7) + 1e-9 * scale)
        np.testing.assert_allclose(rt[sol.slip], mu * r[sol.slip, 0], rtol=1e-6,
                                   atol=1e-9 * scale)
    # every plate: its nodes' reactions (local patch axes) are its cuff spring's force
    F = frames(GEOM.normals)
    tau = model.T @ sol.u + model.delta
    for e in range(GEOM.n):
        on = sol.plate == e
        fe_ = F[e] @ f[on].sum(0)
        if np.isfinite(model.k_cuff[e]):
            spring = model.k_cuff[e] * np.array([1, model.shear_ratio, model.shear_ratio]) * (
                tau[6 * e:6 * e + 3] - sol.plates[e, :3])
            np.testing.assert_allclose(fe_, spring, rtol=0, atol=1e-8 * scale)
        np.testing.assert_allclose(sol.plates[e, 3:], tau[6 * e + 3:6 * e + 6], rtol=0,
                                   atol=1e-12)
        np.testing.assert_allclose(sol.plate_forces[e, :3], fe_, rtol=0, atol=1e-10 * scale)


def test_bonded_increment_equals_the_direct_rigid_cuff_fe(fe):
    """Small load, every node pressing and sticking (mu huge): the increment from the
    preloaded cuff is the bonded rigid cuff of references.rigid_cuff_fe (a different solve)."""
    Kc, Fn, _ = rigid_cuff_fe.direct_rigid_cuff_response(GEOM, T_TISSUE, NU, level=1,
                                                     length_factor=LF)
    W = np.array([0.02, 0.03, -0.025, 2e-4, -1e-4, 3e-4])
    s0 = fc.solve_contact(fe, RIGID, np.zeros(6), friction_coefficient=1e3)
    s1 = fc.solve_contact(fe, RIGID, W, friction_coefficient=1e3)
    assert s1.contact.all() and not s1.slip.any()
    du = np.linalg.solve(E * Kc, W)
    np.testing.assert_allclose(s1.u - s0.u, du, rtol=0, atol=1e-8 * np.abs(du).max())
    df = E * Fn @ du
    np.testing.assert_allclose(s1.normal_forces - s0.normal_forces, df, rtol=0,
                               atol=1e-8 * np.abs(df).max())
    # a rigid cuff: the plates follow the cuff's rigid motion plus the offset
    np.testing.assert_allclose(s1.plates.ravel(), RIGID.T @ s1.u + RIGID.delta, atol=1e-15)


@pytest.mark.parametrize("mu", [0.0, 0.3, np.inf])
@pytest.mark.parametrize("model, Fy", [(RIGID, 16.0), (SOFT, 4.0)], ids=["rigid", "soft"])
def test_equilibrium_and_unilateral_contact_with_lift_off(fe, mu, model, Fy):
    W = np.array([0.0, Fy, Fy / 4, 0.0, Fy / 200, -Fy / 400])
    sol = fc.solve_contact(fe, model, W, friction_coefficient=mu, steps=3, preload_steps=2)
    assert 0 < sol.contact.sum() < len(fe.points)                 # some nodes lifted off
    if 0 < mu < np.inf:
        assert sol.slip.any()
    check_state(fe, model, sol, mu)
    # the reported forces integrate the same reactions' traction
    np.testing.assert_allclose(sol.normal_forces.sum(), fe.normal_output.sum(0) @
                               sol.reactions.ravel())
    assert np.all(np.isfinite(sol.patch_forces)) and sol.patch_forces.shape == (GEOM.n, 6)


@pytest.mark.parametrize("mu", [0.0, 0.5])
def test_mirror_symmetric_load_gives_mirror_symmetric_patch_forces(fe, mu):
    """A push along +y: the cuff is symmetric in x (row A <-> B) and in z (angle
    45 + 90 k <-> -(45 + 90 k), k <-> 3 - k)."""
    sol = fc.solve_contact(fe, SOFT, [0.0, 3.0, 0.0, 0.0, 0.0, 0.0], friction_coefficient=mu,
                           steps=3, preload_steps=2)
    f = sol.normal_forces.reshape(2, 4)
    assert not sol.contact.all() and f.max() > 0.5
    np.testing.assert_allclose(f, f[::-1], atol=1e-6 * f.max())
    np.testing.assert_allclose(f, f[:, ::-1], atol=1e-6 * f.max())


def test_vanishing_friction_tends_to_the_frictionless_solution(fe):
    """All three components with Coulomb mu -> 0 (slip law) against the normal-only
    stiffness with free tangents: two different systems, one answer."""
    W = [0.0, 3.0, -1.0, 0.0, 0.0, 0.0]
    s0 = fc.solve_contact(fe, SOFT, W, friction_coefficient=0.0)
    s1 = fc.solve_contact(fe, SOFT, W, friction_coefficient=1e-7, steps=2, preload_steps=1)
    np.testing.assert_allclose(s1.normal_forces, s0.normal_forces,
                               atol=1e-5 * s0.normal_forces.max())
    assert np.abs(s1.reactions[:, 1:]).max() <= 1e-6 * np.abs(s1.reactions).max()


def test_sliding_nodes_rub_against_their_slip(fe):
    """Coulomb: a node sliding in a step carries mu lambda_n opposite to its slip in it."""
    rows = [[0.0, 8.0, 0.0, 0.0, 0.0, 0.0], [0.0, 8.0, 0.0, 0.0, 0.05, 0.0]]
    s1, s2 = fc.solve_contact_path(fe, SOFT, rows, friction_coefficient=0.3, preload_steps=2)
    check_state(fe, SOFT, s2, 0.3)

    def offset(sol):           # tangential offset of each node from its plate point
        pp = plate_points(fe, sol)[np.arange(len(fe.points)), np.maximum(sol.plate, 0)]
        return sol.displacements[:, 1:] - pp[:, 1:]
    k = s2.slip & s1.contact & (s1.plate == s2.plate)
    assert k.sum() >= 5
    slip = offset(s2)[k] - offset(s1)[k]
    t = s2.reactions[k, 1:]
    cos = np.einsum("ij,ij->i", t, slip) / np.linalg.norm(t, axis=1) / np.linalg.norm(slip,
                                                                                  axis=1)
    np.testing.assert_allclose(cos, -1.0, atol=1e-6)


def test_no_equilibrium_is_an_error(fe):
    """Torsion about the arm: no frictionless contact resists it; friction only up to
    about mu * (sum of normal forces) * R."""
    with pytest.raises(ConvergenceError, match="no equilibrium"):
        fc.solve_contact(fe, SOFT, [0, 0, 0, 0.01, 0, 0], friction_coefficient=0.0)
    held = fc.solve_contact(fe, RIGID, np.zeros(6), friction_coefficient=0.2)
    capacity = 0.2 * held.reactions[:, 0].sum() * 0.04
    with pytest.raises(ConvergenceError, match="no equilibrium"):
        fc.solve_contact(fe, RIGID, [0, 0, 0, 3 * capacity, 0, 0], friction_coefficient=0.2,
                         steps=3, preload_steps=1)


def test_bad_inputs_are_refused(fe):
    with pytest.raises(ModelInputError, match="friction_coefficient"):
        fc.solve_contact(fe, SOFT, np.zeros(6), friction_coefficient=-0.1)
    bad = SimpleNamespace(**{**vars(SOFT), "T": SOFT.T[:-6]})
    with pytest.raises(ModelInputError):
        fc.solve_contact(fe, bad, np.zeros(6))
    with pytest.raises(ValueError, match="wrenches"):
        fc.solve_contact_path(fe, SOFT, np.zeros((2, 5)))


def test_bonded_plates_in_full_contact_are_the_coupled_model(fe):
    """Every node pressing and sticking, plates apart (patch gap): the contact FE is the
    bonded-plate FE that the coupled model condenses by L2 projection; with its own
    preload (delta, W_pre) both report the same patch forces."""
    if fe.info["patch_gap"] <= 0:
        pytest.skip("tiled plates share nodes: the condensation smooths their edges")
    from phri_spring.physics.continuum.coupled import build_coupled_model
    from phri_spring.physics.contact.solver import solve

    ops = fe_tissue.condensed_surface_operators(GEOM, T_TISSUE, E, NU, level=1,
                                                length_factor=LF)
    model = build_coupled_model(GEOM, ops.K, np.full(GEOM.n, 300.0), poisson_ratio=NU,
                                strap_tension=5.0, normal_output=ops.N)
    W = np.array([0.05, -0.1, 0.08, 1e-3, 0.0, -2e-3])
    sol = fc.solve_contact(fe, model, W, friction_coefficient=np.inf, steps=2,
                           preload_steps=1)
    assert sol.contact.all()
    ref = solve(model, W[None])
    np.testing.assert_allclose(sol.normal_forces, ref.forces[0], rtol=0,
                               atol=1e-8 * ref.forces.max())
    np.testing.assert_allclose(sol.u, ref.u[0], rtol=0, atol=1e-8 * np.abs(ref.u).max())
