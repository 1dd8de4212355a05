"""Mirror symmetry of the reduced hyperelastic model (docs/model.md 10.8,
phri_spring.physics.hyperelastic.symmetry).

Independent of the code under test: which planes the human preset is symmetric about (its
rows at x = -25, 0, 25 mm, its patches at angles symmetric about the plane z = 0; the
felupe reference answers F+x and F-x, F+z and F-z, M+y and M-y identically), and the signs
a mirror puts on a patch's forces in its local axes (normal, axial, circumferential, then
the moments about them), worked out by hand below from the frame of a patch at angle
theta: n = -(0, cos, sin), axial e_x, circumferential (0, -sin, cos), moments
pseudovectors (a mirror S maps them by -S).
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from phri_spring.io.config import config_from_dict
from phri_spring.io.config.yaml_loader import _StrictSafeLoader
from phri_spring.physics.hyperelastic.reduced import EXPONENTS, HyperReduction, features, linear_bonded
from phri_spring.physics.hyperelastic.symmetry import mirror_group, pose_signs, symmetrized
from phri_spring.workflows.common import _linear_coupled_model

from support.helpers import REPO

# mirror x -> -x: n and the circumferential axis stay, the axial flips; moments -S v:
# about n and about the circumferential axis flip, about the axial one stays
SIGNS_X = np.array([1, -1, 1, -1, 1, -1.0])
# mirror z -> -z takes the patch at theta to -theta: S n(theta) = n(-theta),
# S e_x = e_x, S t(theta) = -t(-theta); moments: -n, -e_x, +t
SIGNS_Z = np.array([1, 1, -1, -1, -1, 1.0])


@pytest.fixture(scope="module")
def human_linear():
    raw = yaml.load((REPO / "configs" / "human_upper_arm.yaml").read_text(),
                    Loader=_StrictSafeLoader)
    raw["cuff"]["stiffness"] = float("inf")
    cfg = config_from_dict(raw, path=REPO / "configs" / "human_upper_arm.yaml",
                           base_dir=REPO / "configs")
    model = _linear_coupled_model(cfg, cache_dir=None, level=1)
    return model.geometry.points, linear_bonded(model)


def test_the_human_preset_is_symmetric_about_x_and_z_with_the_hand_worked_signs(human_linear):
    points, lin = human_linear
    planes, group = mirror_group(points, lin)
    assert planes == ["x", "z"]
    assert len(group) == 4
    signs = {tuple(g[0]): g[2] for g in group}
    np.testing.assert_array_equal(signs[tuple(pose_signs(0))], SIGNS_X)
    np.testing.assert_array_equal(signs[tuple(pose_signs(2))], SIGNS_Z)
    np.testing.assert_array_equal(signs[tuple(pose_signs(0) * pose_signs(2))],
                                  SIGNS_X * SIGNS_Z)
    # the mirror about x swaps rows A and C and keeps row B
    perm_x = next(g[1] for g in group if np.array_equal(g[0], pose_signs(0)))
    np.testing.assert_allclose(points[perm_x] * [-1, 1, 1], points, atol=1e-12)


@pytest.mark.parametrize("what", ["normal", "W_pre", "H"])
def test_a_model_that_is_not_symmetric_keeps_its_fit(human_linear, what):
    """One patch 1 % stiffer in its normal output (no plane holds), a strap wrench along
    the arm (x goes), a stiffness coupling F_z to w_y (x goes): a plane the linear model
    breaks is not used."""
    points, lin = human_linear
    lin = {k: np.array(v, copy=True) for k, v in lin.items()}
    if what == "normal":
        lin["N"][0] *= 1.01
        lin["f0"][0] *= 1.01
        expect = []
    elif what == "W_pre":
        lin["W_pre"][0] += 0.01 * np.abs(lin["W_pre"]).max()     # a force along x
        expect = ["z"]
    else:
        # F_z from w_y: the mirror about x flips w_y but not F_z; the one about z both
        lin["H"][2, 4] += 1e-3 * np.abs(lin["H"]).max()
        lin["H"][4, 2] = lin["H"][2, 4]
        expect = ["z"]
    planes, group = mirror_group(points, lin)
    assert planes == expect
    assert len(group) == 2 ** len(expect)


def _random_reduction(n, seed):
    rng = np.random.default_rng(seed)
    K = len(EXPONENTS)
    return HyperReduction(scale=rng.uniform(0.5, 2.0, 6), wrench=rng.normal(size=(K, 6)),
                          normal=rng.normal(size=(K, n)), patch=rng.normal(size=(K, n * 6)),
                          range_map=np.eye(6), info={})


def _outputs(red, u):
    phi = features(u / red.scale)
    n = red.normal.shape[1]
    return phi @ red.wrench, phi @ red.normal, (phi @ red.patch).reshape(len(u), n, 6)


def test_averaged_corrections_answer_a_mirrored_pose_with_mirrored_forces(human_linear):
    points, lin = human_linear
    _, group = mirror_group(points, lin)
    red = symmetrized(_random_reduction(len(points), 1), group)
    u = np.random.default_rng(2).normal(size=(50, 6)) * red.scale
    R, f, P = _outputs(red, u)
    for sigma, perm, c in group:
        Rm, fm, Pm = _outputs(red, u * sigma)
        np.testing.assert_allclose(Rm, R * sigma, atol=1e-9 * np.abs(R).max())
        np.testing.assert_allclose(fm[:, perm], f, atol=1e-9 * np.abs(f).max())
        np.testing.assert_allclose(Pm[:, perm], P * c, atol=1e-9 * np.abs(P).max())


def test_averaging_keeps_what_is_symmetric_and_is_done_once(human_linear):
    points, lin = human_linear
    _, group = mirror_group(points, lin)
    raw = _random_reduction(len(points), 3)
    once = symmetrized(raw, group)
    twice = symmetrized(once, group)
    for name in ("wrench", "normal", "patch"):
        a, b = getattr(once, name), getattr(twice, name)
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-12 * np.abs(a).max())
    # the average of a model and its mirror images: the asymmetric part is gone, the
    # symmetric part of the random fit (about a quarter of it, 4 mirror images) stays
    assert 0.1 < np.abs(once.wrench).sum() / np.abs(raw.wrench).sum() < 0.9
    assert symmetrized(raw, group[:1]) is raw
